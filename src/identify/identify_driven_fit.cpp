// The driven route's segment fit (identify_driven.hpp): the record cut into segments with their
// inputs, the equation-error start, multiple shooting with the inputs.
#include <algorithm>
#include <string>
#include <vector>

#include <Eigen/QR>

#include "csympnet/core/dense.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/core/stop.hpp"
#include "identify_driven.hpp"

namespace csympnet::detail {

namespace {

// The equation-error start: with W = 1, per interior sample and dof i,
//   q̈_i ≈ −Σ_k c_k ∂_iφ_k(q) − γ q̇_i + Σ_j B_ij u_j,
// q̇ and q̈ from the three-point differences, solved by least squares for c, γ and B.
Vector driven_start(const HamiltonianLibraryMap& map, const std::vector<Trajectory>& nt) {
  const Index d = map.d(), m = map.n_inputs(), nt_terms = static_cast<Index>(map.terms().size());
  const Index cols = nt_terms + 1 + d * m;
  Vector theta(map.n_params());
  Rng unused(1, "unused");
  map.init_params(unused, theta);
  std::vector<Vector> unit_thetas;
  for (Index k = 0; k < nt_terms; ++k) {
    Vector t = theta;
    for (Index j = 0; j < nt_terms; ++j) t(map.coefficient_index(j)) = j == k ? 1.0 : 0.0;
    unit_thetas.push_back(std::move(t));
  }
  std::vector<double> rows_a, rows_b;
  Vector g(d);
  for (const Trajectory& t : nt)
    for (Index k = 1; k + 1 < t.t.size(); ++k) {
      if (k % 65536 == 0) throw_if_stop_requested("the equation-error start of a driven fit");
      const double h1 = t.t(k) - t.t(k - 1), h2 = t.t(k + 1) - t.t(k);
      const Vector dq1 = t.z.col(k) - t.z.col(k - 1), dq2 = t.z.col(k + 1) - t.z.col(k);
      const Vector acc = 2.0 * (dq2 / h2 - dq1 / h1) / (h1 + h2);
      const Vector vel = (dq2 * (h1 / h2) + dq1 * (h2 / h1)) / (h1 + h2);
      std::vector<Vector> forces;
      for (Index c = 0; c < nt_terms; ++c) {
        map.gradient(unit_thetas[static_cast<std::size_t>(c)], t.z.col(k).data(), g.data());
        forces.push_back(g);
      }
      for (Index i = 0; i < d; ++i) {
        for (Index c = 0; c < nt_terms; ++c)
          rows_a.push_back(-forces[static_cast<std::size_t>(c)](i));
        rows_a.push_back(-vel(i));
        for (Index r = 0; r < d; ++r)
          for (Index j = 0; j < m; ++j) rows_a.push_back(r == i ? t.u(j, k) : 0.0);
        rows_b.push_back(acc(i));
      }
    }
  const auto n = static_cast<Index>(rows_b.size());
  const Matrix a = Eigen::Map<const RowMajorMatrix>(rows_a.data(), n, cols);
  const Vector b = Eigen::Map<const Vector>(rows_b.data(), n);
  const Vector x = dense::least_squares(a, b);
  if (!x.allFinite()) return theta;
  for (Index c = 0; c < nt_terms; ++c) theta(map.coefficient_index(c)) = x(c);
  // β must be nonzero (γ̂ = |β| has no slope at 0); a negative start is a noisy one.
  theta(*map.damping_param_index()) = std::max(x(nt_terms), 0.05);
  for (Index r = 0; r < d; ++r)
    for (Index j = 0; j < m; ++j) theta(map.input_index(r, j)) = x(nt_terms + 1 + r * m + j);
  return theta;
}

}  // namespace

DrivenCut cut_driven(const std::vector<Trajectory>& nt, Index d) {
  DrivenCut c;
  c.train.d = c.val.d = d;
  Index count = 0;
  for (std::size_t j = 0; j < nt.size(); ++j) {
    const Trajectory& t = nt[j];
    const Index n = t.t.size();
    for (Index first = 0; first + 3 <= n;) {
      Index len = std::min(kSegment, n - first);
      if (n - (first + len) < kSegment / 2) len = n - first;
      const bool held_out = count % kHoldOut == kHoldOut - 1;
      ShootingSegments& s = held_out ? c.val : c.train;
      s.q.push_back(t.z.middleCols(first, len));
      s.h.push_back(t.t.segment(first + 1, len - 1) - t.t.segment(first, len - 1));
      s.u.push_back(detail::step_inputs(t, first, len));
      s.block.push_back(static_cast<Index>(s.q.size()) - 1);
      c.places.push_back({static_cast<Index>(j), first, len, held_out});
      ++count;
      first += len;
    }
  }
  require(c.train.size() >= 3, [&] {
    return "a record with inputs needs at least 4 segments of " + std::to_string(kSegment) +
           " samples (3 to fit, 1 held out); it gives " + std::to_string(count);
  });
  return c;
}

HamiltonianLibraryMap driven_map(const LibrarySpec& s, const std::vector<LibraryTerm>& terms,
                                 Index d, Index m) {
  return HamiltonianLibraryMap(d, terms, s.order, s.substeps, false, 0.1, {}, {},
                               InputSpec{m, s.inputs.m != 0 ? s.inputs.hold : InputHold::kFirst});
}

ShootingOptions driven_options(const IdentifyConfig& config, const IdentifyHooks& hooks,
                               long max_iterations) {
  ShootingOptions opt;
  opt.iterations = config.lm_iterations > 0 ? std::min<long>(config.lm_iterations, max_iterations)
                                            : max_iterations;
  opt.max_abs_state = kMaxAbsState;
  opt.should_stop = hooks.should_stop;
  opt.converged_chi2 = 1e-3;
  return opt;
}

DrivenFit fit_driven(HamiltonianLibraryMap map, const std::vector<Trajectory>& nt,
                     const DrivenCut& cut, const IdentifyConfig& config, const IdentifyHooks& hooks,
                     long max_iterations) {
  const Index d = map.d();
  Vector theta = driven_start(map, nt);
  Matrix z0(2 * d, cut.train.size()), vz0(2 * d, cut.val.size());
  const auto first_positions = [&](const ShootingSegments& s, Matrix& z) {
    for (Index k = 0; k < s.size(); ++k) {
      z.col(k).head(d) = s.q[static_cast<std::size_t>(k)].col(0);
      z.col(k).tail(d).setZero();
    }
  };
  first_positions(cut.train, z0);
  first_positions(cut.val, vz0);
  fit_start_states(map, theta, cut.train, z0, 30, true, kMaxAbsState);
  // Held out: scored only (fit_shooting refits them at once).
  fit_start_states(map, theta, cut.val, vz0, 30, true, kMaxAbsState, kScoringTolerance);
  const ShootingOptions opt = driven_options(config, hooks, max_iterations);
  ShootingReport rep = fit_shooting(map, theta, z0, cut.train, vz0, cut.val, opt);
  return {std::move(map), std::move(theta), std::move(z0), std::move(vz0), rep, nullptr};
}

}  // namespace csympnet::detail
