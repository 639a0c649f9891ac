// identify_positions(): records with positions and no momenta (docs/derivations.md,
// "Positions only: the momenta as hidden states"; docs/identification.md, "Positions only").
//
//   1. velocities from a local quadratic fit of q start the momenta (a start only);
//   2. fit_core trains the core on those states, as for any record (units, blocks, candidates);
//   3. the blocks are cut into shooting segments; each segment's start state is a hidden
//      unknown, fitted jointly with θ on the positions alone (train/shooting.hpp), with the
//      per-dof momentum scales held (the gauge);
//   4. the interval is the same sandwich over the same blocks, from the normal equations with
//      the start states eliminated; the held-out inflation as always;
//   5. the checks and the verdict run on the blocks with q observed and p reconstructed.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>

#include <Eigen/QR>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/diagnostics/diagnostics.hpp"
#include "csympnet/identify/identify.hpp"
#include "csympnet/identify/model_checks.hpp"
#include "csympnet/models/dof_scaled_map.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/train/gamma_sandwich.hpp"
#include "csympnet/train/positions_state.hpp"
#include "csympnet/train/shooting.hpp"
#include "identify_chain.hpp"
#include "identify_segments.hpp"
#include "identify_stages.hpp"

namespace csympnet {

namespace {

void check_positions(const std::vector<Trajectory>& positions) {
  require(!positions.empty(), "fit: no data");
  const Index d = positions.front().z.rows();
  for (std::size_t k = 0; k < positions.size(); ++k) {
    const Trajectory& t = positions[k];
    const std::string where = "fit: trajectory " + std::to_string(k);
    require(d >= 1 && t.z.rows() == d, [&] {
      return where + " has " + std::to_string(t.z.rows()) +
             " position rows (d = " + std::to_string(t.z.rows()) + "), but trajectory 0 has " +
             std::to_string(d) + "; expected every trajectory to have the same d";
    });
    require(t.t.size() >= 1 && t.z.cols() == t.t.size(),
            [&] { return where + ": expected one time per sample"; });
    require(t.t.allFinite() && t.z.allFinite(), [&] { return where + ": non-finite value"; });
    for (Index i = 1; i < t.t.size(); ++i)
      require(t.t(i) > t.t(i - 1), [&] {
        return where + ": times must increase strictly (sample " + std::to_string(i) + ")";
      });
  }
  // As the states' normalisation refuses a constant column, before any fit (a constant q2 once
  // ran half a minute to "not identified").
  for (Index i = 0; i < d; ++i) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const Trajectory& t : positions) {
      lo = std::min(lo, t.z.row(i).minCoeff());
      hi = std::max(hi, t.z.row(i).maxCoeff());
    }
    require(hi > lo, [&] {
      return "fit: q" + std::to_string(i + 1) + " does not vary in the data (every value is " +
             number_text(lo) + "); expected every coordinate to vary";
    });
  }
}

// The lag, in samples, at which the positions' autocorrelation first falls below 1/2: the
// motion's time scale, an oscillation's (about a sixth of a period) or a decay's (about 0.7 of
// its time constant), whichever is shorter; the smallest over the coordinates, pooled over
// the trajectories.
double half_correlation_lag(const std::vector<Trajectory>& positions) {
  double lag = std::numeric_limits<double>::infinity();
  const Index d = positions.front().z.rows();
  for (Index i = 0; i < d; ++i) {
    const Index max_lag = 400;
    std::vector<double> num(max_lag + 1, 0.0);
    double var = 0.0;
    for (const Trajectory& t : positions) {
      const Vector x = t.z.row(i).transpose().array() - t.z.row(i).mean();
      var += x.squaredNorm();
      for (Index k = 1; k <= max_lag && k < x.size(); ++k)
        num[static_cast<std::size_t>(k)] += x.head(x.size() - k).dot(x.tail(x.size() - k));
    }
    if (!(var > 0.0)) continue;
    for (Index k = 1; k <= max_lag; ++k)
      if (num[static_cast<std::size_t>(k)] < 0.5 * var) {
        lag = std::min(lag, static_cast<double>(k));
        break;
      }
  }
  return std::isfinite(lag) ? lag : 400.0;
}

