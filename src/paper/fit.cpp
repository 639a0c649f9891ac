#include "csympnet/paper/fit.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>

#include "../kernels/registry.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/diagnostics/diagnostics.hpp"
#include "csympnet/train/loss.hpp"
#include "csympnet/train/objective.hpp"

namespace csympnet {

const std::vector<std::string>& fit_model_names() {
  static const std::vector<std::string> names = {"csympnet", "sympnet"};
  return names;
}

const std::vector<std::string>& refine_choice_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n = {"auto"};
    for (const std::string& m : refine_method_names()) n.push_back(m);
    return n;
  }();
  return names;
}

std::string to_string(FitModel m) {
  return fit_model_names().at(static_cast<std::size_t>(m));
}

FitModel parse_fit_model(const std::string& text, const char* key) {
  return static_cast<FitModel>(choice_index(key, fit_model_names(), text));
}

FitConfig FitConfig::identification() {
  return FitConfig{};
}

FitConfig FitConfig::adamw_only() {
  FitConfig c;
  c.warm_start = false;
  c.refine_method = RefineMethod::kNone;
  c.bootstrap_replicates = 0;
  return c;
}

void FitConfig::validate() const {
  kValFractionRange.check(val_fraction);
  check_nonzero("beta_init", beta_init);
  if (train.epochs != kAutoEpochs) kFitEpochsRange.check(train.epochs);
  train.validate();
  refine.validate();
  BootstrapOptions b = bootstrap;
  b.replicates = bootstrap_replicates.value_or(0);
  if (replicate_refine) b.refine = *replicate_refine;
  b.validate();
  if (b.replicates != 0 && model != FitModel::kCSympNet)
    throw OptionError("bootstrap",
                      "needs {model=csympnet} (the only model here with a damping rate)");
}

void to_json(nlohmann::json& j, const FitConfig& c) {
  nlohmann::json refine = c.refine;
  refine["method"] = c.refine_method ? to_string(*c.refine_method) : "auto";
  nlohmann::json bootstrap = c.bootstrap;
  bootstrap["replicates"] =
      c.bootstrap_replicates ? nlohmann::json(*c.bootstrap_replicates) : nlohmann::json("auto");
  bootstrap["refine"] =
      c.replicate_refine ? nlohmann::json(*c.replicate_refine) : nlohmann::json("auto");
  j = {{"model", to_string(c.model)},    {"core", c.core},   {"seed", c.seed},
       {"val_fraction", c.val_fraction}, {"train", c.train}, {"beta_init", c.beta_init},
       {"warm_start", c.warm_start},     {"refine", refine}, {"bootstrap", bootstrap}};
  // As in a run's configuration (run.cpp): recorded only when not the default.
  if (kernels::arithmetic() != kernels::kDefaultArithmetic)
    j["arithmetic"] = kernels::to_string(kernels::arithmetic());
}

FitConfig make_fit_config(const FitConfig& recipe, const FitSettings& s) {
  FitConfig c = recipe;
  if (s.model) c.model = parse_fit_model(*s.model);
  if (!s.core.is_null()) c.core = s.core;
  if (s.seed) c.seed = *s.seed;
  if (s.val_fraction) c.val_fraction = *s.val_fraction;
  if (s.beta_init) c.beta_init = *s.beta_init;
  if (s.epochs) {
    kFitEpochsRange.check(*s.epochs);  // a given budget: kAutoEpochs (0) is not one
    c.train.epochs = *s.epochs;
  }
  if (s.val_every) c.train.val_every = *s.val_every;
  if (s.threads) c.train.threads = *s.threads;
  if (s.chunk_pairs) c.train.chunk_pairs = *s.chunk_pairs;
  if (s.batch_size) c.train.batch_size = *s.batch_size;
  if (s.lr) c.train.adamw.lr = *s.lr;
  if (s.weight_decay) c.train.adamw.weight_decay = *s.weight_decay;
  if (s.decay_damping) c.train.adamw.decay_damping = *s.decay_damping;
  if (s.lr_schedule)
    c.train.lr_schedule =
        static_cast<LrSchedule>(choice_index("lr_schedule", lr_schedule_names(), *s.lr_schedule));
  if (s.lr_final_fraction) c.train.lr_final_fraction = *s.lr_final_fraction;
  if (s.warm_start) c.warm_start = *s.warm_start;
  if (s.refine) {
    const std::size_t k = choice_index("refine", refine_choice_names(), *s.refine);
    if (k == 0)
      c.refine_method.reset();
    else
      c.refine_method = static_cast<RefineMethod>(k - 1);
  }
  if (s.refine_iterations) c.refine.iterations = *s.refine_iterations;
  if (s.refine_solver) {
    c.refine.linear_solver = static_cast<LinearSolver>(
        choice_index("refine_solver", linear_solver_names(), *s.refine_solver));
    // auto picks the solver with the method; an explicit one would be overridden silently.
    if (!c.refine_method)
      throw OptionError("refine_solver",
                        "needs {refine=lm}: {refine=auto} (fit's default) chooses the solver by "
                        "the model's size");
  }
  if (s.bootstrap) c.bootstrap_replicates = *s.bootstrap;
  c.train.shuffle_seed = c.seed;  // the mini-batch order follows the fit's seed
  c.validate();
  return c;
}

