#include "csympnet/data/normalization.hpp"

#include <algorithm>
#include <cmath>

#include "csympnet/core/error.hpp"

namespace csympnet {

void Normalization::validate(const std::string& where) const {
  const Index n = d();
  require(n >= 1 && q_scale.size() == n && p_scale.size() == n, [&] {
    return where + ": q_shift, q_scale and p_scale need one entry per degree of freedom";
  });
  require(q_shift.allFinite(), [&] { return where + ": q_shift must be finite"; });
  require(std::isfinite(time_scale) && time_scale > 0.0,
          [&] { return where + ": time_scale must be finite and > 0"; });
  for (Index i = 0; i < n; ++i)
    require(std::isfinite(q_scale(i)) && q_scale(i) > 0.0 && std::isfinite(p_scale(i)) &&
                p_scale(i) > 0.0,
            [&] {
              return where + ": scales must be finite and > 0 (entry " + std::to_string(i + 1) +
                     ")";
            });
  const double c = q_scale(0) * p_scale(0);
  for (Index i = 1; i < n; ++i)
    require(std::abs(q_scale(i) * p_scale(i) - c) <= 1e-12 * c, [&] {
      return where + ": q_scale[i] * p_scale[i] must be the same for every i (entry " +
             std::to_string(i + 1) +
             " differs), or the map would not stay conformally "
             "symplectic";
    });
}

Vector Normalization::unit() const {
  Vector u(2 * d());
  u << q_scale, p_scale;
  return u;
}

Matrix Normalization::to_normal(const Matrix& z) const {
  const Index n = d();
  require(z.rows() == 2 * n, [&] {
    return "normalization: states have " + std::to_string(z.rows()) + " rows, expected " +
           std::to_string(2 * n);
  });
  Matrix out(z.rows(), z.cols());
  for (Index i = 0; i < n; ++i) {
    out.row(i) = (z.row(i).array() - q_shift(i)) / q_scale(i);
    out.row(n + i) = z.row(n + i) / p_scale(i);
  }
  return out;
}

Matrix Normalization::from_normal(const Matrix& zn) const {
  const Index n = d();
  require(zn.rows() == 2 * n, [&] {
    return "normalization: states have " + std::to_string(zn.rows()) + " rows, expected " +
           std::to_string(2 * n);
  });
  Matrix out(zn.rows(), zn.cols());
  for (Index i = 0; i < n; ++i) {
    out.row(i) = zn.row(i).array() * q_scale(i) + q_shift(i);
    out.row(n + i) = zn.row(n + i) * p_scale(i);
  }
  return out;
}

void to_json(nlohmann::json& j, const Normalization& n) {
  auto vec = [](const Vector& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
  j = {{"q_shift", vec(n.q_shift)},
       {"q_scale", vec(n.q_scale)},
       {"p_scale", vec(n.p_scale)},
       {"time_scale", n.time_scale}};
}

void from_json(const nlohmann::json& j, Normalization& n) {
  const std::string where = "normalization";
  require(j.is_object(), [&] { return where + ": expected an object"; });
  for (const auto& item : j.items()) {  // not a structured binding: clang 14 cannot capture it
    const std::string& key = item.key();
    require(key == "q_shift" || key == "q_scale" || key == "p_scale" || key == "time_scale",
            [&] { return where + ": unknown key '" + key + "'"; });
  }
  auto vec = [&](const char* key) {
    require(j.contains(key) && j.at(key).is_array(),
            [&] { return where + ": missing array '" + key + "'"; });
    const auto& a = j.at(key);
    Vector v(static_cast<Index>(a.size()));
    for (std::size_t i = 0; i < a.size(); ++i) {
      require(a[i].is_number(), [&] { return where + "." + key + ": expected numbers"; });
      v(static_cast<Index>(i)) = a[i].get<double>();
    }
    return v;
  };
  n.q_shift = vec("q_shift");
  n.q_scale = vec("q_scale");
  n.p_scale = vec("p_scale");
  require(j.contains("time_scale") && j.at("time_scale").is_number(),
          [&] { return where + ": missing number 'time_scale'"; });
  n.time_scale = j.at("time_scale").get<double>();
  n.validate(where);
}

Normalization identity_normalization(Index d) {
  Normalization n;
  n.q_shift = Vector::Zero(d);
  n.q_scale = Vector::Ones(d);
  n.p_scale = Vector::Ones(d);
  n.time_scale = 1.0;
  return n;
}

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// From all states (2d × M) and steps.
Normalization from_states(const Matrix& z, const std::vector<double>& steps) {
  const Index d = z.rows() / 2;
  require(z.cols() >= 2, "normalization: need at least 2 states");
  require(!steps.empty(), "normalization: need at least one step");
  Normalization n;
  n.q_shift = z.topRows(d).rowwise().mean();
  Vector sq(d), sp(d);
  const double m = static_cast<double>(z.cols());
  for (Index i = 0; i < d; ++i) {
    const double mq = n.q_shift(i);
    const double mp = z.row(d + i).mean();
    sq(i) = std::sqrt((z.row(i).array() - mq).square().sum() / m);
    // The spread of p about its mean; p itself is not shifted (the damping pulls p to 0).
    sp(i) = std::sqrt((z.row(d + i).array() - mp).square().sum() / m);
    const std::string dof = std::to_string(i + 1);
    // Equal extremes, not a spread of 0, mean "does not vary": the mean of a constant 0.7 is
    // not 0.7 to the bit, and the spread about it is a rounding error (a constant column once
    // passed). A spread of 0 or infinity with values that differ: their squares underflowed
    // (below ~1e-154 the square of a difference is no longer a normal double) or overflowed.
    const auto varies = [&](Index row) { return z.row(row).maxCoeff() > z.row(row).minCoeff(); };
    auto why_zero = [&](Index row, double mean, const char* name) {
      const std::string what = "normalization: " + std::string(name) + dof;
      if (!varies(row))
        return what + " does not vary in the data; expected every coordinate to vary";
      const double widest = (z.row(row).array() - mean).abs().maxCoeff();
      const bool large = !(widest < 1.0);
      return what + " varies by about " + number_text(widest) + ", too " +
             (large ? "much" : "little") + " for its square to be a normal double (it " +
             (large ? "overflows" : "underflows to 0") +
             "); expected variations between 1e-150 and 1e150 (rescale the data, e.g. to SI "
             "units)";
    };
    require(varies(i) && sq(i) > 0.0 && std::isfinite(sq(i)), [&] { return why_zero(i, mq, "q"); });
    require(varies(d + i) && sp(i) > 0.0 && std::isfinite(sp(i)),
            [&] { return why_zero(d + i, mp, "p"); });
  }
  // c = geometric mean of σ_q σ_p, in logs (no overflow for spreads of 1e±150).
  double log_c = 0.0;
  for (Index i = 0; i < d; ++i) log_c += std::log(sq(i)) + std::log(sp(i));
  const double c = std::exp(log_c / static_cast<double>(d));
  n.q_scale.resize(d);
  n.p_scale.resize(d);
  for (Index i = 0; i < d; ++i) {
    n.q_scale(i) = std::sqrt(c * (sq(i) / sp(i)));
    n.p_scale(i) = c / n.q_scale(i);
  }
  n.time_scale = median(steps);
  n.validate("normalization");
  return n;
}

}  // namespace

Normalization fit_normalization(const std::vector<Trajectory>& trajs) {
  require(!trajs.empty(), "normalization: no trajectories");
  Index cols = 0;
  for (const Trajectory& t : trajs) cols += t.z.cols();
  Matrix z(trajs.front().z.rows(), cols);
  std::vector<double> steps;
  Index c = 0;
  for (const Trajectory& t : trajs) {
    z.middleCols(c, t.z.cols()) = t.z;
    c += t.z.cols();
    for (Index k = 0; k < t.steps(); ++k) steps.push_back(t.t(k + 1) - t.t(k));
  }
  return from_states(z, steps);
}

Normalization fit_normalization(const PairSet& pairs) {
  Matrix z(pairs.dim(), 2 * pairs.size());
  z << pairs.z0, pairs.z1;
  return from_states(z, std::vector<double>(pairs.h.data(), pairs.h.data() + pairs.size()));
}

std::vector<Trajectory> normalize(const Normalization& n, const std::vector<Trajectory>& trajs) {
  std::vector<Trajectory> out;
  out.reserve(trajs.size());
  for (const Trajectory& t : trajs) {
    Trajectory s;
    s.z = n.to_normal(t.z);
    // Times relative to the trajectory's start, so that steps keep their bits as well as
    // they can: ĥ = (t[k+1] − t[k]) / τ is what the windows read.
    s.t = (t.t.array() - t.t(0)) / n.time_scale;
    out.push_back(std::move(s));
  }
  return out;
}

PairSet normalize(const Normalization& n, const PairSet& pairs) {
  PairSet s;
  s.z0 = n.to_normal(pairs.z0);
  s.z1 = n.to_normal(pairs.z1);
  s.h = pairs.h / n.time_scale;
  return s;
}

}  // namespace csympnet