// dq/dt at every sample from a least-squares quadratic over the samples within `half` of its
// time (at least the 2 nearest on each side that exist; gaps are not spanned by more): a start
// for the momenta, not an estimate of them.
Trajectory with_local_velocities(const Trajectory& t, double half) {
  const Index d = t.z.rows(), n = t.t.size();
  Trajectory out;
  out.t = t.t;
  out.z.resize(2 * d, n);
  out.z.topRows(d) = t.z;
  if (n < 2) {
    out.z.bottomRows(d).setZero();
    return out;
  }
  // A sample exactly `half` away (half is a whole number of median steps) is inside: with a
  // margin far above rounding, so that times in s and in ms (0.2 s is 0.19999999999999907
  // after the arithmetic, 200 ms is 200) take the same samples and give the same answer.
  const double reach = half * (1.0 + 1e-9);
  for (Index j = 0; j < n; ++j) {
    Index lo = std::max<Index>(0, j - 2), hi = std::min<Index>(n - 1, j + 2);
    while (lo > 0 && t.t(j) - t.t(lo - 1) <= reach) --lo;
    while (hi < n - 1 && t.t(hi + 1) - t.t(j) <= reach) ++hi;
    const Index degree = hi - lo >= 2 ? 2 : 1;
    Matrix x(hi - lo + 1, degree + 1);
    // In units of `half`: powers of the raw offsets (1e-20 s and its square) would differ by
    // more than the QR's rank threshold spans, and it would drop the slope as rank-deficient.
    for (Index i = lo; i <= hi; ++i) {
      const double s = (t.t(i) - t.t(j)) / half;
      for (Index p = 0; p <= degree; ++p) x(i - lo, p) = std::pow(s, static_cast<double>(p));
    }
    const Matrix coef = x.colPivHouseholderQr().solve(t.z.middleCols(lo, hi - lo + 1).transpose());
    out.z.col(j).tail(d) = coef.row(1).transpose() / half;
  }
  return out;
}

// The velocity start must be a state the normalisation can scale: Δq/Δt with steps of 1e-200
// (or 1e200) time units is a velocity whose square is no normal double, and the states'
// normalisation would blame a "p" the record does not have. Refused in the record's own
// columns, t and q.
void check_velocity_start(const std::vector<Trajectory>& states, double h_median) {
  const Index d = states.front().z.rows() / 2;
  for (Index i = 0; i < d; ++i) {
    double sum = 0.0, sq = 0.0, count = 0.0, widest = 0.0;
    for (const Trajectory& t : states) {
      sum += t.z.row(d + i).sum();
      count += static_cast<double>(t.z.cols());
      widest = std::max(widest, t.z.row(i).maxCoeff() - t.z.row(i).minCoeff());
    }
    for (const Trajectory& t : states) sq += (t.z.row(d + i).array() - sum / count).square().sum();
    const double spread2 = sq / count;
    if (std::isfinite(spread2) && spread2 >= std::numeric_limits<double>::min()) continue;
    if (!(widest > 0.0)) continue;  // a constant q: check_positions names it
    const std::string q = "q" + std::to_string(i + 1);
    throw Error("fit: the times' median step " + number_text(h_median) + " with " + q +
                "'s variations (up to " + number_text(widest) +
                ") give velocities dq/dt whose squares are not normal doubles (" +
                (std::isfinite(spread2) ? "they underflow" : "they overflow") +
                "); expected the steps of t and the variations of " + q +
                " to keep |dq/dt| roughly between 1e-150 and 1e150 (rescale t, e.g. to seconds)");
  }
}

}  // namespace

