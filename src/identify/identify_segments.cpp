// The shooting segments shared by the positions route (identify_positions.cpp) and the
// whole-record fit of records with momenta (identify_states.cpp): cutting the blocks, the
// segment length, the segments' fit, their interval with the start states eliminated, and the
// library core's terms judged on the linked chain (identify_segments.hpp).
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "csympnet/core/error.hpp"
#include "csympnet/models/dof_scaled_map.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/train/gamma_sandwich.hpp"
#include "csympnet/train/shooting.hpp"
#include "identify_chain.hpp"
#include "identify_segments.hpp"
#include "identify_stages.hpp"

namespace csympnet {

namespace detail {

// Samples per period of the fastest-crossing coordinate, from crossings of its mean (the whole
// record when it never crosses): the scale of the local fits and of the segments.
double samples_per_period(const std::vector<Trajectory>& positions) {
  double crossings = 0.0, samples = 0.0;
  for (const Trajectory& t : positions) {
    samples += static_cast<double>(t.t.size());
    double most = 0.0;
    for (Index i = 0; i < t.z.rows(); ++i) {
      const double mean = t.z.row(i).mean();
      double c = 0.0;
      for (Index j = 1; j < t.z.cols(); ++j)
        if ((t.z(i, j - 1) - mean) * (t.z(i, j) - mean) < 0.0) c += 1.0;
      most = std::max(most, c);
    }
    crossings += most;
  }
  return crossings >= 2.0 ? 2.0 * samples / crossings : samples;
}

Cut cut_segments(const std::vector<Trajectory>& blocks, Index d, Index len, Index rows) {
  if (rows <= 0) rows = d;
  std::vector<double> steps;
  for (const Trajectory& t : blocks)
    for (Index k = 1; k < t.t.size(); ++k) steps.push_back(t.t(k) - t.t(k - 1));
  double gap = std::numeric_limits<double>::infinity();
  if (!steps.empty()) {
    std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2),
                     steps.end());
    gap = kWindowGapFactor * steps[steps.size() / 2];
  }
  Cut c;
  c.segs.d = d;
  std::vector<Vector> starts;
  const auto add = [&](const Trajectory& t, Index b, Index first, Index count) {
    c.segs.q.push_back(t.z.block(0, first, rows, count));
    c.segs.h.push_back(t.t.segment(first + 1, count - 1) - t.t.segment(first, count - 1));
    c.segs.block.push_back(b);
    c.at.emplace_back(b, first);
    starts.push_back(t.z.col(first));
  };
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    const Trajectory& t = blocks[b];
    const Index n = t.t.size();
    for (Index begin = 0; begin < n;) {
      Index end = begin + 1;  // one past the stretch without a gap
      while (end < n && t.t(end) - t.t(end - 1) <= gap) ++end;
      if (end - begin < kMinSegmentPositions) {
        c.set_aside += end - begin;
        begin = end;
        continue;
      }
      for (Index first = begin; first + 1 < end;) {
        Index count = std::min(len, end - first);
        if (end - first - count < len / 2) count = end - first;
        add(t, static_cast<Index>(b), first, count);
        first += count;
      }
      begin = end;
    }
  }
  c.z0.resize(2 * d, static_cast<Index>(starts.size()));
  for (std::size_t s = 0; s < starts.size(); ++s) c.z0.col(static_cast<Index>(s)) = starts[s];
  return c;
}

Cut evenly_spread_segments(const Cut& c, Index cap) {
  const Index n = c.segs.size();
  if (n <= cap) return c;
  Cut out;
  out.set_aside = c.set_aside;
  out.segs.d = c.segs.d;
  out.segs.row_weight = c.segs.row_weight;
  out.z0.resize(c.z0.rows(), cap);
  const auto copy_if = [](const auto& from, auto& to, std::size_t k) {
    if (!from.empty()) to.push_back(from[k]);
  };
  for (Index j = 0; j < cap; ++j) {
    const Index s = j * n / cap;
    const auto k = static_cast<std::size_t>(s);
    out.segs.q.push_back(c.segs.q[k]);
    out.segs.h.push_back(c.segs.h[k]);
    out.segs.block.push_back(c.segs.block[k]);
    copy_if(c.segs.observed, out.segs.observed, k);
    copy_if(c.segs.column_block, out.segs.column_block, k);
    copy_if(c.segs.u, out.segs.u, k);
    copy_if(c.at, out.at, k);
    out.z0.col(j) = c.z0.col(s);
  }
  return out;
}

