// The whole-record fit of records with momenta (docs/derivations.md, "Momenta observed: the
// whole record"; docs/identification.md, "Records with momenta").
//
// The windows of fit_core() see a trajectory a few steps at a time: the decay from one window
// to the next, where the damping rate lives, is not used, and a record that decays into its
// noise leaves each window with little to tell γ by. Here the model fitted on the windows
// starts a multiple-shooting fit of the whole record in which both q and p are observed, each
// with its own noise (an errors-in-variables fit):
//
//   1. the training blocks are cut into segments; each segment's start state is an unknown,
//      fitted with θ, and the residuals are the observed states minus the rollout, each row
//      weighted by the inverse of its noise level (estimated from the start-state fits);
//   2. the segments are linked by continuity into chains over whole stretches of the record
//      (identify_chain.hpp), where the model follows them, and the library core's terms are
//      judged over the chain as on the positions route;
//   3. γ̂'s interval is the cluster-robust sandwich over the same blocks from the chain's normal
//      equations, the start states eliminated (identify_segments.hpp).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "csympnet/train/shooting.hpp"
#include "identify_chain.hpp"
#include "identify_segments.hpp"
#include "identify_stages.hpp"

namespace csympnet::detail {

namespace {

// Per observed row, the root-mean-square residual of the segments at (θ, their start states).
Vector row_noise(const OneStepMap& map, ConstParams theta, const Cut& c) {
  const Index rows = c.segs.observed_rows();
  Vector sum = Vector::Zero(rows);
  double count = 0.0;
  for (Index s = 0; s < c.segs.size(); ++s) {
    const auto i = static_cast<std::size_t>(s);
    const Matrix z = shooting_states(map, theta, c.z0.col(s), c.segs.h[i]);
    const Matrix r = z.topRows(rows) - c.segs.q[i];
    sum += r.rowwise().squaredNorm();
    count += static_cast<double>(r.cols());
  }
  return count > 0.0 ? Vector((sum / count).cwiseSqrt()) : Vector(Vector::Ones(rows));
}

// Row weights 1/σ_i from the noise levels σ, normalised to 1 on average over the positions'
// rows, and held within 10⁴ of each other: a row the model reproduces to rounding (noise-free
// data) must not take the whole weight.
Vector weights_from_noise(const Vector& sigma, Index d) {
  const double top = sigma.maxCoeff();
  if (!(top > 0.0) || !sigma.allFinite()) return Vector::Ones(sigma.size());
  Vector w = sigma.cwiseMax(1e-4 * top).cwiseInverse();
  return w / w.head(d).mean();
}

// The segments' row weights from their own residuals: start states fitted with θ fixed under
// the current weights, the noise per row measured, twice (from equal weights).
void estimate_row_weights(const OneStepMap& map, ConstParams theta, Index d, Cut& train, Cut& val,
                          nlohmann::json& rec) {
  train.segs.row_weight = Vector::Ones(2 * d);
  Vector sigma;
  for (int round = 0; round < 2; ++round) {
    fit_start_states(map, theta, train.segs, train.z0, 30, round == 0, kMaxAbsState,
                     kScoringTolerance);
    sigma = row_noise(map, theta, train);
    train.segs.row_weight = weights_from_noise(sigma, d);
  }
  val.segs.row_weight = train.segs.row_weight;
  rec["row_noise"] = std::vector<double>(sigma.data(), sigma.data() + sigma.size());
  rec["row_weights"] =
      std::vector<double>(train.segs.row_weight.data(), train.segs.row_weight.data() + 2 * d);
}

}  // namespace

// "auto": the library core (a few parameters; a neural core's thousands make every segment's
// sensitivities costly: an FPU chain of 16 dof took minutes where its windows took 6 s).
bool whole_record_wanted(const nlohmann::json& core, const IdentifyConfig& config) {
  if (config.record_fit != "auto") return config.record_fit == "whole";
  return core.is_object() && core.value("type", "") == "library";
}

WholeRecordFit fit_whole_record(CoreFit& f, const IdentifyConfig& given,
                                const IdentifyHooks& hooks) {
  const auto t0 = std::chrono::steady_clock::now();
  const Index d = f.facts.d, rows = 2 * d;
  const std::vector<Trajectory>& nt = f.units.trajectories;
  Candidate& best = f.cand[f.best];
  WholeRecordFit out;
  nlohmann::json& rec = out.record;
  rec = {{"method",
          "multiple shooting over the whole record with q and p observed, each row weighted by "
          "its noise (errors in variables); segments linked by continuity"}};
  if (hooks.stage) hooks.stage("whole record: the segments' length");
  const double spp = samples_per_period(nt);
  nlohmann::json tried = nlohmann::json::array();
  if (cut_segments(f.split.train_blocks, d, 10, rows).segs.size() == 0) {
    rec["skipped"] = "no training block has 10 samples in a row without a gap";
    return out;
  }
  const Index len =
      segment_length(*best.inner.map, best.theta, f.split.train_blocks, d, spp, tried, rows);
  Cut train = cut_segments(f.split.train_blocks, d, len, rows);
  Cut val = cut_segments(f.split.val_blocks, d, len, rows);
  rec["segment_length"] = len;
  rec["segment_lengths_tried"] = tried;
  rec["samples_per_period"] = spp;
  if (hooks.stage) hooks.stage("whole record: states observed, segments fitted");
  estimate_row_weights(*best.inner.map, best.theta, d, train, val, rec);

  ShootingOptions opt;
  opt.iterations = given.lm_iterations > 0 ? given.lm_iterations : kPositionsLmIterations;
  opt.patience = 20;
  opt.max_abs_state = kMaxAbsState;
  opt.should_stop = [&hooks] { return hooks.should_stop && hooks.should_stop(); };
  opt.converged_chi2 = 1e-3;
  opt.converged_se = kDampingConvergedSe;
  opt.n_free = best.inner.map->n_params();
  SegmentFit seg = fit_segments(*best.inner.map, best.theta, train, val, opt);
  rec["segment_fit"] = {{"iterations", seg.rep.iterations},
                        {"initial_loss", seg.rep.initial_loss},
                        {"final_loss", seg.rep.final_loss},
                        {"validation_loss", seg.rep.val_loss},
                        {"message", seg.rep.message}};
  if (seg.rep.stopped) {
    out.stopped = true;
    return out;
  }
  Vector theta = seg.theta;
  train = std::move(seg.train);
  val = std::move(seg.val);

  RecordLayout layout = record_layout(nt, f.split);
  layout.observed_rows = rows;
  layout.row_weight = train.segs.row_weight;
  // Every sample's state: observed; the linking carries its own rollouts into it.
  std::vector<Matrix> states;
  for (const Trajectory& t : nt) states.push_back(t.z);
  if (hooks.stage) hooks.stage("whole record: states observed, segments linked");
  LinkedFit linked = link_segments(*best.inner.map, theta, nt, layout, len, states, val.segs,
                                   val.z0, opt, seg.rep);
  rec["linking"] = linked.record;
  const bool terms_given = given.core.is_object() && given.core.contains("terms");
  if (f.config.init == nullptr && !terms_given && !linked.report.stopped) {
    best.theta = theta;
    Matrix q = training_positions(f.split, d);
    const StageNamer stage = [&hooks](const char* part) {
      if (hooks.stage) hooks.stage(std::string("whole record: ") + part);
    };
    if (judge_terms_on_chain(best, d, q, nt, layout, linked, val, opt, states,
                             given.dissipation == "auto", rec, stage)) {
      theta = best.theta;
      out.core = best.core;
    }
  }
  if (linked.report.stopped) {
    out.stopped = true;
    return out;
  }
  if (linked.chain.segs.size() > 0) {
    train.segs = std::move(linked.chain.segs);
    train.z0 = std::move(linked.chain.z0);
    train.at.clear();
  }
  const OneStepMap& map = *best.inner.map;
  best.theta = theta;
  out.theta = theta;
  out.gamma = map.damping_rate(theta).value_or(0.0) / f.units.normalization.time_scale;
  // The held-out inflation compares the chain's losses per residual, as the positions route.
  out.train_loss = linked.chain.segs.size() > 0 ? linked.report.final_loss : seg.rep.final_loss;
  out.val_loss = linked.chain.segs.size() > 0 ? linked.report.val_loss : seg.rep.val_loss;
  const nlohmann::json& core = out.core ? *out.core : f.config.core;
  out.interval =
      segments_interval(map, interval_basis(f, theta, core, out.train_loss, out.val_loss), train,
                        f.split, map.n_params(), true, hooks);
  out.stopped = out.interval.stopped;
  if (out.interval.degrees_of_freedom_factor)
    rec["degrees_of_freedom_factor"] = *out.interval.degrees_of_freedom_factor;
  rec["seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // Fitted: its interval, or the reason it has none, stands (the windows' interval at this θ
  // would be neither fit's).
  out.fitted = true;
  return out;
}

}  // namespace csympnet::detail