namespace detail {

inline constexpr double kMaxSensitivity = 1e6;

// The positions fit of a neural candidate core, for the comparison of cores: at most this many
// Levenberg–Marquardt steps (a G core on a 3-cart record ran its 100, 32 s, to lose).
inline constexpr long kNeuralComparisonIterations = 40;
// Per normalised trajectory, the state at every sample: the segments' fitted rollouts where a
// segment covers it (training and held-out blocks alike), the velocity start elsewhere.
std::vector<Matrix> segment_states(const std::vector<Trajectory>& nt,
                                   const detail::BlockSplit& split, const Cut& train,
                                   const Cut& val, const OneStepMap& map, ConstParams theta) {
  std::vector<Matrix> states;
  for (const Trajectory& t : nt) states.push_back(t.z);
  const auto write = [&](const Cut& c, const std::vector<Index>& ids) {
    for (Index s = 0; s < c.segs.size(); ++s) {
      const auto [b, first] = c.at[static_cast<std::size_t>(s)];
      const auto [j, a] = split.origin[static_cast<std::size_t>(ids[static_cast<std::size_t>(b)])];
      const Matrix z =
          shooting_states(map, theta, c.z0.col(s), c.segs.h[static_cast<std::size_t>(s)]);
      states[static_cast<std::size_t>(j)].middleCols(a + first, z.cols()) = z;
    }
  };
  write(val, split.val_ids);
  write(train, split.train_ids);
  return states;
}

// The blocks with q observed and p from the fitted rollouts of their segments.
std::vector<Trajectory> reconstructed(const std::vector<Trajectory>& blocks, const Cut& c,
                                      const OneStepMap& map, ConstParams theta, Index d) {
  std::vector<Trajectory> out = blocks;
  for (Index s = 0; s < c.segs.size(); ++s) {
    const auto [b, first] = c.at[static_cast<std::size_t>(s)];
    const Matrix z =
        shooting_states(map, theta, c.z0.col(s), c.segs.h[static_cast<std::size_t>(s)]);
    out[static_cast<std::size_t>(b)].z.block(d, first, d, z.cols()) = z.bottomRows(d);
  }
  return out;
}

// Sums over segments: the model's squared residual, the motion from each segment's first
// position, and the spread about each segment's mean (what a constant leaves: no dynamics).
struct SegmentSums {
  double res = 0.0, motion = 0.0, still = 0.0;
  Index n = 0;
};
SegmentSums segment_sums(const OneStepMap& map, ConstParams theta, const Cut& c) {
  SegmentSums out;
  for (Index s = 0; s < c.segs.size(); ++s) {
    const auto i = static_cast<std::size_t>(s);
    const Matrix& obs = c.segs.q[i];
    const Matrix z = shooting_states(map, theta, c.z0.col(s), c.segs.h[i]);
    // Only the observed positions count (a linked chain passes held-out ones unobserved).
    const Vector w =
        c.segs.observed.empty() ? Vector(Vector::Ones(obs.cols())) : c.segs.observed[i];
    const double count = w.sum();
    if (!(count > 0.0)) continue;
    Index first = 0;
    while (w(first) == 0.0) ++first;
    const Vector mean = (obs * w) / count;
    out.res += ((z.topRows(obs.rows()) - obs) * w.asDiagonal()).squaredNorm();
    out.motion += ((obs.colwise() - obs.col(first)) * w.asDiagonal()).squaredNorm();
    out.still += ((obs.colwise() - mean) * w.asDiagonal()).squaredNorm();
    out.n += static_cast<Index>(std::llround(count)) * obs.rows();
  }
  return out;
}

// The held-out quality on positions: the unexplained share of the motion within a segment, and
// the squared error over that of a constant per segment, its mean (no dynamics: the analogue of
// the pure contraction the states' null model is; on a record of noise alone a map with a free
// start state does hardly better, and the ratio stays near 1). Held-out segments in which
// nothing moves beyond the noise (their spread under twice what the training residuals give:
// the late, settled part of a decay) cannot show dynamics; the training segments then stand in
// for the null comparison, which still finds a record of noise alone (a few hundred
// parameters over thousands of positions absorb little of it). Returns which were used.
std::string positions_quality(const OneStepMap& map, ConstParams theta, const Cut& train,
                              const Cut& val, HeldOutQuality& q) {
  const SegmentSums v = segment_sums(map, theta, val);
  const SegmentSums t = segment_sums(map, theta, train);
  q.val_relative_residual = v.motion > 0.0 ? std::sqrt(v.res / v.motion) : 0.0;
  const double noise = t.n > 0 ? t.res / static_cast<double>(t.n) : 0.0;
  const bool val_moves = v.still > 2.0 * noise * static_cast<double>(v.n);
  const SegmentSums& use = val_moves ? v : t;
  q.null_ratio = use.still > 0.0 ? use.res / use.still : 0.0;
  if (!val_moves) q.val_relative_residual = t.motion > 0.0 ? std::sqrt(t.res / t.motion) : 0.0;
  return val_moves ? "held-out segments"
                   : "training segments (the held-out segments do not move beyond the noise)";
}

}  // namespace detail