// The largest growth of a perturbation of the start state along any segment's fitted rollout,
// ‖∂z_L/∂z_0‖ (Frobenius). A damped system contracts; a fitted map whose rollout amplifies a
// perturbation 1e6-fold over one segment has start states poised on an unstable manifold of
// the map (a saddle fitted where the motion has settled), and its derivatives, the Gauss–Newton
// matrix and the interval are then meaningless.
double largest_sensitivity(const OneStepMap& map, ConstParams theta, const Cut& c) {
  double most = 0.0;
  for (Index s = 0; s < c.segs.size(); ++s) {
    const Vector& h = c.segs.h[static_cast<std::size_t>(s)];
    Matrix t = Matrix::Identity(c.z0.rows(), c.z0.rows());
    if (map.has_step_tangents()) {
      // Forward mode: the identity carried along the rollout (no Jacobian per step).
      Vector z = c.z0.col(s);
      for (Index k = 0; k < h.size(); ++k) map.step_tangents(theta, h(k), nullptr, z.data(), t, 0);
    } else {
      const Matrix z = shooting_states(map, theta, c.z0.col(s), h);
      for (Index k = 0; k < h.size(); ++k) t = map.jacobian(theta, z.col(k), h(k)) * t;
    }
    const double n = t.norm();
    most = std::isfinite(n) ? std::max(most, n) : std::numeric_limits<double>::infinity();
  }
  return most;
}

// The segment length: the longest of 10, 20, 40, 80 (up to two periods) over which the
// velocity-start model still follows the training positions, its start states fitted: the
// loss per residual, corrected for the 2d unknowns a segment fits (× L / (L − 2)), within 25%
// of the lowest. Longer segments spend fewer unknowns per position; a model that drifts from
// the motion over a long segment (chaotic or poorly started) fits it only in local minima.
Index segment_length(const OneStepMap& map, ConstParams theta,
                     const std::vector<Trajectory>& blocks, Index d, double spp,
                     nlohmann::json& tried, Index rows) {
  const Index longest = std::clamp<Index>(static_cast<Index>(std::lround(2.0 * spp)), 10, 80);
  std::vector<std::pair<Index, double>> losses;
  for (Index len = 10; len <= longest;
       len = len * 2 > longest && len < longest ? longest : 2 * len) {
    Cut c = evenly_spread_segments(cut_segments(blocks, d, len, rows), kLengthSegments);
    const double loss =
        fit_start_states(map, theta, c.segs, c.z0, 30, true, kMaxAbsState, kScoringTolerance);
    const double corrected = loss * static_cast<double>(len) / static_cast<double>(len - 2);
    const double growth = largest_sensitivity(map, theta, c);
    // A length over which the rollout amplifies perturbations beyond 1e3 is not a candidate.
    losses.emplace_back(len, growth <= 1e3 ? corrected : std::numeric_limits<double>::infinity());
    tried.push_back({{"length", len}, {"corrected_loss", corrected}, {"sensitivity", growth}});
    if (len == longest) break;
  }
  double lowest = std::numeric_limits<double>::infinity();
  for (const auto& [len, loss] : losses) lowest = std::min(lowest, loss);
  if (!std::isfinite(lowest)) return losses.front().first;
  Index chosen = losses.front().first;
  for (const auto& [len, loss] : losses)
    if (std::isfinite(loss) && loss <= 1.25 * lowest) chosen = len;
  return chosen;
}

// The reduced normal equations of the n_free fitted parameters, embedded in all P (a held
// parameter: 1 on the diagonal, nothing else) for the modes' gradients over all of θ.
NormalEquations embedded(const NormalEquations& ne, Index p) {
  const Index nf = ne.a.rows();
  if (nf == p) return ne;
  NormalEquations out;
  out.a = Matrix::Identity(p, p);
  out.a.topLeftCorner(nf, nf) = ne.a;
  out.g = Vector::Zero(p);
  out.g.head(nf) = ne.g;
  out.cost = ne.cost;
  out.scores = Matrix::Zero(p, ne.scores.cols());
  out.scores.topRows(nf) = ne.scores;
  for (const Matrix& info : ne.block_information) {
    out.block_information.push_back(Matrix::Zero(p, p));
    out.block_information.back().topLeftCorner(nf, nf) = info;
  }
  return out;
}

