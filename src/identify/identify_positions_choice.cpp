// The positions route's choices of the core (identify_positions.hpp): whether the library core
// leaves the positions at the noise floor, so that the neural cores are not trained
// (positions_floor), and the cores compared on the positions (choose_on_positions).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "csympnet/core/stop.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/train/shooting.hpp"
#include "identify_chain.hpp"
#include "identify_positions.hpp"

namespace csympnet::detail {

// The library terms are judged on the floor test's segments up to this d. The changes offered
// are per coordinate (powers, sin/cos pairs); a chain's force laws are in the differences of
// neighbours, and on the benchmark's 4- and 8-mass chains from positions no such search left
// noise, while at d = 8 it cost 30 of a fit's 187 CPU s.
inline constexpr Index kTermsOnPositionsMaxD = 3;

// The positions fit of a neural candidate core, for the comparison of cores: at most this many
// Levenberg–Marquardt steps (a G core on a 3-cart record ran its 100, 32 s, to lose).
inline constexpr long kNeuralComparisonIterations = 40;

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

namespace {

ShootingOptions floor_options() {
  ShootingOptions opt;
  opt.iterations = kPositionsLmIterations;
  opt.patience = 20;
  opt.max_abs_state = kMaxAbsState;
  opt.should_stop = [] { return stop_requested(); };
  opt.converged_chi2 = 1e-3;
  opt.converged_se = detail::kDampingConvergedSe;
  return opt;
}

// Whether a lag-one correlation over segments of `len` positions is within three standard
// errors of what noise leaves; `bound` is that limit.
bool is_white(const LagOne& lag, Index len, double& bound) {
  const double noise = -2.0 / static_cast<double>(len - 2);
  bound = noise + 3.0 / std::sqrt(static_cast<double>(std::max<Index>(lag.pairs, 1)));
  return lag.rho <= bound;
}

// The library terms judged on the floor test's segments (terms_on_segments) from `version`
// (fitted there: `fit`, its held-out lag-one correlation `before`): the changed core when its
// held-out residuals are then noise, none otherwise; recorded in rec["terms_on_positions"].
// The search ends at the first core that leaves noise: parsimony (the linked chain judges the
// terms again; on a pendulum record it went on past the sin/cos pair to add q1^3 and q1^4) and
// cost. (Ending it too after a change that removed less than 1/(2d) of the correlation's excess
// over noise lost a 3-mass Toda chain, whose first change raised the correlation from 0.28 to
// 0.30 and whose fourth left noise.)
std::optional<TermsOnSegments> terms_that_leave_noise(const detail::Candidate& version,
                                                      const SegmentFit& fit,
                                                      const detail::BlockSplit& split, Index d,
                                                      Index len, const LagOne& before,
                                                      nlohmann::json& rec) {
  nlohmann::json lags = nlohmann::json::array();
  const auto stop = [&](const detail::Candidate& c, const SegmentFit& f) {
    const LagOne lag = residual_lag_one(*c.inner.map, f.theta, f.val.z0, f.val.segs);
    lags.push_back(lag.rho);
    double bound = 0.0;
    return std::isfinite(f.rep.val_loss) && is_white(lag, len, bound);
  };
  TermsOnSegments t =
      terms_on_segments(version, fit, d, training_positions(split, d), floor_options(), stop);
  bool white = false;
  if (t.changed) {
    const LagOne lag =
        residual_lag_one(*t.lib.inner.map, t.fit.theta, t.fit.val.z0, t.fit.val.segs);
    double bound = 0.0;
    white = std::isfinite(t.fit.rep.val_loss) && is_white(lag, len, bound);
  }
  rec["terms_on_positions"] = {
      {"rule",
       "where the library core leaves smooth structure in the positions, each coordinate's "
       "missing powers 3 and 4 and its sin/cos pair (added, or in place of its powers 3 and 4), "
       "and each sin/cos or exp group in place of the powers of its argument, are fitted to the "
       "same segments of the positions, and the best change is made while it lowers the "
       "Bayesian information criterion of the training positions, n log(loss) + parameters x "
       "log n, until the held-out residuals are noise (d <= 3); the changed core replaces the "
       "velocity stage's when its held-out residuals are then noise"},
      {"positions_per_segment", len},
      {"residuals", t.fit.train.segs.n_residuals()},
      {"trials", t.trials},
      {"terms", t.lib.core["terms"]},
      {"lag_one_correlation_before", before.rho},
      {"lag_one_correlation_after_each_change", lags},
      {"adopted", white}};
  if (!white) return std::nullopt;
  return t;
}

}  // namespace

// The floor test of the positions route (detail::FloorTest): the library core, with its rest
// position terms, fitted to segments of up to two periods (80 positions at most) of the
// positions (at most 20,000 positions a side, evenly spread); when the lag-one correlation of its
// held-out residuals is within three standard errors (1/√pairs each) of what measurement noise
// leaves, nothing smooth is left for a neural core to explain, and those are not trained. Noise
// leaves −2/(L − 2) over segments of L positions: each coordinate's fitted start (a position and a
// momentum) takes the residuals' slowest part. A misfit of the force shows as a positive excess,
// the larger the longer the segments (over 10 positions the fitted starts absorb it). The velocity
// start's own test judges velocities from local fits, whose errors are smooth: there a linear
// two-cart record at 0.2% noise "left structure", and two neural cores were trained and fitted on
// the positions to lose (30 of a fit's 35 CPU s). Where the velocity stage's terms leave structure,
// the terms are judged on the same segments first (terms_that_leave_noise): between families that
// differ by less than the velocities' errors, its choice was a coin toss.
bool positions_floor(detail::Candidate& library, const detail::BlockSplit& split, Index d,
                     double spp, std::string& why, nlohmann::json& rec) {
  std::optional<detail::Candidate> rest = detail::with_rest_position_terms(library, d);
  const detail::Candidate& x = rest ? *rest : library;
  const Index len = std::clamp<Index>(static_cast<Index>(std::lround(2.0 * spp)), 10, 80);
  // A choice, as the library's selection: at most kSelectionWindows positions a side, in whole
  // segments evenly spread over the record. The test's three standard errors are then at
  // least 3/√20000 = 0.021 in the correlation (on 10⁶ samples the test had fitted every
  // segment: 40 of the fit's 221 CPU s).
  const Index cap = std::max<Index>(1, detail::kSelectionWindows / len);
  const Cut all_train = cut_segments(split.train_blocks, d, len);
  if (all_train.segs.size() == 0) {
    // The positions-only fit that follows has nothing to fit whatever the core ("not
    // identified", refine_on_positions): no neural core is trained for it. Such a record of
    // 600 positions took 7 CPU s in the neural cores, 55 under the sanitizers.
    why = "no training trajectory has " + std::to_string(kMinSegmentPositions) +
          " positions in a row without a gap: no core can be fitted to the positions, so the "
          "neural cores were not trained";
    return true;
  }
  const Cut train = evenly_spread_segments(all_train, cap);
  const Cut val = evenly_spread_segments(cut_segments(split.val_blocks, d, len), cap);
  rec["floor_segments"] = {{"training", train.segs.size()},
                           {"held_out", val.segs.size()},
                           {"positions_per_segment", len},
                           {"at_most", cap}};
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
  const detail::Candidate* best_version = nullptr;
  std::optional<SegmentFit> best_fit;
  const ShootingOptions base = floor_options();
  for (const detail::Candidate* v : versions) {
    const OneStepMap& map = *v->inner.map;
    ShootingOptions opt = base;
    opt.n_free = free_parameters(map, d);
    SegmentFit fit = fit_segments(map, v->theta, train, val, opt);
    throw_if_stop_requested("the library core's test on the positions");
    const LagOne lag = residual_lag_one(map, fit.theta, fit.val.z0, fit.val.segs);
    if (std::isfinite(fit.rep.val_loss) && lag.rho < best.rho) {
      best = lag;
      best_version = v;
      best_fit = std::move(fit);
    }
  }
  double bound = 0.0;
  bool white = is_white(best, len, bound);
  std::string judged;
  // Smooth structure left: the terms judged on these segments, adopted when they leave noise.
  if (!white && d <= kTermsOnPositionsMaxD && best_version != nullptr &&
      dynamic_cast<const HamiltonianLibraryMap*>(best_version->inner.map.get()) != nullptr) {
    std::optional<TermsOnSegments> t =
        terms_that_leave_noise(*best_version, *best_fit, split, d, len, best, rec);
    if (t) {
      library = std::move(t->lib);
      best = residual_lag_one(*library.inner.map, t->fit.theta, t->fit.val.z0, t->fit.val.segs);
      white = is_white(best, len, bound);
      std::string names;
      for (const auto& term : library.core["terms"])
        names += (names.empty() ? "" : ", ") + term.get<std::string>();
      judged = " with the terms judged on the positions (" + names + ")";
    }
  }
  why = std::string(white ? "the library core's held-out position residuals are noise"
                          : "the library core leaves smooth structure in the held-out "
                            "positions") +
        judged + " (lag-one correlation " + detail::significant(best.rho, 3) +
        " within segments of " + std::to_string(len) + " positions, where noise leaves " +
        detail::significant(noise, 3) + ", three standard errors " +
        detail::significant(bound - noise, 2) + "): the neural cores were " +
        (white ? "not trained" : "trained too");
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

}  // namespace csympnet::detail