void resolve_auto_refine(RefineOptions& refine, Index n_pairs, Index dim, Index n_params) {
  const double entries =
      static_cast<double>(n_pairs) * static_cast<double>(dim) * static_cast<double>(n_params);
  const Index residuals = n_pairs * dim;
  if (entries <= kMaxJacobianEntries && n_params <= kMaxLmParams &&
      ceres_iteration_flops(LinearSolver::kDenseQr, residuals, n_params) <=
          kMaxCeresIterationFlops) {
    refine.method = RefineMethod::kLm;
  } else if (entries <= kMaxNormalLmJacobianEntries && n_params <= kMaxNormalLmParams) {
    refine.method = RefineMethod::kLm;
    refine.linear_solver = LinearSolver::kBlasNormalCholesky;
  } else {
    refine.method = RefineMethod::kLbfgs;
  }
}

RefineOptions default_replicate_refine_for(const RefineOptions& refine) {
  RefineOptions r;
  // Replicates start at θ̂ and keep their last iterate: with the best-validation rule they
  // would mostly keep θ̂ itself, and the interval would collapse to a point (measured).
  r.keep_best_validation = false;
  if (refine.method == RefineMethod::kLm) {
    r.method = RefineMethod::kLm;
    r.linear_solver = refine.linear_solver;
    r.iterations = 10;
  } else {
    r.method = RefineMethod::kLbfgs;
    r.iterations = 100;
  }
  return r;
}

void to_json(nlohmann::json& j, const FitQuality& q) {
  j = {{"train_loss", q.train_loss},
       {"val_loss", q.val_loss},
       {"val_relative_residual", q.val_relative_residual},
       {"structure_residual_mean", q.structure_residual_mean},
       {"structure_residual_max", q.structure_residual_max}};
}

FitQuality fit_quality(const Model& model, const Vector& theta, const PairSet& train,
                       const PairSet& val) {
  require(model.is_map(), "fit quality: needs a map model");
  const OneStepMap& map = *model.map;
  FitQuality q;
  q.train_loss = one_step_loss(map, theta, train);
  q.val_loss = one_step_loss(map, theta, val);
  const Matrix r = map.apply(theta, val.z0, val.h) - val.z1;
  q.val_relative_residual = r.norm() / (val.z1 - val.z0).norm();
  const auto gamma = map.damping_rate(theta);
  for (Index j = 0; j < val.size(); ++j) {
    const Matrix jac = map.jacobian(theta, val.z0.col(j), val.h(j));
    std::optional<double> own;
    if (gamma) own = std::exp(-*gamma * val.h(j));
    const double s = structure_at(jac, own.value_or(1.0), own).self_residual;
    q.structure_residual_mean += s / static_cast<double>(val.size());
    q.structure_residual_max = std::max(q.structure_residual_max, s);
  }
  return q;
}

nlohmann::json default_core_for(Index d) {
  if (d == 1) return {{"type", "la"}, {"layers", 5}, {"sublayers", 20}};
  if (d <= 20) return {{"type", "la"}, {"layers", 4}, {"sublayers", 10}};
  return {{"type", "la"}, {"layers", 4}, {"sublayers", 4}};
}

long default_epochs_for(Index d) {
  return d <= 20 ? 50000 : 3000;
}

namespace {
// (training indices, validation indices) of a deterministic split.
std::pair<std::vector<Index>, std::vector<Index>> split_indices(Index n, double val_fraction,
                                                                Rng& rng) {
  require(n >= 2, [&] {
    return "need at least 2 pairs to hold out a validation set, got " + std::to_string(n) +
           "; expected more pairs, or a separate validation file (--val FILE)";
  });
  std::vector<Index> idx(static_cast<std::size_t>(n));
  std::iota(idx.begin(), idx.end(), Index{0});
  // Fisher–Yates with our own RNG, so the split is the same on every platform.
  for (Index i = n - 1; i > 0; --i) {
    const auto j = static_cast<Index>(rng.next_u64() % static_cast<std::uint64_t>(i + 1));
    std::swap(idx[static_cast<std::size_t>(i)], idx[static_cast<std::size_t>(j)]);
  }
  Index n_val = static_cast<Index>(std::llround(val_fraction * static_cast<double>(n)));
  n_val = std::clamp<Index>(n_val, 1, n - 1);
  return {std::vector<Index>(idx.begin() + n_val, idx.end()),
          std::vector<Index>(idx.begin(), idx.begin() + n_val)};
}
}  // namespace