// One Gauss–Newton step of the reduced shooting problem (start states eliminated) from θ:
// −(Ã + μD)⁻¹ g̃, μ a ridge at 1e-9 of the diagonal; empty when stopped.
Vector shooting_gauss_newton_step(const OneStepMap& map, const Vector& theta, const Cut& train,
                                  Index n_free, const std::function<bool()>& stop) {
  const double scale = 1.0 / std::sqrt(static_cast<double>(train.segs.n_residuals()));
  const NormalEquations ne =
      shooting_normal_equations(map, theta, train.z0, train.segs, n_free, scale, false, stop);
  if (ne.stopped) return {};
  Vector step = Vector::Zero(theta.size());
  step.head(n_free) = gauss_newton_step(ne);
  return step;
}

// Where the library core's fit over these segments moves when its integrator takes twice the
// substeps: one Gauss–Newton step at 2n less the step at n (what the fit's own optimisation
// left is in both), so the integrator's share is measured on the fit the interval is formed
// from, not on the one-step windows (which fix γ too loosely for the difference to mean
// anything). θ moved by that difference; empty for any other core, or when stopped. The step at
// n is taken from `at_fit`, the reduced normal equations already formed at θ for the interval
// (the same A and g, summed over other clusters).
std::optional<Vector> integrator_moved(const OneStepMap& map, const nlohmann::json& core,
                                       const Vector& theta, const Cut& train, Index n_free,
                                       const NormalEquations& at_fit,
                                       const std::function<bool()>& stop) {
  if (!core.is_object() || core.value("type", "") != "library" || !core.contains("substeps"))
    return std::nullopt;
  nlohmann::json fine = core;
  fine["substeps"] = 2 * core["substeps"].get<Index>();
  const Model finer =
      make_model({{"type", "csympnet"}, {"d", train.segs.d}, {"core", fine}, {"beta_init", 1.0}});
  if (!finer.is_map() || finer.n_params() != map.n_params()) return std::nullopt;
  const Vector step2 = shooting_gauss_newton_step(*finer.map, theta, train, n_free, stop);
  if (step2.size() != theta.size() || at_fit.a.rows() != n_free) return std::nullopt;
  Vector step1 = Vector::Zero(theta.size());
  step1.head(n_free) = gauss_newton_step(at_fit);
  return Vector(theta + step2 - step1);
}

// The interval's clusters are the blocks; when γ̂'s information sits in fewer than this many of
// them (effective blocks, gamma_sandwich.hpp), they are cut into runs of about a period.
constexpr double kMinEffectiveBlocks = 8.0;
// The shortest run of positions that is a cluster of its own.
constexpr Index kMinClusterRun = 10;

// The normal equations over the interval's clusters and γ̂'s sandwich interval from them (before
// the held-out inflation and the integrator's share): over the blocks, or over runs of a period
// inside them when γ̂'s information sits in fewer than kMinEffectiveBlocks blocks and the runs
// spread it wider (a decay that stops, or fades into the noise, in the first block of each
// trajectory). Throws Error when the matrix cannot be factored.
struct ClusterInterval {
  NormalEquations ne;
  SandwichInterval s;
  Index run = 0;  // 0: the blocks
  double dof_factor = 1.0;
};
ClusterInterval cluster_interval(const OneStepMap& map, const Vector& theta, const Cut& train,
                                 Index n_free, double spp, double data_scale, double level,
                                 const std::function<bool()>& stop) {
  const Index d = train.segs.d, n_res = train.segs.n_residuals();
  const double scale = 1.0 / std::sqrt(static_cast<double>(n_res));
  const Index bi = *map.damping_param_index();
  const double gamma_n = map.damping_rate(theta).value_or(0.0);
  // The residuals have also fitted 2d unknowns per segment: their spread understates the
  // noise by that many degrees of freedom (docs/derivations.md, "Positions only").
  const double hidden = static_cast<double>(2 * d * train.segs.size());
  const double dof_factor =
      std::sqrt(static_cast<double>(n_res) / std::max(1.0, static_cast<double>(n_res) - hidden));
  const auto over = [&](const ShootingSegments& segs, Index run) {
    ClusterInterval c;
    c.run = run;
    c.dof_factor = dof_factor;
    c.ne = shooting_block_equations(map, theta, train.z0, segs, n_free, scale, stop);
    if (c.ne.stopped) return c;
    c.ne.scores *= dof_factor;
    c.s = sandwich_interval(c.ne.a, c.ne.g, c.ne.scores, bi, gamma_n, theta(bi) >= 0.0 ? 1.0 : -1.0,
                            n_res, c.ne.cost, scale, data_scale, level, &c.ne.block_information);
    return c;
  };
  ClusterInterval blocks = over(train.segs, 0);
  const Index run = std::max<Index>(kMinClusterRun, static_cast<Index>(std::lround(spp)));
  if (blocks.ne.stopped || blocks.s.effective_blocks <= 0.0 ||
      blocks.s.effective_blocks >= kMinEffectiveBlocks)
    return blocks;
  ClusterInterval runs = over(split_blocks_into_runs(train.segs, run), run);
  if (runs.ne.stopped) return runs;
  return runs.s.effective_blocks > blocks.s.effective_blocks ? runs : blocks;
}