namespace {

using detail::Cut;
using detail::cut_segments;
using detail::fit_segments;
using detail::free_parameters;
using detail::kMaxAbsState;
using detail::kMaxSensitivity;
using detail::kMinSegmentPositions;
using detail::kNeuralComparisonIterations;
using detail::kPositionsLmIterations;
using detail::samples_per_period;
using detail::SegmentFit;
using detail::segments_interval;

// The lag-one correlation of the residuals within the segments, pooled over segments and
// coordinates, and how many neighbouring pairs it pools.
struct LagOne {
  double rho = 0.0;
  Index pairs = 0;
};
LagOne residual_lag_one(const OneStepMap& map, ConstParams theta, const Matrix& z0,
                        const ShootingSegments& segs) {
  const Vector r = shooting_residuals(map, theta, z0, segs);
  const Index d = segs.d;
  double num = 0.0, den = 0.0;
  LagOne out;
  Index at = 0;
  for (Index s = 0; s < segs.size(); ++s) {
    const Index len = segs.q[static_cast<std::size_t>(s)].cols();
    for (Index k = 0; k < len; ++k)
      for (Index i = 0; i < d; ++i) {
        const double v = r(at + k * d + i);
        den += v * v;
        if (k + 1 < len) {
          num += v * r(at + (k + 1) * d + i);
          ++out.pairs;
        }
      }
    at += len * d;
  }
  out.rho = den > 0.0 ? num / den : 0.0;
  return out;
}

// The floor test of the positions route (detail::FloorTest): the library core, with its rest
// position terms, fitted to segments of up to two periods (80 positions at most) of the
// positions; when the lag-one correlation of its held-out residuals is within three standard
// errors (1/√pairs each) of what measurement noise leaves, nothing smooth is left for a neural
// core to explain, and those are not trained. Noise leaves −2/(L − 2) over segments of L
// positions: each coordinate's fitted start (a position and a momentum) takes the residuals'
// slowest part. A misfit of the force shows as a positive excess, the larger the longer the
// segments (over 10 positions the fitted starts absorb it). The velocity start's own test
// judges velocities from local fits, whose errors are smooth: there a linear two-cart record
// at 0.2% noise "left structure", and two neural cores were trained and fitted on the
// positions to lose (30 of a fit's 35 CPU s).
bool positions_floor(const detail::Candidate& library, const detail::BlockSplit& split, Index d,
                     double spp, std::string& why) {
  std::optional<detail::Candidate> rest = detail::with_rest_position_terms(library, d);
  const detail::Candidate& x = rest ? *rest : library;
  const Index len = std::clamp<Index>(static_cast<Index>(std::lround(2.0 * spp)), 10, 80);
  const Cut train = cut_segments(split.train_blocks, d, len);
  const Cut val = cut_segments(split.val_blocks, d, len);
  if (train.segs.size() == 0 || val.segs.size() == 0) {
    why = "no training or held-out segment of " + std::to_string(len) +
          " positions to judge the library core on: the neural cores were trained too";
    return false;
  }
  // Friction or drag chosen on the velocity start may be false (its local fits' errors grow
  // with the amplitude); the core is judged with and without it, the whiter wins.
  std::vector<const detail::Candidate*> versions = {&x};
  std::optional<detail::Candidate> viscous;
  if (const auto* lm = dynamic_cast<const HamiltonianLibraryMap*>(x.inner.map.get());
      lm != nullptr && !lm->dissipation().empty()) {
    viscous = detail::library_with(x, d, lm->terms(), {});
    versions.push_back(&*viscous);
  }
  const double noise = -2.0 / static_cast<double>(len - 2);
  LagOne best{std::numeric_limits<double>::infinity(), 0};
  for (const detail::Candidate* v : versions) {
    const OneStepMap& map = *v->inner.map;
    ShootingOptions opt;
    opt.iterations = kPositionsLmIterations;
    opt.patience = 20;
    opt.max_abs_state = kMaxAbsState;
    opt.should_stop = [] { return stop_requested(); };
    opt.converged_chi2 = 1e-3;
    opt.converged_se = detail::kDampingConvergedSe;
    opt.n_free = free_parameters(map, d);
    const SegmentFit fit = fit_segments(map, v->theta, train, val, opt);
    throw_if_stop_requested("the library core's test on the positions");
    const LagOne lag = residual_lag_one(map, fit.theta, fit.val.z0, fit.val.segs);
    if (std::isfinite(fit.rep.val_loss) && lag.rho < best.rho) best = lag;
  }
  const double bound = noise + 3.0 / std::sqrt(static_cast<double>(std::max<Index>(best.pairs, 1)));
  const bool white = best.rho <= bound;
  why = std::string(white ? "the library core's held-out position residuals are noise"
                          : "the library core leaves smooth structure in the held-out "
                            "positions") +
        " (lag-one correlation " + detail::significant(best.rho, 3) + " within segments of " +
        std::to_string(len) + " positions, where noise leaves " + detail::significant(noise, 3) +
        ", three standard errors " + detail::significant(bound - noise, 2) +
        "): the neural cores were " + (white ? "not trained" : "trained too");
  return white;
}

// The cores compared on what was observed: every trained candidate's segment fit on the
// positions, and the held-out loss of the positions decides. The velocity start's choice was
// made on velocities from local fits, whose noise hides the force law at many samples per
// period. Parsimony: the library core (a readable Hamiltonian with few parameters) is kept
// unless a neural core's held-out loss is lower by more than three of its standard errors
// (√(2/n) of itself); between neural cores the lower loss wins. Returns the chosen index, its
// fit in `chosen`, and records every candidate.
std::size_t choose_on_positions(detail::CoreFit& f, const Cut& train, const Cut& val, Index d,
                                const ShootingOptions& base, SegmentFit& chosen,
                                nlohmann::json& rec) {
  std::vector<std::optional<SegmentFit>> fits(f.cand.size());
  nlohmann::json tried = nlohmann::json::array();
  std::vector<std::size_t> tried_index;  // tried[k] is candidate tried_index[k]
  const auto is_library = [&](std::size_t i) {
    return f.cand[i].core.is_object() && f.cand[i].core.value("type", "") == "library";
  };
  const double n_val = static_cast<double>(std::max<Index>(1, val.segs.n_residuals()));
  for (std::size_t i = 0; i < f.cand.size(); ++i) {
    const detail::Candidate& x = f.cand[i];
    if (i != f.best && !(std::isfinite(x.val_loss) && x.theta.allFinite())) continue;
    const auto t0 = std::chrono::steady_clock::now();
    ShootingOptions opt = base;
    opt.n_free = free_parameters(*x.inner.map, d);
    // A neural core is compared after at most kNeuralComparisonIterations steps: the library
    // wins ties anyway, and a neural core chosen is fitted further by the linking.
    if (!is_library(i)) opt.iterations = std::min(opt.iterations, kNeuralComparisonIterations);
    fits[i] = fit_segments(*x.inner.map, x.theta, train, val, opt);
    tried_index.push_back(i);
    tried.push_back(
        {{"core", detail::core_name(x.core)},
         {"model", x.core},
         {"held_out_position_loss", fits[i]->rep.val_loss},
         {"training_position_loss", fits[i]->rep.final_loss},
         {"lm_iterations", fits[i]->rep.iterations},
         {"lm_message", fits[i]->rep.message},
         {"chosen_on_velocities", i == f.best},
         {"seconds",
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()}});
    if (fits[i]->rep.stopped) break;
  }
  std::size_t pick = f.best;
  const auto val_of = [&](std::size_t i) {
    const double v = fits[i] ? fits[i]->rep.val_loss : std::numeric_limits<double>::infinity();
    return std::isfinite(v) ? v : std::numeric_limits<double>::infinity();
  };
  std::optional<std::size_t> lib, neural;
  for (std::size_t i = 0; i < fits.size(); ++i) {
    if (!fits[i]) continue;
    if (is_library(i) && (!lib || val_of(i) < val_of(*lib))) lib = i;
    if (!is_library(i) && (!neural || val_of(i) < val_of(*neural))) neural = i;
  }
  std::string why;
  if (lib && neural) {
    const double v = val_of(*neural);
    const bool neural_wins = val_of(*lib) > v * (1.0 + 3.0 * std::sqrt(2.0 / n_val));
    pick = neural_wins ? *neural : *lib;
    why = neural_wins ? "the held-out loss of the positions: the neural core's is lower than "
                        "the library's by more than three standard errors"
                      : "the held-out loss of the positions: the library core's is within "
                        "three standard errors of the lowest (parsimony: a readable Hamiltonian "
                        "with few parameters)";
  } else {
    pick = lib ? *lib : neural ? *neural : f.best;
    why = "the only candidate fitted on the positions";
  }
  if (!fits[pick]) pick = f.best;
  for (std::size_t k = 0; k < tried.size(); ++k) tried[k]["chosen"] = tried_index[k] == pick;
  rec["core_choice"] = {{"candidates", tried}, {"reason", why}, {"validation_residuals", n_val}};
  chosen = std::move(*fits[pick]);
  return pick;
}

}  // namespace