std::pair<PairSet, PairSet> split_pairs(const PairSet& all, double val_fraction, Rng& rng) {
  const auto [train_idx, val_idx] = split_indices(all.size(), val_fraction, rng);
  return {select_pairs(all, train_idx), select_pairs(all, val_idx)};
}

void check_beta_start(double beta, double h_max, bool from_warm_start) {
  if (std::abs(beta) * h_max <= kMaxBetaInitTimesStep) return;
  const std::string problem =
      number_text(beta) + " with the data's largest step h = " + number_text(h_max) +
      " shrinks every state by exp(-|beta| h) = " + number_text(std::exp(-std::abs(beta) * h_max)) +
      " per step, so training could not move it; expected |beta_init| * h <= " +
      number_text(kMaxBetaInitTimesStep) +
      " (|beta_init| <= " + number_text(kMaxBetaInitTimesStep / h_max) + " here)";
  // A beta_init the user gave names that option (spelt by the front end); the warm start's
  // estimate is the data's doing.
  if (!from_warm_start) throw OptionError("beta_init", problem);
  throw Error("the warm start's gamma " + problem +
              "; the data decay too fast for their steps to identify gamma");
}

namespace {

// The classic recipe trains in the data's own units: states far from order 1 make its loss
// tiny or huge, and its optimiser's steps (and the warm start's fit) no longer fit the data.
std::string scale_note(const PairSet& train) {
  const double scale = train.z0.cwiseAbs().maxCoeff();
  if (scale >= 1e-3 && scale <= 1e3) return {};
  std::ostringstream s;
  s.precision(3);
  s << "the states are of order " << scale
    << ": this recipe trains in the data's own units, where the optimiser's steps do not fit "
       "states of that size, and gamma_hat may be far off; `csympnet fit` (its default recipe) "
       "removes units first";
  return s.str();
}

}  // namespace

FitResult fit_pairs(const PairSet& train, const std::optional<PairSet>& val,
                    const FitConfig& config, const ProgressCallback& progress,
                    const std::vector<Index>& groups, const std::function<bool()>& should_stop) {
  config.validate();
  train.validate("training pairs");
  require(groups.empty() || static_cast<Index>(groups.size()) == train.size(),
          "fit: need one trajectory index per pair");
  FitResult r;
  r.config = config;
  if (r.config.core.is_null()) r.config.core = default_core_for(train.d());
  if (r.config.train.epochs <= 0) r.config.train.epochs = default_epochs_for(train.d());

  r.val_split = !val.has_value();
  if (val) {
    r.train = train;
    r.val = *val;
    r.train_groups = groups;
  } else {
    Rng split_rng(config.seed, "validation-split");
    const auto [train_idx, val_idx] = split_indices(train.size(), config.val_fraction, split_rng);
    r.train = select_pairs(train, train_idx);
    r.val = select_pairs(train, val_idx);
    if (!groups.empty())
      for (Index i : train_idx) r.train_groups.push_back(groups[static_cast<std::size_t>(i)]);
  }
  r.scale_note = scale_note(train);
  nlohmann::json spec = {
      {"type", to_string(config.model)}, {"d", train.d()}, {"core", r.config.core}};
  if (config.model == FitModel::kCSympNet) {
    spec["beta_init"] = config.beta_init;
    if (config.warm_start) {
      // A convenience, not a requirement: on data it cannot use (too few pairs, states that
      // do not span phase space) the fit starts from beta_init instead and says why.
      try {
        r.warm_start = gamma_warm_start(r.train);
        // γ̂ = |β|; β must not be 0, where its gradient vanishes.
        spec["beta_init"] = std::max(std::abs(r.warm_start->gamma), 1e-8);
      } catch (const Error& e) {
        r.warm_start_note = e.what();
      }
    }
    check_beta_start(spec["beta_init"].get<double>(), r.train.h.maxCoeff(),
                     r.warm_start.has_value());
  }
  r.model = make_model(spec);
  r.theta.resize(r.model.n_params());
  Rng init_rng(config.seed, "init");
  r.model.init_params(init_rng, r.theta);
  r.config.bootstrap.seed = config.seed;
  if (config.refine_method)
    r.config.refine.method = *config.refine_method;
  else
    resolve_auto_refine(r.config.refine, r.train.size(), r.train.dim(), r.model.n_params());
  r.config.refine_method = r.config.refine.method;
  // This recipe trains a map; it claims no interval for γ̂. The bootstrap runs only when asked
  // for, and its spread is reported as such (report "bootstrap"), not as an interval: it has
  // not passed the identification's checks, and resampling few groups collapses it.
  r.config.bootstrap.replicates = config.bootstrap_replicates.value_or(0);
  if (config.model == FitModel::kCSympNet) r.interval_note = std::string(kNoIntervalNote);
  r.config.bootstrap_replicates = r.config.bootstrap.replicates;
  r.config.bootstrap.refine = config.replicate_refine
                                  ? *config.replicate_refine
                                  : default_replicate_refine_for(r.config.refine);
  r.config.replicate_refine = r.config.bootstrap.refine;
  // A second stage that could not be interrupted is refused before any training.
  check_refine_fits(r.config.refine, r.train.size() * r.train.dim(), r.model.n_params());
  if (r.config.bootstrap.replicates > 0)
    check_refine_fits(r.config.bootstrap.refine, r.train.size() * r.train.dim(),
                      r.model.n_params());
  r.training = train_model(r.model, r.theta, r.train, r.val, r.config.train, progress);
  if (r.training.stop_reason != StopReason::kBudget) {  // diverged or stopped: no second stage
    r.stopped = r.training.stop_reason == StopReason::kCallback;
    return r;
  }
  r.refine = refine_one_step_map(*r.model.map, r.theta, r.train, r.val, r.config.refine,
                                 {progress, should_stop});
  if (r.refine.stopped) {
    r.stopped = true;
    if (r.config.bootstrap.replicates > 0)
      r.interval_note = "no interval: the fit was interrupted during the second stage";
    return r;
  }
  if (r.config.bootstrap.replicates > 0) {
    GammaInterval g = gamma_bootstrap(*r.model.map, r.theta, r.train, r.val, r.config.bootstrap,
                                      r.train_groups, {progress, should_stop});
    if (g.stopped) {
      r.stopped = true;
      r.interval_note = "no interval: the bootstrap was interrupted after " +
                        std::to_string(g.gammas.size()) + " of " +
                        std::to_string(r.config.bootstrap.replicates) + " replicates";
    } else {
      r.interval = std::move(g);
    }
  }
  return r;
}