GammaInterval segments_interval(const OneStepMap& map, const IntervalBasis& at, const Cut& train,
                                const BlockSplit& split, Index n_free, bool momenta_observed,
                                const IdentifyHooks& hooks) {
  if (hooks.stage) hooks.stage("interval");
  GammaInterval out;
  const auto stop = [&hooks] { return hooks.should_stop && hooks.should_stop(); };
  const Index p = map.n_params();
  const Vector& theta = at.theta;
  const double tau = at.units.time_scale;
  const double gamma_n = map.damping_rate(theta).value_or(0.0);
  const Index n_res = train.segs.n_residuals();
  const double scale = 1.0 / std::sqrt(static_cast<double>(n_res));
  ClusterInterval c;
  try {
    c = cluster_interval(map, theta, train, n_free, samples_per_period(split.blocks),
                         detail::data_scale(split.blocks), at.level, stop);
  } catch (const Error&) {
    // A property of the data (too few positions per hidden start), not an internal failure.
    out.reasons.push_back(
        std::string(momenta_observed ? "the states" : "the positions") +
        " do not fix the parameters: the Gauss-Newton matrix, with each segment's start state "
        "eliminated, could not be factored even regularised, so no interval can be formed (too "
        "few samples per segment for its start state and the dynamics)");
    return out;
  }
  if (c.ne.stopped) {
    out.stopped = true;
    return out;
  }
  const NormalEquations& ne = c.ne;
  SandwichInterval s = c.s;
  const double ratio =
      at.train_loss > 0.0 && std::isfinite(at.val_loss) ? at.val_loss / at.train_loss : 1.0;
  const double inflation = std::sqrt(std::max(1.0, ratio));
  inflate_interval(s, inflation);
  // The library core's integrator share, measured on this fit (integrator_moved).
  std::vector<double> dissipation_integrator;
  if (const auto moved = integrator_moved(map, at.library_core, theta, train, n_free, ne, stop)) {
    const double g1 = map.damping_rate(*moved).value_or(gamma_n);
    add_integrator(s, std::isfinite(g1) ? std::abs(g1 - gamma_n) : 0.0);
    dissipation_integrator = dissipation_relative_changes(map, theta, *moved);
  }
  for (double* v : {&s.gamma, &s.low, &s.high, &s.std_error, &s.sandwich, &s.model_based,
                    &s.optimisation, &s.rounding, &s.integrator})
    *v /= tau;
  if (c.run > 0) s.method += " (runs of " + std::to_string(c.run) + " positions inside them)";
  s.method += momenta_observed ? " of the whole-record fit (q and p observed)"
                               : " over hidden start states (positions only)";
  out.interval = s;
  out.degrees_of_freedom_factor = c.dof_factor;
  const NormalEquations all = embedded(ne, p);
  out.modes =
      modal_analysis(map, theta, split.train, tau, at.level,
                     {&all, n_res, scale, detail::data_scale(split.blocks), inflation, stop});
  out.stopped = out.modes.stopped;
  // Friction and drag in the user's units are products the gauge of the hidden momenta leaves
  // alone (W μ, c / W), so they keep their intervals from positions alone; with the momenta
  // observed the Hamiltonian's terms get theirs too.
  const HamiltonianIntervalInput shared = {&all, n_res, scale, inflation, at.level};
  if (momenta_observed) out.hamiltonian = hamiltonian_report(map, theta, at.units, shared);
  out.dissipation =
      detail::dissipation_terms_report(map, theta, at.units, shared, dissipation_integrator);
  return out;
}

