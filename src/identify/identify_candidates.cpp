// Stages of the identification that train: the candidate cores, AdamW and Levenberg–Marquardt
// on the window loss, the choice of core, and longer windows (identify_stages.hpp).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "identify_evaluators.hpp"
#include "identify_stages.hpp"

namespace csympnet::detail {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

// The candidate cores, chosen between by validation loss (choose_core).
//  - LA(5, 20) for d = 1; for d > 1 LA(4, m) with m ≤ 10 sublayers, fewer from d = 8 on, so
//    that a sublayer sweep holds about 1,200 parameters: an LM iteration forms JᵀJ, rows × P²
//    flops (seconds at d = 10 with 2,000 samples and P = 4,000), and factorises it. With step
//    polynomials when the steps vary. Exact for linear systems; its activation modules act
//    coordinate by coordinate, so a coupled or strongly nonlinear force is approximated
//    coarsely.
//  - G(6, w): six gradient modules, alternately kicks p += h Kᵀ(a ⊙ σ(K q + b)) and drifts,
//    each a ridge-function sum of width w ≤ 32, about 1,200 parameters at most. A learned
//    splitting method: any smooth potential, coupled or not; each module scales with h, so
//    irregular steps need no step polynomials.
std::vector<nlohmann::json> default_cores(Index d, bool varying_steps) {
  nlohmann::json la;
  if (d == 1) {
    la = {{"type", "la"}, {"layers", 5}, {"sublayers", 20}};
  } else {
    const Index per_sublayer = 4 * d * (d + 1) / 2;
    const Index m = std::clamp<Index>(1200 / per_sublayer, 2, 10);
    la = {{"type", "la"}, {"layers", 4}, {"sublayers", m}};
  }
  if (varying_steps) la["step_terms"] = 2;
  const Index g_layers = 6;
  const Index width = std::clamp<Index>(1200 / (g_layers * (d + 2)), 8, 32);
  nlohmann::json g = {{"type", "g"}, {"layers", g_layers}, {"width", width}};
  return {la, g};
}

std::string core_name(const nlohmann::json& core) {
  const std::string type = core.value("type", "?");
  if (type == "la")
    return "la:" + std::to_string(core.value("layers", 0)) + ":" +
           std::to_string(core.value("sublayers", 0)) +
           (core.value("step_terms", 1) == 2 ? ":h2" : "");
  if (type == "g")
    return "g:" + std::to_string(core.value("layers", 0)) + ":" +
           std::to_string(core.value("width", 0));
  if (type == "library") return "library";
  return core.dump();
}

std::vector<Candidate> make_candidates(const std::vector<nlohmann::json>& cores, Index d,
                                       double beta_init, const IdentifyConfig& c,
                                       std::uint64_t seed) {
  const IdentifyInit* init = c.init.get();
  std::vector<Candidate> cand(cores.size());
  for (std::size_t k = 0; k < cores.size(); ++k) {
    Candidate& x = cand[k];
    x.core = cores[k];
    if (init != nullptr) {  // the file's map in its normalised units, and its θ
      x.inner = make_model(init->inner_spec);
      x.theta = init->theta;
      continue;
    }
    nlohmann::json spec = {
        {"type", "csympnet"}, {"d", d}, {"core", x.core}, {"beta_init", beta_init}};
    if (c.dof_scales == DofScales::kLearned && d > 1) spec["dof_scales"] = to_string(c.dof_scales);
    x.inner = make_model(spec);
    x.theta.resize(x.inner.n_params());
    Rng init_rng(seed, k == 0 ? std::string("init") : "init-" + std::to_string(k));
    x.inner.init_params(init_rng, x.theta);
  }
  return cand;
}

CandidateFit::CandidateFit(const IdentifyConfig& given, const IdentifyConfig& resolved,
                           const IdentifyHooks& hooks, const Communicator& comm,
                           const BlockSplit& split, double share)
    : given_(&given), c_(&resolved), hooks_(&hooks), comm_(&comm), split_(&split), share_(share) {}

bool CandidateFit::stop_requested() const {
  return hooks_->should_stop && hooks_->should_stop();
}

double CandidateFit::loss(const Candidate& x, const WindowSet& w) const {
  return ChunkedWindowLoss(*x.inner.map, w, c_->balanced, *comm_, c_->threads)(x.theta, nullptr);
}

// The AdamW budget by an estimate of an epoch's seconds (about 4 ns per sample, step and
// parameter on one core), about 10 s in all (shared by the candidates), between 300 and
// 50,000 epochs. From a model file, AdamW runs only when epochs are given: LM starts from
// the file's θ.
long CandidateFit::epochs_for(const Candidate& x) const {
  if (given_->epochs > 0) return given_->epochs;
  if (given_->init != nullptr) return 0;
  const double epoch_seconds = 4e-9 * static_cast<double>(split_->train.size()) *
                               static_cast<double>(split_->m) *
                               static_cast<double>(x.inner.n_params());
  return std::clamp<long>(std::lround(10.0 * share_ / epoch_seconds), 300, 50000);
}

void CandidateFit::adamw(Candidate& x, const std::string& label) const {
  if (stop_requested()) return;
  const OneStepMap& map = *x.inner.map;
  const bool bal = c_->balanced;
  auto train_loss =
      std::make_shared<ChunkedWindowLoss>(map, split_->train, bal, *comm_, c_->threads);
  auto val_loss = std::make_shared<ChunkedWindowLoss>(map, split_->val, bal, *comm_, c_->threads);
  if (epochs_for(x) == 0) {  // none: the summary of the parameters as they are
    x.training = TrainSummary{};
    x.training.best_val_loss = (*val_loss)(x.theta, nullptr);
    x.training.final_train_loss = (*train_loss)(x.theta, nullptr);
    return;
  }
  if (hooks_->stage) hooks_->stage(label);
  Objective o;
  o.n_params = x.inner.n_params();
  o.damping_index = map.damping_param_index();
  o.damping_rate = [&map](const Vector& th) { return map.damping_rate(th); };
  o.train_loss = [train_loss](const Vector& th, Vector& grad) { return (*train_loss)(th, &grad); };
  o.val_loss = [val_loss](const Vector& th) { return (*val_loss)(th, nullptr); };
  TrainOptions t;
  t.epochs = epochs_for(x);
  t.adamw.lr = c_->lr;
  t.adamw.decay_damping = false;  // no pull of γ̂ towards 0
  t.lr_schedule = LrSchedule::kCosine;
  t.threads = c_->threads;
  ProgressCallback cb = [this](const TrainProgress& p) {
    if (stop_requested()) return false;
    return hooks_->progress ? hooks_->progress(p) : true;
  };
  x.training = train_parameters(o, x.theta, t, cb);
}

// The LM budget by work: an estimate of one iteration's seconds on one core (a reverse pass
// per row of J and step, about 5 µs + 30 ns per parameter, measured on d = 1 and d = 2; the
// Gram matrix; the factorisation), so that LM takes about `target` seconds; a patience of
// 100 iterations without a better validation loss ends it sooner. At least `floor`
// iterations (a stage that must run); a continuation passes 0 and is skipped when its share
// buys no iteration.
long CandidateFit::lm_budget(const Candidate& x, double target, long floor) const {
  if (given_->lm_iterations > 0) return given_->lm_iterations;
  const Index np = x.inner.n_params();
  if (np > 6000) return 0;
  const double rows = static_cast<double>(split_->train.size() * split_->train.dim());
  const double p_d = static_cast<double>(np);
  const double seconds = rows * static_cast<double>(split_->m) * (5e-6 + 30e-9 * p_d) +
                         rows * p_d * p_d / 3e10 + p_d * p_d * p_d / 3e10;
  return std::clamp<long>(std::lround(target / seconds), floor, 3000);
}

void CandidateFit::lm(Candidate& x, long budget, const std::string& label, LmEnd end) {
  if (stopped_ || stop_requested() || x.training.stop_reason == StopReason::kDiverged ||
      budget <= 0)
    return;
  if (hooks_->stage) hooks_->stage(label);
  const OneStepMap& map = *x.inner.map;
  const WindowSet& train = split_->train;
  const bool bal = c_->balanced;
  const double sc = 1.0 / std::sqrt(static_cast<double>(train.size()));
  const auto stop = [this] { return stop_requested(); };
  LeastSquaresProblem prob;
  prob.n_residuals = train.size() * train.dim();
  prob.n_params = x.inner.n_params();
  prob.residuals = [&](ConstParams th, Eigen::Ref<Vector> res) {
    res = sc * window_residuals(map, th, train, bal);
    return true;
  };
  prob.normal_equations = [&](ConstParams th, Matrix& a, Vector& g) {
    // Polled per chunk: a large core's normal equations take seconds.
    NormalEquations ne = normal_equations_over_ranks(map, th, train, bal, sc, false, stop, *comm_);
    a = std::move(ne.a);
    g = std::move(ne.g);
  };
  IterationCallbacks callbacks;
  callbacks.progress = hooks_->progress;
  callbacks.should_stop = stop;
  callbacks.patience = kLmPatience;
  ChunkedWindowLoss val_loss(map, split_->val, bal, *comm_, c_->threads);
  IterationMonitor monitor(
      "lm", budget, [&](const Vector& th) { return val_loss(th, nullptr); }, x.theta, callbacks,
      [&map](const Vector& th) { return map.damping_rate(th); });
  prob.should_stop = [&monitor] { return monitor.interrupted(); };
  const auto t0 = std::chrono::steady_clock::now();
  LmSettings ls;
  ls.max_iterations = budget;
  ls.chi2_tolerance = kLmChi2Tolerance;
  if (end == LmEnd::kChi2OrGammaSettled) {
    ls.watch_index = map.damping_param_index().value_or(-1);
    ls.converged_se = kDampingConvergedSe;
  }
  Vector th = x.theta;
  LmReport rep = levenberg_marquardt(prob, th, ls, lm_hooks(monitor));
  x.theta = monitor.best();
  if (stop_requested()) stopped_ = true;
  if (monitor.cause() == StopCause::kPatience)
    rep.message = "no better validation loss in " + std::to_string(kLmPatience) + " iterations";
  x.lm = rep;
  x.lm_best_iteration = monitor.best_iteration();
  x.lm_seconds += seconds_since(t0);
}

Vector CandidateFit::gauss_newton_step(const Candidate& x) const {
  const WindowSet& train = split_->train;
  const double sc = 1.0 / std::sqrt(static_cast<double>(train.size()));
  const auto stop = [this] { return stop_requested(); };
  const NormalEquations ne = normal_equations_over_ranks(*x.inner.map, x.theta, train, c_->balanced,
                                                         sc, false, stop, *comm_);
  if (ne.stopped) return {};
  return csympnet::gauss_newton_step(ne);
}

namespace {

// The winner continues where its LM stopped, with the rest of the one-step budget.
long continue_winner(Candidate& best, CandidateFit& fit, std::size_t n_cand,
                     const IdentifyConfig& given) {
  long lm_total = n_cand > 1 ? fit.lm_budget(best, 10.0, 2) : fit.lm_budget(best, 25.0);
  const long more = n_cand > 1 && given.lm_iterations == 0 && best.lm.iterations > 0 &&
                            best.lm.message.rfind("no better", 0) != 0 &&
                            best.lm.message.rfind("converged", 0) != 0 && !fit.stopped()
                        ? fit.lm_budget(best, 12.0, 0)
                        : 0;
  if (more > 0) {
    const LmReport first = best.lm;
    const long first_best = best.lm_best_iteration;
    fit.lm(best, more, "LM (continued, " + core_name(best.core) + ")",
           CandidateFit::LmEnd::kChi2OrGammaSettled);
    best.lm_best_iteration =
        best.lm_best_iteration > 0 ? first.iterations + best.lm_best_iteration : first_best;
    best.lm.iterations += first.iterations;
    best.lm.accepted += first.accepted;
    best.lm.initial_cost = first.initial_cost;
    lm_total += more;
  }
  return lm_total;
}

}  // namespace

CoreChoice choose_core(std::vector<Candidate>& cand, CandidateFit& fit, bool choosing,
                       bool varying_steps, const IdentifyConfig& given) {
  nlohmann::json tried = nlohmann::json::array();
  std::size_t win = 0;
  for (std::size_t k = 0; k < cand.size(); ++k) {
    Candidate& x = cand[k];
    const std::string of = cand.size() > 1
                               ? " (core " + std::to_string(k + 1) + " of " +
                                     std::to_string(cand.size()) + ", " + core_name(x.core) + ")"
                               : "";
    if (!x.pretrained) {
      fit.adamw(x, "AdamW" + of);
      // With several candidates each gets at least 2 iterations (a large core's iteration can
      // take seconds); the winner continues below.
      const long budget = cand.size() > 1 ? fit.lm_budget(x, 10.0, 2) : fit.lm_budget(x, 25.0);
      fit.lm(x, budget, "LM" + of);
    }
    x.val_loss = fit.loss(x, fit.split().val);
    if (!std::isfinite(x.val_loss)) x.val_loss = std::numeric_limits<double>::infinity();
    tried.push_back({{"core", x.core},
                     {"params", x.inner.n_params()},
                     {"epochs", x.training.epochs_run},
                     {"lm_iterations", x.lm.iterations},
                     {"val_loss", x.val_loss}});
    if (x.val_loss < cand[win].val_loss) win = k;
  }
  fit.note_stop();
  Candidate& best = cand[win];
  CoreChoice out;
  out.index = win;
  out.core = best.core;
  out.choices["core"] = best.core;
  if (choosing) {
    out.choices["core_candidates"] = tried;
    std::string why = "lowest validation loss of " + std::to_string(cand.size()) + " candidates (" +
                      core_name(best.core) + ")";
    if (varying_steps) why += "; the LA candidate has step polynomials because the steps vary";
    out.choices["core_reason"] = why;
  } else {
    out.choices["core_reason"] = given.init != nullptr ? "the init model file's" : "given";
  }
  out.epochs = best.pretrained ? 0 : fit.epochs_for(best);
  out.choices["epochs"] = out.epochs;
  if (given.init != nullptr) {
    out.choices["init"] = {{"file", given.init->file}, {"checksum", given.init->checksum}};
    out.choices["epochs_reason"] = given.epochs > 0
                                       ? "given: AdamW from the init model file's parameters"
                                       : "none: LM refines the init model file's parameters";
  }
  // The library candidate ran its LM to convergence already.
  out.lm_iterations =
      best.pretrained ? best.lm.iterations : continue_winner(best, fit, cand.size(), given);
  out.choices["lm_iterations"] = out.lm_iterations;
  return out;
}

double lag_one_correlation(const Vector& res, const WindowSet& w) {
  const Index dim = w.dim();
  double num = 0.0, den = 0.0;
  for (Index i = 0; i < w.size(); ++i) {
    const auto ri = res.segment(i * dim, dim);
    den += ri.squaredNorm();
    if (i + 1 < w.size() &&
        w.block[static_cast<std::size_t>(i)] == w.block[static_cast<std::size_t>(i + 1)])
      num += ri.dot(res.segment((i + 1) * dim, dim));
  }
  return den > 0.0 ? num / den : 0.0;
}

double relative_residual(const Vector& res, const WindowSet& w) {
  return res.norm() / std::max((w.zm - w.z0).norm(), 1e-300);
}

// Along a trajectory, one-step residuals of pure measurement noise, D e_k − e_{k+1}, correlate
// at about −1/2 with their successors; a misfit is smooth in the state and correlates
// positively. So a negative lag-one correlation says noise dominates, and windows of m_long
// steps (which divide its bias and variance) are worth their compounding of misfit; LM
// continues from the one-step fit.
WindowChoice adapt_windows(Candidate& best, CandidateFit& fit, BlockSplit& split,
                           const IdentifyConfig& given, bool pairs_file, bool balanced,
                           bool start_only) {
  WindowChoice out;
  nlohmann::json& choices = out.choices;
  if (!split.adaptive || fit.stopped()) {
    choices["window_reason"] = given.window > 0 ? "given"
                               : pairs_file     ? "pairs: one step"
                                                : "trajectories too short for longer windows";
    return out;
  }
  const OneStepMap& map = *best.inner.map;
  const WindowSet& train = split.train;
  const Vector res = window_residuals(map, best.theta, train, balanced);
  const double rho = lag_one_correlation(res, train);
  choices["one_step_residual_lag1_correlation"] = rho;
  const double rel = relative_residual(res, train);
  if (rel <= kCleanRelativeResidual) {
    choices["window_reason"] = "one-step residuals at " + significant(rel, 3) +
                               " of the steps (clean data explained): longer windows would "
                               "change nothing the data can show; one-step windows";
  } else if (rho < 0.0) {
    split.set_window(split.m_long);
    choices["window_reason"] =
        "one-step residuals correlate negatively along trajectories "
        "(noise dominates misfit): windows of " +
        std::to_string(split.m) + " steps";
    out.thinned = start_only &&
                  (split.train.size() > kSelectionWindows || split.val.size() > kSelectionWindows);
    const BlockSplit thin = out.thinned ? selection_split(split, kSelectionWindows) : BlockSplit{};
    std::optional<CandidateFit> thin_fit;
    if (out.thinned) thin_fit = fit.on(thin);
    CandidateFit& on = thin_fit ? *thin_fit : fit;
    // The budget of every window's fit (a budget by work would buy the thinned fit as many
    // more iterations as it has fewer windows).
    const long stage_b = fit.lm_budget(best, 15.0);
    choices["lm_iterations_windows"] = stage_b;
    if (out.thinned)
      choices["lm_windows_thinned"] = {
          {"windows", thin.train.size()},
          {"of", split.train.size()},
          {"held_out", thin.val.size()},
          {"held_out_of", split.val.size()},
          {"why",
           "a later fit of the record refits theta: the windows' fit is its start, on windows "
           "evenly spread over the record"}};
    on.lm(best, stage_b, "LM on longer windows (noise dominates)",
          CandidateFit::LmEnd::kChi2OrGammaSettled);
    fit.note_stop();
  } else {
    choices["window_reason"] =
        "one-step residuals correlate positively along trajectories "
        "(misfit dominates noise): one-step windows";
  }
  return out;
}

}  // namespace csympnet::detail
