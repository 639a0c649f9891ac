#include "csympnet/data/generate.hpp"

#include <cmath>
#include <string>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"

namespace csympnet {

namespace {

void check_box(double box, const char* where) {
  require(std::isfinite(box) && box > 0.0, [&] {
    return std::string(where) + ": box must be a finite number > 0, got " + number_text(box);
  });
}

// Population standard deviation of each row (divide by the number of columns).
Vector row_std(const Matrix& X) {
  const double m = static_cast<double>(X.cols());
  const Vector mean = X.rowwise().sum() / m;
  return ((X.colwise() - mean).array().square().rowwise().sum() / m).sqrt().matrix();
}

// True when every entry satisfies |x| <= bound (NaN and ±inf fail).
bool bounded(const Eigen::Ref<const Vector>& z, double bound) {
  for (Index i = 0; i < z.size(); ++i)
    if (!(std::abs(z(i)) <= bound)) return false;
  return true;
}

}  // namespace

void StepSpec::validate() const {
  require(std::isfinite(h_min) && h_min > 0.0,
          [&] { return "steps.h_min must be a finite number > 0, got " + number_text(h_min); });
  require(std::isfinite(h_max) && h_max >= h_min, [&] {
    return "steps.h_max must be a finite number >= h_min = " + number_text(h_min) + ", got " +
           number_text(h_max);
  });
}

void to_json(nlohmann::json& j, const StepSpec& s) {
  j = nlohmann::json{{"h_min", s.h_min}, {"h_max", s.h_max}};
}

void from_json(const nlohmann::json& j, StepSpec& s) {
  require(j.is_object(),
          [&] { return "steps: expected a JSON object, got " + std::string(j.type_name()); });
  StepSpec out;
  for (const auto& item : j.items()) {  // not a structured binding: clang 14 cannot capture it
    const std::string& key = item.key();
    const nlohmann::json& value = item.value();
    require(key == "h_min" || key == "h_max",
            [&] { return "steps: unknown key \"" + key + "\" (allowed: h_min, h_max)"; });
    require(value.is_number(),
            [&] { return "steps." + key + " must be a number, got " + value.dump(); });
    (key == "h_min" ? out.h_min : out.h_max) = value.get<double>();
  }
  require(j.contains("h_min"), "steps.h_min is required");
  require(j.contains("h_max"), "steps.h_max is required");
  out.validate();
  s = out;
}

PairSet generate_pairs(const System& sys, Index n, const StepSpec& steps, Rng& rng,
                       const ReferenceOptions& ref, double box) {
  steps.validate();
  ref.validate();
  check_box(box, "generate_pairs");
  require(n >= 1,
          [&] { return "generate_pairs: number of pairs must be >= 1, got " + std::to_string(n); });
  const Index dim = sys.dim();
  PairSet pairs;
  pairs.z0.resize(dim, n);
  pairs.h.resize(n);
  for (Index j = 0; j < n; ++j) {
    if ((j & 255) == 255 || dim >= 65536) throw_if_stop_requested("generating the data");
    for (Index i = 0; i < dim; ++i) pairs.z0(i, j) = rng.uniform(-box, box);
    const double h = rng.uniform(steps.h_min, steps.h_max);
    pairs.h(j) = steps.h_min == steps.h_max ? steps.h_min : h;
  }
  pairs.z1 = reference_flow(sys, pairs.z0, pairs.h, ref);
  return pairs;
}

NoiseScales noise_scales(const System& sys, const StepSpec& steps, Rng& rng,
                         const ReferenceOptions& ref, Index m, double box) {
  require(m >= 2,
          [&] { return "noise_scales: m must be >= 2 snapshots, got " + std::to_string(m); });
  const PairSet clean = generate_pairs(sys, m, steps, rng, ref, box);
  return NoiseScales{row_std(clean.z0), row_std(clean.z1)};
}

void add_noise(PairSet& pairs, double sigma, const NoiseScales& scales, Rng& rng) {
  require(std::isfinite(sigma) && sigma >= 0.0, [&] {
    return "add_noise: sigma must be a finite number >= 0, got " + number_text(sigma);
  });
  const Index dim = pairs.z0.rows();
  require(pairs.z1.rows() == dim && pairs.z1.cols() == pairs.z0.cols(),
          "add_noise: z0 and z1 must have the same shape");
  require(scales.s0.size() == dim && scales.s1.size() == dim, [&] {
    return "add_noise: noise scales have lengths " + std::to_string(scales.s0.size()) + " and " +
           std::to_string(scales.s1.size()) + ", expected 2d = " + std::to_string(dim);
  });
  Vector xi0(dim), xi1(dim);
  for (Index j = 0; j < pairs.z0.cols(); ++j) {
    if ((j & 255) == 255 || dim >= 65536) throw_if_stop_requested("adding noise to the data");
    for (Index i = 0; i < dim; ++i) xi0(i) = rng.normal();
    for (Index i = 0; i < dim; ++i) xi1(i) = rng.normal();
    if (sigma == 0.0) continue;  // adding +0.0 would turn −0.0 into +0.0
    pairs.z0.col(j) += sigma * scales.s0.cwiseProduct(xi0);
    pairs.z1.col(j) += sigma * scales.s1.cwiseProduct(xi1);
  }
}

TestSet generate_test_set(const System& sys, Index m, double h_test, double horizon, Rng& rng,
                          const ReferenceOptions& ref, double bound, double box,
                          Index max_redraws) {
  ref.validate();
  check_box(box, "generate_test_set");
  require(m >= 1, [&] {
    return "generate_test_set: m must be >= 1 trajectories, got " + std::to_string(m);
  });
  require(std::isfinite(h_test) && h_test > 0.0, [&] {
    return "generate_test_set: h_test must be a finite number > 0, got " + number_text(h_test);
  });
  require(std::isfinite(horizon) && horizon > 0.0, [&] {
    return "generate_test_set: horizon must be a finite number > 0, got " + number_text(horizon);
  });
  require(std::isfinite(bound) && bound > 0.0, [&] {
    return "generate_test_set: bound must be a finite number > 0, got " + number_text(bound);
  });
  require(max_redraws >= 0, [&] {
    return "generate_test_set: max_redraws must be >= 0, got " + std::to_string(max_redraws);
  });
  const double steps_real = std::round(horizon / h_test);
  require(steps_real >= 1.0 && steps_real <= 1e9, [&] {
    return "generate_test_set: horizon / h_test = " + number_text(horizon / h_test) +
           " must round to a step count in [1, 1e9]";
  });
  const auto n_steps = static_cast<Index>(steps_real);
  const Index dim = sys.dim();

  Vector t(n_steps + 1);
  for (Index n = 0; n <= n_steps; ++n) t(n) = static_cast<double>(n) * h_test;

  TestSet out;
  out.trajectories.reserve(static_cast<std::size_t>(m));
  while (static_cast<Index>(out.trajectories.size()) < m) {
    // One round: exactly as many candidates as are still missing (see the header).
    const Index need = m - static_cast<Index>(out.trajectories.size());
    // Sized in place: copying one prototype into each would touch every page of a history
    // before the first step (640 MB at d = 10^5, a second in which no stop request is seen).
    std::vector<Matrix> hist(static_cast<std::size_t>(need));
    for (Matrix& record : hist) record.resize(dim, n_steps + 1);
    std::vector<bool> alive(static_cast<std::size_t>(need), true);
    Matrix cur = rng.uniform_matrix(dim, need, -box, box);  // column by column: q then p
    std::vector<Index> ids;                                 // candidate of each column of cur
    for (Index c = 0; c < need; ++c) {
      hist[c].col(0) = cur.col(c);
      alive[c] = bounded(cur.col(c), bound);
      if (alive[c]) ids.push_back(c);
    }
    for (Index n = 1; n <= n_steps && !ids.empty(); ++n) {
      throw_if_stop_requested("generating the test trajectories");
      // Integrate only the survivors; each column's result is independent of the others.
      Matrix active(dim, static_cast<Index>(ids.size()));
      for (std::size_t i = 0; i < ids.size(); ++i)
        active.col(static_cast<Index>(i)) = cur.col(ids[i]);
      const Matrix next = reference_flow(
          sys, active, Vector::Constant(static_cast<Index>(ids.size()), h_test), ref);
      std::vector<Index> survivors;
      for (std::size_t i = 0; i < ids.size(); ++i) {
        const Index c = ids[i];
        cur.col(c) = next.col(static_cast<Index>(i));
        hist[c].col(n) = cur.col(c);
        if (bounded(cur.col(c), bound))
          survivors.push_back(c);
        else
          alive[c] = false;
      }
      ids = std::move(survivors);
    }
    for (Index c = 0; c < need; ++c) {
      if (alive[c])
        out.trajectories.push_back(Trajectory{t, std::move(hist[c]), {}});
      else
        ++out.redraws;
    }
    require(out.redraws <= max_redraws, [&] {
      return "cannot generate the test trajectories: only " +
             std::to_string(out.trajectories.size()) + " of " + std::to_string(m) +
             " stayed within |z| <= " + number_text(bound) + " over the horizon after " +
             std::to_string(out.redraws) +
             " starts were drawn again (the reference solution blows up or loses accuracy "
             "for this system: check --omega, --gamma, --alpha and --k); expected a system "
             "whose test trajectories stay bounded";
    });
  }
  return out;
}

}  // namespace csympnet