SegmentFit fit_segments(const OneStepMap& map, const Vector& theta, const Cut& train,
                        const Cut& val, const ShootingOptions& opt) {
  SegmentFit out{theta, train, val, {}};
  // To the scoring tolerance (1e-8 of each segment's ‖r‖²) on both sides: the training start
  // states only choose among the starts and start the joint fit, whose Gauss–Newton steps
  // move them with θ (and whose convergence rule sees what they leave); the held-out ones are
  // scored (fit_shooting refits them at once).
  fit_start_states(map, out.theta, out.train.segs, out.train.z0, 30, true, kMaxAbsState,
                   kScoringTolerance);
  fit_start_states(map, out.theta, out.val.segs, out.val.z0, 30, true, kMaxAbsState,
                   kScoringTolerance);
  out.rep = fit_shooting(map, out.theta, out.train.z0, out.train.segs, out.val.z0, out.val.segs,
                         detail::watching_damping(map, opt));
  return out;
}

Index free_parameters(const OneStepMap& map, Index d) {
  const Index p = map.n_params();
  return dynamic_cast<const DofScaledMap*>(&map) != nullptr ? p - (d - 1) : p;
}

// How often the linking may stop, get a richer force law, and go on (identify_force_law.cpp).
constexpr int kForceLawRounds = 3;

// The training blocks' positions side by side (d x n): where a group's potential is matched
// by powers of its argument.
Matrix training_positions(const detail::BlockSplit& split, Index d) {
  Matrix q(d, 0);
  for (const Trajectory& t : split.train_blocks) {
    q.conservativeResize(d, q.cols() + t.z.cols());
    q.rightCols(t.z.cols()) = t.z.topRows(d);
  }
  return q;
}

// The velocity stage's terms judged on the linked positions, in turn: a richer force law where
// the linking stops (a few rounds, each linking further), the sin/cos or exp groups against
// the powers of their arguments, the powers of degree 3 and 4, and (`auto_dissipation`) the
// friction and drag. `best` (its θ the linked fit's), `linked`, `val.z0` and `states` follow.
// Returns whether the core changed.
bool judge_terms_on_chain(detail::Candidate& best, Index d, const Matrix& q_train,
                          const std::vector<Trajectory>& nt, const detail::RecordLayout& layout,
                          detail::LinkedFit& linked, Cut& val, const ShootingOptions& opt,
                          std::vector<Matrix>& states, bool auto_dissipation, nlohmann::json& rec,
                          const StageNamer& stage) {
  const auto begin = [&stage](const char* what) {
    if (stage) stage(what);
  };
  bool changed = false;
  begin("a richer force law on the chain");
  for (int round = 0; round < kForceLawRounds && !linked.linked_fully; ++round) {
    nlohmann::json tried_here;
    const bool added = detail::richer_force_law_on_chain(best, d, q_train, nt, layout, linked,
                                                         val.segs, val.z0, opt, states, tried_here);
    if (tried_here.contains("force_law_on_chain"))
      rec["force_law_on_chain"].push_back(tried_here["force_law_on_chain"]);
    if (!added) break;
    changed = true;
    rec["linking"] = linked.record;
  }
  begin("polynomials against sin/cos and exp on the chain");
  changed |= detail::prefer_polynomials_on_chain(best, d, q_train, linked, val.segs, val.z0, opt,
                                                 states, rec);
  begin("powers 3 and 4 pruned on the chain");
  changed |= detail::prune_library_terms(best, d, linked, val.segs, val.z0, opt, states, rec);
  // Friction and drag the velocity start missed, offered on the positions; those it chose,
  // confirmed there.
  if (auto_dissipation) {
    begin("friction and drag on the chain");
    changed |=
        detail::add_dissipation_on_chain(best, d, linked, val.segs, val.z0, opt, states, rec);
    changed |=
        detail::drop_dissipation_on_chain(best, d, linked, val.segs, val.z0, opt, states, rec);
  }
  return changed;
}

}  // namespace detail

}  // namespace csympnet