namespace detail {

// The rest position is unknown from positions alone: every library candidate gets a linear
// term per coordinate (with_rest_position_terms). Returns the sentence for the report, empty
// when no term was added to the chosen core.
std::string add_rest_position_terms(CoreFit& f) {
  std::string said;
  for (std::size_t i = 0; i < f.cand.size(); ++i)
    if (std::optional<Candidate> x = with_rest_position_terms(f.cand[i], f.facts.d)) {
      f.cand[i] = std::move(*x);
      if (i != f.best) continue;
      said =
          "a linear term per coordinate added to the selected library terms: the rest "
          "position is not known from positions alone";
    }
  return said;
}

// After the linking (and the pruning): γ̂, the reconstructed momenta, the interval, the quality
// and the sensitivity of the fitted `map` (best's), into `out`.
void finish_on_positions(const OneStepMap& map, Candidate& best, Vector theta, CoreFit& f,
                         Cut& train, Cut& val, std::vector<Matrix>& states,
                         const ShootingReport& final_rep, const IdentifyHooks& hooks,
                         PositionsFit& out) {
  const Index d = f.facts.d;
  const Index n_free = free_parameters(map, d);
  BlockSplit& split = f.split;
  nlohmann::json& rec = out.record;
  best.theta = theta;
  const Normalization& units = f.units.normalization;
  out.fitted = true;
  out.gamma = map.damping_rate(theta).value_or(0.0) / units.time_scale;
  out.train_loss = final_rep.final_loss;
  out.val_loss = final_rep.val_loss;

  // The blocks with reconstructed momenta: the checks, the modes' mean state, the structure.
  for (std::size_t i = 0; i < split.train_blocks.size(); ++i) {
    const auto [j, a] = split.origin[static_cast<std::size_t>(split.train_ids[i])];
    Trajectory& blk = split.train_blocks[i];
    blk.z.bottomRows(d) = states[static_cast<std::size_t>(j)].block(d, a, d, blk.z.cols());
  }
  split.val_blocks = reconstructed(split.val_blocks, val, map, theta, d);
  split.set_window(1);
  split.blocks.clear();
  for (const auto& t : split.train_blocks) split.blocks.push_back(t);
  for (const auto& t : split.val_blocks) split.blocks.push_back(t);

  out.dissipation = dissipation_terms_report(map, theta, units, {});
  if (!out.stopped) {
    out.interval =
        segments_interval(map, interval_basis(f, theta, best.core, out.train_loss, out.val_loss),
                          train, split, n_free, false, hooks);
    out.stopped = out.interval.stopped;
    if (out.interval.degrees_of_freedom_factor)
      rec["degrees_of_freedom_factor"] = *out.interval.degrees_of_freedom_factor;
    if (out.interval.dissipation) out.dissipation = *out.interval.dissipation;
  }
  out.quality = measure_quality(map, theta, split, d);  // the structure residual; the shares:
  rec["quality_from"] = positions_quality(map, theta, train, val, out.quality);
  out.sensitivity = largest_sensitivity(map, theta, train);
  rec["sensitivity"] = out.sensitivity;
  rec["about"] =
      "the momenta are not observed: each segment's start state is fitted with the "
      "map, and the loss is on the positions alone (errors " +
      significant(std::sqrt(final_rep.final_loss)) + " rms in normalised units on training)";
}

// The options of every positions fit: `given`'s LM budget (else kPositionsLmIterations), the
// convergence rules of the damping rate.
ShootingOptions positions_options(const IdentifyConfig& given, const IdentifyHooks& hooks) {
  ShootingOptions opt;
  // Not the resolved lm_iterations: that is what the windows' LM spent (2 when the library core
  // arrived converged), and a positions fit started from velocities from local fits needs more.
  opt.iterations = given.lm_iterations > 0 ? given.lm_iterations : kPositionsLmIterations;
  opt.patience = 20;
  opt.max_abs_state = kMaxAbsState;
  opt.should_stop = [&hooks] { return hooks.should_stop && hooks.should_stop(); };
  opt.converged_chi2 = 1e-3;
  opt.converged_se = detail::kDampingConvergedSe;
  return opt;
}

PositionsFit refine_on_positions(const std::vector<Trajectory>& positions, CoreFit& f,
                                 const IdentifyConfig& given, const IdentifyHooks& hooks) {
  const auto t0 = std::chrono::steady_clock::now();
  PositionsFit out;
  out.stopped = f.stopped;
  const bool terms_given = given.core.is_object() && given.core.contains("terms");
  const Index d = f.facts.d;
  const std::vector<Trajectory>& nt = f.units.trajectories;
  const std::string rest_terms = f.config.init == nullptr && !terms_given && !out.stopped
                                     ? add_rest_position_terms(f)
                                     : std::string();
  if (!rest_terms.empty()) out.core = f.cand[f.best].core;
  const OneStepMap& start_map = *f.cand[f.best].inner.map;
  const double spp = samples_per_period(positions);
  nlohmann::json tried = nlohmann::json::array();
  const bool any = cut_segments(f.split.train_blocks, d, 10).segs.size() > 0;
  const Index len =
      any ? segment_length(start_map, f.cand[f.best].theta, f.split.train_blocks, d, spp, tried)
          : 10;
  Cut train = cut_segments(f.split.train_blocks, d, len);
  Cut val = cut_segments(f.split.val_blocks, d, len);
  nlohmann::json& rec = out.record;
  rec = {{"segment_length", len},
         {"segment_lengths_tried", tried},
         {"samples_per_period", spp},
         {"training_segments", train.segs.size()},
         {"validation_segments", val.segs.size()},
         {"hidden_unknowns", 2 * d * (train.segs.size() + val.segs.size())},
         {"positions_set_aside", train.set_aside + val.set_aside},
         {"shortest_segment", kMinSegmentPositions}};
  if (!rest_terms.empty()) rec["rest_position"] = rest_terms;
  if (train.segs.size() == 0 && !out.stopped)
    out.reasons.push_back(
        "no training trajectory has " + std::to_string(kMinSegmentPositions) +
        " positions in a row without a gap (" + std::to_string(train.set_aside) +
        " positions set aside): from positions alone a trajectory needs 2 to fix its hidden "
        "start state (a position and a momentum per coordinate) and at least one more to "
        "constrain the dynamics; expected longer trajectories");
  if (train.segs.size() == 0 || out.stopped || !f.lm_fits ||
      f.training.stop_reason == StopReason::kDiverged)
    return out;
  if (hooks.stage) hooks.stage("hidden momenta: positions-only Levenberg-Marquardt");
  ShootingOptions opt = positions_options(given, hooks);
  SegmentFit seg;
  const bool choosing = f.config.init == nullptr && f.cand.size() > 1;
  if (choosing) {
    const std::size_t was = f.best;
    f.best = choose_on_positions(f, train, val, d, opt, seg, rec);
    if (f.best != was) {
      out.core = f.cand[f.best].core;
      out.core_reason = rec["core_choice"]["reason"];
      out.training = f.cand[f.best].training;
      out.lm = f.cand[f.best].lm;
    }
  } else {
    opt.n_free = free_parameters(start_map, d);
    seg = fit_segments(start_map, f.cand[f.best].theta, train, val, opt);
  }
  Candidate& best = f.cand[f.best];
  const OneStepMap& map = *best.inner.map;
  const Index n_free = free_parameters(map, d);
  opt.n_free = n_free;
  rec["gauge"] = n_free < map.n_params()
                     ? "the per-dof momentum scales held at the velocity start's"
                 : d == 1 ? "d = 1: the momentum's scale is the core's"
                          : "the core's own: the momenta's units are in the library core's W and "
                            "V, fixed up to one common factor of H";
  Vector theta = seg.theta;
  train = std::move(seg.train);
  val = std::move(seg.val);
  const ShootingReport rep = seg.rep;
  rec["lm"] = {{"iterations", rep.iterations},
               {"accepted", rep.accepted},
               {"best_iteration", rep.best_iteration},
               {"initial_loss", rep.initial_loss},
               {"final_loss", rep.final_loss},
               {"validation_loss", rep.val_loss},
               {"message", rep.message}};
  if (rep.stopped) out.stopped = true;

  // The segments linked by continuity into chains over whole stretches of the record.
  BlockSplit& split = f.split;
  std::vector<Matrix> states = segment_states(nt, split, train, val, map, theta);
  ShootingReport final_rep = rep;
  if (!out.stopped) {
    if (hooks.stage) hooks.stage("hidden momenta: linking the segments");
    const RecordLayout layout = record_layout(nt, split);
    LinkedFit linked =
        link_segments(map, theta, nt, layout, len, states, val.segs, val.z0, opt, rep);
    rec["linking"] = linked.record;
    // The velocity stage's families and higher powers judged on the linked positions
    // (replaces `best`, so `map` is not used below: the fitted map is read from `best` again).
    if (f.config.init == nullptr && !terms_given && !linked.report.stopped) {
      best.theta = theta;
      if (judge_terms_on_chain(best, d, training_positions(split, d), nt, layout, linked, val, opt,
                               states, given.dissipation == "auto", rec)) {
        theta = best.theta;
        out.core = best.core;
      }
    }
    if (linked.chain.segs.size() > 0) {
      train.segs = std::move(linked.chain.segs);
      train.z0 = std::move(linked.chain.z0);
      train.at.clear();
      final_rep = linked.report;
    }
    if (linked.report.stopped) out.stopped = true;
  }
  finish_on_positions(*best.inner.map, best, theta, f, train, val, states, final_rep, hooks, out);
  rec["seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace detail

namespace {

// The data's own check does not apply: the momenta were not given.
ModelCheck momenta_not_given() {
  ModelCheck none;
  none.name = "measured_momenta";
  none.assumption = "momenta measured, not derived from the positions";
  none.applicable = false;
  none.passed = true;
  none.sentence =
      "not applicable: the record has positions alone; the momenta are hidden states fitted "
      "with the map";
  return none;
}

// The velocity start's half width (in the data's time) and the lag it came from.
struct VelocityStart {
  std::vector<Trajectory> states;  // the positions with velocities from local fits
  double half = 0.0, lag = 0.0;
};
VelocityStart velocity_start(const std::vector<Trajectory>& positions) {
  // Half the time over which the motion stays correlated, in the median step: the local fits
  // stay within the motion's own time scale.
  std::vector<double> steps;
  for (const Trajectory& t : positions)
    for (Index k = 1; k < t.t.size(); ++k) steps.push_back(t.t(k) - t.t(k - 1));
  require(!steps.empty(),
          "fit: every trajectory has a single position; expected at least one "
          "with two or more");
  std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2), steps.end());
  const double h_median = steps[steps.size() / 2];
  VelocityStart v;
  v.lag = half_correlation_lag(positions);
  v.half = std::clamp(std::floor(v.lag / 2.0), 2.0, 20.0) * h_median;
  for (const Trajectory& t : positions) v.states.push_back(with_local_velocities(t, v.half));
  check_velocity_start(v.states, h_median);
  return v;
}

// The positions route after refine_on_positions: the checks on the blocks with the momenta
// reconstructed, the growth rate, the verdict (and the sensitivity's reason), the Hamiltonian
// up to its factor.
detail::FinalFit judge_on_positions(const std::vector<Trajectory>& positions,
                                    const detail::CoreFit& f, const detail::PositionsFit& p,
                                    const detail::Refit& refit, const IdentifyConfig& config,
                                    const IdentifyHooks& hooks) {
  using namespace detail;
  FinalFit end;
  end.observed = "positions";
  end.choices["positions"] = p.record;
  if (p.core_reason) end.choices["core_reason"] = *p.core_reason;
  end.core = p.core;
  end.training = p.training;
  end.lm = p.lm;
  const Candidate& best = f.cand[f.best];
  const OneStepMap& map = *best.inner.map;
  const Normalization& units = f.units.normalization;
  end.theta = best.theta;
  bool stopped = f.stopped || p.stopped;
  ModelChecks checks = {momenta_not_given()};
  if (!p.fitted) {  // nothing fitted on the positions: the velocity start's fit, unassessed
    end.gamma = f.gamma;
    end.quality.train_loss = f.train_loss;
    end.quality.val_loss = f.val_loss;
    end.verdict = verdict(f.split, f.facts.h_max, f.lm_fits,
                          evidence(f, end, std::move(checks), p.reasons, stopped));
    end.stopped = stopped;
    return end;
  }
  end.gamma = p.gamma;
  end.quality = {p.train_loss, p.val_loss, p.quality.val_relative_residual, p.quality.null_ratio,
                 p.quality.structure_residual_max};
  end.interval = p.interval;
  end.dissipation = p.dissipation;
  if (!stopped && end.interval.interval)
    for (ModelCheck& k :
         run_checks(map, end.theta, f.split, units.time_scale, f.config.level, hooks))
      checks.push_back(std::move(k));
  if (refit && !stopped) {
    GrowthRate growth = confirm_growth(positions, refit, config, hooks, std::move(checks), stopped);
    checks = std::move(growth.checks);
    stopped = stopped || growth.stopped;
  }
  end.verdict = verdict(f.split, f.facts.h_max, f.lm_fits,
                        evidence(f, end, std::move(checks), p.interval.reasons, stopped));
  // From positions alone the momenta's unit is not observed: H is fixed up to one factor
  // (docs/derivations.md, "Positions only"), and its terms carry no intervals here.
  end.hamiltonian = hamiltonian_report(map, end.theta, units, {});
  if (!end.hamiltonian.is_null())
    end.hamiltonian["note"] =
        "fitted from positions alone: the momenta's unit is not observed, so H (kinetic and "
        "potential alike) is known up to one common factor; ratios of coefficients and the "
        "wavenumbers are what the data fix; no intervals";
  if (!(p.sensitivity <= kMaxSensitivity) && !stopped) {
    end.verdict.reasons.push_back(
        "the fitted map amplifies a perturbation of a segment's start state " +
        significant(p.sensitivity) +
        "-fold over the segment (more than 1e6): the hidden momenta sit on an unstable "
        "manifold of the map, where its derivatives and the interval mean nothing");
    end.verdict.identified = false;
    if (end.verdict.text == "identified") end.verdict.text = "not identified";
  }
  end.stopped = stopped;
  return end;
}

// identify_positions; with `confirm_growth`, a record that gains energy is fitted again in
// reversed time for its growth rate (detail::confirm_growth), as identify() does with momenta.
// `set_aside`: the given momenta's check, when they were set aside (it stands for the
// positions' own).
IdentifyResult positions_once(const std::vector<Trajectory>& positions,
                              const IdentifyConfig& config, const IdentifyHooks& hooks,
                              bool confirm_growth, const ModelCheck* set_aside = nullptr) {
  check_positions(positions);
  const VelocityStart start = velocity_start(positions);
  const double spp = samples_per_period(positions);
  const Index d = positions.front().z.rows();
  detail::CoreFit f = detail::fit_core(
      start.states, false, config, hooks,
      [spp, d](const detail::Candidate& lib, const detail::BlockSplit& split, std::string& why) {
        return positions_floor(lib, split, d, spp, why);
      });
  const detail::PositionsFit p = detail::refine_on_positions(positions, f, config, hooks);
  detail::Refit refit;
  if (confirm_growth)
    refit = [&](const std::vector<Trajectory>& reversed) {
      return positions_once(reversed, config, hooks, false);
    };
  detail::FinalFit end = judge_on_positions(positions, f, p, refit, config, hooks);
  end.choices["velocity_start"] = {
      {"method", "local quadratic least squares"},
      {"half_width_time", start.half},
      {"half_correlation_lag_samples", start.lag},
      {"about", "a start for the hidden momenta only; gamma comes from the positions alone"}};
  if (set_aside != nullptr) {
    end.verdict.checks.front() = *set_aside;
    end.choices["momenta_set_aside"] =
        "the given momenta are a filter of the noisy positions (check measured_momenta)";
  }
  return detail::assemble(f, end);
}

}  // namespace

IdentifyResult identify_positions(const std::vector<Trajectory>& positions,
                                  const IdentifyConfig& config, const IdentifyHooks& hooks) {
  return positions_once(positions, config, hooks, true);
}

namespace detail {

IdentifyResult positions_in_place_of_momenta(const std::vector<Trajectory>& positions,
                                             const IdentifyConfig& config,
                                             const IdentifyHooks& hooks,
                                             const ModelCheck& set_aside) {
  return positions_once(positions, config, hooks, true, &set_aside);
}

}  // namespace detail

}  // namespace csympnet