nlohmann::json fit_report(const FitResult& r) {
  const auto gamma = r.model.damping_rate(r.theta);
  const FitQuality quality = fit_quality(r.model, r.theta, r.train, r.val);
  // The pairs given for training: the training pairs, and the validation pairs when they
  // were split off them.
  double h_min = r.train.h.minCoeff(), h_max = r.train.h.maxCoeff();
  if (r.val_split) {
    h_min = std::min(h_min, r.val.h.minCoeff());
    h_max = std::max(h_max, r.val.h.maxCoeff());
  }
  const std::optional<GammaInterval>& g = r.interval;
  nlohmann::json report = {
      {"model", to_string(r.config.model)},
      {"data", nullptr},
      {"validation", r.val_split ? nlohmann::json("split") : nlohmann::json(nullptr)},
      {"d", r.train.d()},
      {"pairs_train", r.train.size()},
      {"pairs_val", r.val.size()},
      {"h_min", h_min},
      {"h_max", h_max},
      {"params", r.model.n_params()},
      {"seed", r.config.seed},
      {"epochs", r.training.epochs_run},
      {"train_seconds", r.training.seconds},
      {"best_val_loss", quality.val_loss},
      {"train_loss", quality.train_loss},
      {"gamma_hat", gamma ? nlohmann::json(*gamma) : nlohmann::json(nullptr)},
      {"gamma_ci_low", nullptr},
      {"gamma_ci_high", nullptr},
      {"gamma_note",
       "a training outcome, with no interval: `csympnet fit` (its default recipe) "
       "identifies gamma with an interval and checks of the model's assumptions"},
      // When asked for: the spread of γ̂ over refits on resampled groups, not an interval.
      {"bootstrap", g ? nlohmann::json(*g) : nlohmann::json(nullptr)},
      {"warm_start", r.warm_start
                         ? nlohmann::json({{"gamma", r.warm_start->gamma},
                                           {"method", to_string(r.warm_start->method)},
                                           {"groups", r.warm_start->groups}})
                         : nlohmann::json(r.warm_start_note.empty() ? "off" : r.warm_start_note)},
      {"quality", quality},
      {"training", r.training},
      {"refine", r.refine},
      {"config", r.config},
      {"architecture", r.model.hyperparams()}};
  if (gamma && !r.interval_note.empty()) report["gamma_ci_note"] = r.interval_note;
  if (!r.scale_note.empty()) report["warnings"] = {r.scale_note};
  if (r.stopped) report["interrupted"] = true;  // a partial result: see training/refine
  return report;
}

}  // namespace csympnet
