// The dissipation terms beside γ in the identification (identify_stages.hpp): their start, the
// amplitude check that calls for them, and their values and intervals in the user's units
// (docs/derivations.md, "Dry friction and drag"; docs/identification.md).
#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

#include "csympnet/core/dense.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/identify/model_checks.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/train/gamma_sandwich.hpp"
#include "identify_stages.hpp"

namespace csympnet::detail {

std::vector<DissipationTerm> dissipation_group(DissipationKind kind, Index d) {
  std::vector<DissipationTerm> out;
  for (Index i = 0; i < d; ++i) out.push_back({kind, i});
  return out;
}

void dissipation_start(Candidate& y, std::size_t first, const WindowSet& train) {
  const auto& map = dynamic_cast<const HamiltonianLibraryMap&>(*y.inner.map);
  const std::vector<DissipationTerm>& dis = map.dissipation();
  const Index d = map.d(), n_new = static_cast<Index>(dis.size() - first);
  if (n_new <= 0) return;
  // The new terms at rate 0 (θ = 0: the identity to the bit): the candidate's prediction
  // without them.
  Vector probe = y.theta;
  for (std::size_t k = first; k < dis.size(); ++k)
    probe(map.dissipation_index(static_cast<Index>(k))) = 0.0;
  Matrix z = train.z0;
  for (Index k = 0; k < train.m; ++k) z = map.apply(probe, z, train.h.row(k).transpose());
  const Vector span = train.span();
  // Momentum residual over a window ≈ −H (Δγ p̄ + Σ rate_k φ_k(p̄)): columns −H p̄_i (Δγ) and
  // −H φ_k, φ = sign(p̄_i) for Coulomb, p̄_i|p̄_i| for drag.
  const Index n = train.size();
  Matrix a = Matrix::Zero(n * d, n_new + 1);
  Vector b(n * d);
  for (Index j = 0; j < n; ++j)
    for (Index i = 0; i < d; ++i) {
      const double pbar = 0.5 * (train.z0(d + i, j) + train.zm(d + i, j));
      b(j * d + i) = train.zm(d + i, j) - z(d + i, j);
      a(j * d + i, n_new) = -span(j) * pbar;
      for (Index k = 0; k < n_new; ++k) {
        const DissipationTerm& t = dis[first + static_cast<std::size_t>(k)];
        if (t.i != i) continue;
        const double phi = t.kind == DissipationKind::kCoulomb ? (pbar > 0.0   ? 1.0
                                                                  : pbar < 0.0 ? -1.0
                                                                               : 0.0)
                                                               : pbar * std::abs(pbar);
        a(j * d + i, k) = -span(j) * phi;
      }
    }
  const Matrix ata = a.transpose() * a;
  const dense::Ldlt l(ata + 1e-10 * std::max(ata.diagonal().maxCoeff(), 1e-300) *
                                Matrix::Identity(ata.rows(), ata.cols()));
  const Vector sol = l.solve(Vector(a.transpose() * b));
  if (!sol.allFinite()) return;
  // A rate that the residuals put at or below 0 starts small and positive (|θ| has no slope
  // at 0): LM takes it down if the data say so.
  for (Index k = 0; k < n_new; ++k)
    y.theta(map.dissipation_index(static_cast<Index>(first) + k)) =
        std::max(sol(k), HamiltonianLibraryMap::kDissipationInit);
  const Index bi = *map.damping_param_index();
  const double beta = y.theta(bi);
  const double gamma = std::abs(beta) + sol(n_new);
  if (std::isfinite(gamma) && gamma > 1e-8) y.theta(bi) = beta < 0.0 ? -gamma : gamma;
}

ModelCheck amplitude_of(const Candidate& x, const BlockSplit& split,
                        const std::function<bool()>& should_stop) {
  CheckInput in;
  in.map = x.inner.map.get();
  in.theta = x.theta;
  in.damping_index = *x.inner.map->damping_param_index();
  in.blocks = split.blocks;
  // The selection asks only whether the rate changes with amplitude (the t test of the slope,
  // whose false-alarm rate does not depend on how far apart the blocks' energies are; a narrow
  // range costs power, not validity). The check's own range rule guards its size statement,
  // which the selection does not use.
  in.thresholds.min_log_energy_range = 0.0;
  return amplitude_check(in, should_stop);
}

namespace {

// The reported number of dissipation term k at θ, in the user's units: Coulomb friction as the
// deceleration α_i W_ii μ_i / τ² of its own coordinate, drag as c_i / (W_ii α_i).
double user_value(const HamiltonianLibraryMap& map, const Vector& theta, const Normalization& u,
                  Index k) {
  const DissipationTerm& t = map.dissipation()[static_cast<std::size_t>(k)];
  const Index i = t.i;
  const double w = theta(map.full_mass() ? i * (i + 1) / 2 + i : i);
  const double rate = std::abs(theta(map.dissipation_index(k)));
  const double alpha = u.q_scale.size() > i ? u.q_scale(i) : 1.0;
  const double tau = u.time_scale;
  return t.kind == DissipationKind::kCoulomb ? alpha * w * rate / (tau * tau) : rate / (w * alpha);
}

}  // namespace

std::vector<double> dissipation_relative_changes(const OneStepMap& any_map, const Vector& theta,
                                                 const Vector& moved) {
  std::vector<double> out;
  const auto* map = dynamic_cast<const HamiltonianLibraryMap*>(&any_map);
  if (map == nullptr) return out;
  const Normalization none;
  for (Index k = 0; k < static_cast<Index>(map->dissipation().size()); ++k) {
    const double v0 = user_value(*map, theta, none, k), v1 = user_value(*map, moved, none, k);
    const double rel = std::abs(v1 - v0) / std::max(std::abs(v0), 1e-300);
    out.push_back(std::isfinite(rel) ? rel : 0.0);
  }
  return out;
}

nlohmann::json dissipation_terms_report(const OneStepMap& any_map, const Vector& theta,
                                        const Normalization& units,
                                        const HamiltonianIntervalInput& in,
                                        const std::vector<double>& integrator) {
  nlohmann::json out = nlohmann::json::array();
  const auto* map = dynamic_cast<const HamiltonianLibraryMap*>(&any_map);
  if (map == nullptr) return out;
  const Index p = theta.size();
  for (Index k = 0; k < static_cast<Index>(map->dissipation().size()); ++k) {
    const DissipationTerm& t = map->dissipation()[static_cast<std::size_t>(k)];
    const double value = user_value(*map, theta, units, k);
    nlohmann::json low = nullptr, high = nullptr;
    if (in.ne != nullptr) {
      Vector grad(p);
      for (Index j = 0; j < p; ++j) {
        const double step = 1e-6 * std::max(1.0, std::abs(theta(j)));
        Vector tp = theta, tm = theta;
        tp(j) += step;
        tm(j) -= step;
        grad(j) = (user_value(*map, tp, units, k) - user_value(*map, tm, units, k)) / (2.0 * step);
      }
      SandwichInterval iv = sandwich_interval_of(in.ne->a, in.ne->g, in.ne->scores, grad, value,
                                                 in.n_residuals, in.ne->cost, in.residual_scale,
                                                 0.0, in.level, &in.ne->block_information);
      inflate_interval(iv, in.inflation);
      if (static_cast<std::size_t>(k) < integrator.size())
        add_integrator(iv, integrator[static_cast<std::size_t>(k)] * std::abs(value));
      low = iv.low;
      high = iv.high;
    }
    const bool coulomb = t.kind == DissipationKind::kCoulomb;
    out.push_back({{"kind", dissipation_kind_name(t.kind)},
                   {"dof", t.i + 1},
                   {"value", value},
                   {"low", low},
                   {"high", high},
                   {"unit", coulomb ? "q unit per time unit squared: q'' = ... - mu sign(q')"
                                    : "per q unit: q'' = ... - c q'|q'|"}});
  }
  return out;
}

}  // namespace csympnet::detail
