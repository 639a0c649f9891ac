#include "csympnet/paper/run.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "../kernels/registry.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/core/options.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/diagnostics/learned_map.hpp"
#include "csympnet/paper/fit.hpp"
#include "csympnet/train/objective.hpp"

namespace csympnet {

void RunConfig::validate() const {
  System(preset.system);  // validates the system spec
  preset.train_steps.validate();
  require(preset.n_train >= 1, "n_train must be >= 1");
  require(preset.n_val >= 1, "n_val must be >= 1");
  require(std::isfinite(preset.h_test) && preset.h_test > 0.0, "h_test must be > 0");
  kSigmaRange.check(sigma);
  check_nonzero("beta_init", beta_init);  // the gradient of |beta| vanishes at 0
  train.validate();
  reference.validate();
  ode.validate();
  refine.validate();
  if (refine.method != RefineMethod::kNone && is_vector_field_type(model))
    throw OptionError("refine",
                      "applies to map models (csympnet, sympnet, map), not to '" + model + "'");
  if (warm_start && model != "csympnet")
    throw OptionError("warm_start", "applies to {model=csympnet} only");
  model_spec_for(preset, model);  // validates the model name
}

const std::vector<std::string>& run_recipe_names() {
  static const std::vector<std::string> names = {"default", "paper"};
  return names;
}

std::string to_string(RunRecipe r) {
  return run_recipe_names().at(static_cast<std::size_t>(r));
}

RunRecipe parse_run_recipe(const std::string& text, const char* key) {
  return static_cast<RunRecipe>(choice_index(key, run_recipe_names(), text));
}

void apply_run_recipe(RunConfig& c, RunRecipe recipe) {
  if (recipe == RunRecipe::kPaper) c.train = paper_recipe(c.train.epochs);
}

RunConfig default_run_config(const std::string& preset, const std::string& model) {
  RunConfig c;
  c.preset = preset_by_name(preset);
  c.model = model;
  c.train = train_options_for(c.preset, model);
  return c;
}

void to_json(nlohmann::json& j, const RunConfig& c) {
  j = {{"preset", c.preset},
       {"model", c.model},
       {"seed", c.seed},
       {"test_seed", c.test_seed},
       {"sigma", c.sigma},
       {"train", c.train},
       {"reference",
        {{"method", to_string(c.reference.method)},
         {"h_ref", c.reference.h_ref},
         {"rk_rtol", c.reference.rk_rtol},
         {"rk_atol", c.reference.rk_atol}}},
       {"beta_init", c.beta_init},
       {"ode", {{"rtol", c.ode.rtol}, {"atol", c.ode.atol}, {"max_steps", c.ode.max_steps}}},
       {"loss", is_vector_field_type(c.model)
                    ? "midpoint: mean over pairs of |(z1 - z0)/h - f((z0 + z1)/2)|^2"
                    : "one-step: mean over pairs of |z1 - Phi_h(z0)|^2"}};
  if (c.refine.method != RefineMethod::kNone) j["refine"] = c.refine;
  if (c.warm_start) j["warm_start"] = true;
  // The arithmetic of the cores' products changes results (rounding-level); recorded, and so
  // part of a suite run's cache key, only when it is not the default, so that reports and keys
  // of default runs stay as they were.
  if (kernels::arithmetic() != kernels::kDefaultArithmetic)
    j["arithmetic"] = kernels::to_string(kernels::arithmetic());
}

RunData generate_run_data(const RunConfig& c) {
  const System sys(c.preset.system);
  RunData d;
  Rng train_rng(c.seed, "train-pairs");
  Rng val_rng(c.seed, "val-pairs");
  d.train = generate_pairs(sys, c.preset.n_train, c.preset.train_steps, train_rng, c.reference);
  d.val = generate_pairs(sys, c.preset.n_val, c.preset.train_steps, val_rng, c.reference);
  if (c.sigma > 0.0) {
    // Noise scales depend on the system and seed only, not on N_train (docs/protocol.md,
    // "Noise").
    Rng scale_rng(c.seed, "noise-scales");
    const NoiseScales scales = noise_scales(sys, c.preset.train_steps, scale_rng, c.reference);
    Rng noise_rng(c.seed, "noise");
    add_noise(d.train, c.sigma, scales, noise_rng);
    add_noise(d.val, c.sigma, scales, noise_rng);
  }
  Rng test_rng(c.test_seed, "test-trajectories");
  d.test = generate_test_set(sys, c.preset.n_test, c.preset.h_test, c.preset.horizon, test_rng,
                             c.reference);
  return d;
}

RunResult run_experiment(const RunConfig& c, const ProgressCallback& progress,
                         bool evaluate_if_stopped, const std::function<bool()>& should_stop) {
  c.validate();
  RunResult r;
  r.data = generate_run_data(c);

  nlohmann::json spec = model_spec_for(c.preset, c.model);
  if (c.model == "csympnet" || c.model == "dhnn2" || c.model == "phnn2")
    spec["beta_init"] = c.beta_init;
  if (c.warm_start) {
    r.warm_start = gamma_warm_start(r.data.train);
    // γ̂ = |β|, and β must not be 0 (its gradient vanishes there).
    spec["beta_init"] = std::max(std::abs(r.warm_start->gamma), 1e-8);
  }
  if (spec.contains("beta_init"))
    check_beta_start(spec["beta_init"].get<double>(), r.data.train.h.maxCoeff(),
                     r.warm_start.has_value());
  r.model = make_model(spec);
  r.theta.resize(r.model.n_params());
  Rng init_rng(c.seed, "init");
  r.model.init_params(init_rng, r.theta);

  // The second stage's options as used: with auto_linear_solver, Ceres' solver where one of
  // its iterations stays small enough to stop within a second of Ctrl-C, else csympnet's LM.
  RefineOptions refine = c.refine;
  const Index n_residuals = r.data.train.size() * r.data.train.dim();
  if (c.auto_linear_solver && refine.method == RefineMethod::kLm && r.model.is_map() &&
      refine.linear_solver != LinearSolver::kBlasNormalCholesky &&
      ceres_iteration_flops(refine.linear_solver, n_residuals, r.model.n_params()) >
          kMaxCeresIterationFlops)
    refine.linear_solver = LinearSolver::kBlasNormalCholesky;
  if (r.model.is_map())  // a second stage that could not be interrupted: refused up front
    check_refine_fits(refine, n_residuals, r.model.n_params());
  r.training = train_model(r.model, r.theta, r.data.train, r.data.val, c.train, progress);
  const bool stopped = r.training.stop_reason == StopReason::kCallback;
  if (stopped && !evaluate_if_stopped) return r;
  if (r.model.is_map() && !stopped)
    r.refine = refine_one_step_map(*r.model.map, r.theta, r.data.train, r.data.val, refine,
                                   {progress, should_stop});

  const System sys(c.preset.system);
  const auto t0 = std::chrono::steady_clock::now();
  r.diagnostics = evaluate(learned_map(r.model, r.theta, c.ode), sys, r.data.test.trajectories,
                           c.preset.h_test);
  const double eval_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  nlohmann::json& rep = r.report;
  rep["model"] = c.model;
  rep["preset"] = c.preset.name;
  rep["params"] = r.model.n_params();
  rep["family"] = r.model.is_map() ? "map" : "vector-field";
  rep["seed"] = c.seed;
  rep["sigma"] = c.sigma;
  rep["epochs"] = r.training.epochs_run;
  rep["best_epoch"] = r.training.best_epoch;
  rep["stop_reason"] = to_string(r.training.stop_reason);
  rep["train_seconds"] = r.training.seconds;
  // Results do not depend on it; only a run that asked for more than one says so.
  if (c.train.threads > 1) rep["train_threads"] = c.train.threads;
  rep["eval_seconds"] = eval_seconds;
  rep["best_val_loss"] = r.training.best_val_loss;
  rep["final_train_loss"] = r.training.final_train_loss;
  rep["gamma_true"] = sys.gamma();
  const nlohmann::json diag = r.diagnostics;
  for (const auto& [key, value] : diag.items()) rep[key] = value;
  rep["test_trajectories"] = r.data.test.trajectories.size();
  rep["test_redraws"] = r.data.test.redraws;
  rep["recipe"] = describe_recipe(c.train);
  if (c.refine.method != RefineMethod::kNone) {
    rep["recipe"] = rep["recipe"].get<std::string>() + "+" + to_string(c.refine.method);
    rep["refine"] = r.refine;  // method "none": skipped because training was stopped
    rep["refine_seconds"] = r.refine.seconds;
    if (r.refine.method != RefineMethod::kNone) rep["best_val_loss"] = r.refine.val_loss_after;
  }
  if (r.warm_start)
    rep["warm_start"] = {{"gamma", r.warm_start->gamma},
                         {"method", to_string(r.warm_start->method)},
                         {"groups", r.warm_start->groups}};
  rep["architecture"] = r.model.hyperparams();
  rep["config"] = c;
  if (c.refine.method != RefineMethod::kNone)  // the solver used, when chosen by size
    rep["config"]["refine"]["linear_solver"] = to_string(refine.linear_solver);
  rep["csympnet_version"] = CSYMPNET_VERSION;  // the project version (CMakeLists.txt)
  return r;
}

}  // namespace csympnet
