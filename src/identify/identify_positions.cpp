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

#include "../train/lapack.hpp"
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
#include "identify_positions.hpp"
#include "identify_segments.hpp"
#include "identify_stages.hpp"

namespace csympnet {

namespace detail {

inline constexpr double kMaxSensitivity = 1e6;

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
  if (hooks.stage) hooks.stage("hidden momenta: rest position, the segments' length");
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
      const StageNamer stage = [&hooks](const char* part) {
        if (hooks.stage) hooks.stage(std::string("hidden momenta: ") + part);
      };
      if (judge_terms_on_chain(best, d, training_positions(split, d), nt, layout, linked, val, opt,
                               states, given.dissipation == "auto", rec, stage)) {
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
  detail::check_positions(positions);
  const detail::VelocityStart start = detail::velocity_start(positions);
  const double spp = detail::samples_per_period(positions);
  const Index d = positions.front().z.rows();
  detail::CoreFit f = detail::fit_core(
      start.states, false, config, hooks,
      [spp, d](detail::Candidate& lib, const detail::BlockSplit& split, std::string& why,
               nlohmann::json& rec) {
        return detail::positions_floor(lib, split, d, spp, why, rec);
      },
      // The positions fit refits θ from the windows' (refine_on_positions).
      [](const nlohmann::json&) { return true; });
  const detail::PositionsFit p = detail::refine_on_positions(positions, f, config, hooks);
  // Not made (no segment of 3 positions, or more than 6,000 parameters): the windows' θ is
  // the answer, fitted on every window.
  if (!p.fitted && !p.stopped && !f.stopped) detail::windows_on_every_window(f, config, hooks);
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
  const lapack::SingleThreaded one_thread;  // the same bits on every core count (lapack.hpp)
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
