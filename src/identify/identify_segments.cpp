// The shooting segments shared by the positions route (identify_positions.cpp) and the
// whole-record fit of records with momenta (identify_states.cpp): cutting the blocks, the
// segment length, the segments' fit, their interval with the start states eliminated, and the
// library core's terms judged on the linked chain (identify_segments.hpp).
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "csympnet/core/error.hpp"
#include "csympnet/models/dof_scaled_map.hpp"
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

// The largest growth of a perturbation of the start state along any segment's fitted rollout,
// ‖∂z_L/∂z_0‖ (Frobenius). A damped system contracts; a fitted map whose rollout amplifies a
// perturbation 1e6-fold over one segment has start states poised on an unstable manifold of
// the map (a saddle fitted where the motion has settled), and its derivatives, the Gauss–Newton
// matrix and the interval are then meaningless.
double largest_sensitivity(const OneStepMap& map, ConstParams theta, const Cut& c) {
  double most = 0.0;
  for (Index s = 0; s < c.segs.size(); ++s) {
    const Vector& h = c.segs.h[static_cast<std::size_t>(s)];
    const Matrix z = shooting_states(map, theta, c.z0.col(s), h);
    Matrix t = Matrix::Identity(z.rows(), z.rows());
    for (Index k = 0; k < h.size(); ++k) t = map.jacobian(theta, z.col(k), h(k)) * t;
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
    Cut c = cut_segments(blocks, d, len, rows);
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
  return out;
}

GammaInterval segments_interval(const OneStepMap& map, const IntervalBasis& at, const Cut& train,
                                const BlockSplit& split, Index n_free, bool momenta_observed,
                                const IdentifyHooks& hooks) {
  if (hooks.stage) hooks.stage("interval");
  GammaInterval out;
  const auto stop = [&hooks] { return hooks.should_stop && hooks.should_stop(); };
  const Index d = train.segs.d, p = map.n_params();
  const Vector& theta = at.theta;
  const double tau = at.units.time_scale;
  const double gamma_n = map.damping_rate(theta).value_or(0.0);
  const Index n_res = train.segs.n_residuals();
  const double scale = 1.0 / std::sqrt(static_cast<double>(n_res));
  NormalEquations ne =
      shooting_normal_equations(map, theta, train.z0, train.segs, n_free, scale, true, stop);
  if (ne.stopped) {
    out.stopped = true;
    return out;
  }
  // The residuals have also fitted 2d unknowns per segment: their spread understates the
  // noise by that many degrees of freedom (docs/derivations.md, "Positions only").
  const double hidden = static_cast<double>(2 * d * train.segs.size());
  const double dof_factor =
      std::sqrt(static_cast<double>(n_res) / std::max(1.0, static_cast<double>(n_res) - hidden));
  ne.scores *= dof_factor;
  const Index bi = *map.damping_param_index();
  SandwichInterval s;
  try {
    s = sandwich_interval(ne.a, ne.g, ne.scores, bi, gamma_n, theta(bi) >= 0.0 ? 1.0 : -1.0, n_res,
                          ne.cost, scale, detail::data_scale(split.blocks), at.level);
  } catch (const Error&) {
    // A property of the data (too few positions per hidden start), not an internal failure.
    out.reasons.push_back(
        std::string(momenta_observed ? "the states" : "the positions") +
        " do not fix the parameters: the Gauss-Newton matrix, with each segment's start state "
        "eliminated, could not be factored even regularised, so no interval can be formed (too "
        "few samples per segment for its start state and the dynamics)");
    return out;
  }
  const double ratio =
      at.train_loss > 0.0 && std::isfinite(at.val_loss) ? at.val_loss / at.train_loss : 1.0;
  const double inflation = std::sqrt(std::max(1.0, ratio));
  inflate_interval(s, inflation);
  // With the momenta observed the library core's integrator share is added, as interval() does.
  const nlohmann::json& lib = at.library;
  if (momenta_observed && lib.contains("gamma_change_at_twice_the_substeps"))
    add_integrator(s, lib["gamma_change_at_twice_the_substeps"].get<double>());
  for (double* v : {&s.gamma, &s.low, &s.high, &s.std_error, &s.sandwich, &s.model_based,
                    &s.optimisation, &s.rounding, &s.integrator})
    *v /= tau;
  s.method += momenta_observed ? " of the whole-record fit (q and p observed)"
                               : " over hidden start states (positions only)";
  out.interval = s;
  out.degrees_of_freedom_factor = dof_factor;
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
  out.dissipation = detail::dissipation_terms_report(map, theta, at.units, shared);
  return out;
}

SegmentFit fit_segments(const OneStepMap& map, const Vector& theta, const Cut& train,
                        const Cut& val, const ShootingOptions& opt) {
  SegmentFit out{theta, train, val, {}};
  fit_start_states(map, out.theta, out.train.segs, out.train.z0, 30, true, kMaxAbsState);
  // Held out: scored only (fit_shooting refits them at once).
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
                          std::vector<Matrix>& states, bool auto_dissipation, nlohmann::json& rec) {
  bool changed = false;
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
  changed |= detail::prefer_polynomials_on_chain(best, d, q_train, linked, val.segs, val.z0, opt,
                                                 states, rec);
  changed |= detail::prune_library_terms(best, d, linked, val.segs, val.z0, opt, states, rec);
  // Friction and drag the velocity start missed, offered on the positions; those it chose,
  // confirmed there.
  if (auto_dissipation) {
    changed |=
        detail::add_dissipation_on_chain(best, d, linked, val.segs, val.z0, opt, states, rec);
    changed |=
        detail::drop_dissipation_on_chain(best, d, linked, val.segs, val.z0, opt, states, rec);
  }
  return changed;
}

}  // namespace detail

}  // namespace csympnet
