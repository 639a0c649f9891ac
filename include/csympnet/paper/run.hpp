// One experiment run: generate the preset's data, train a map model, evaluate it.
// Everything random derives from (seed, purpose) streams, so a run is bit-reproducible.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "csympnet/diagnostics/diagnostics.hpp"
#include "csympnet/integrators/dopri5.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/paper/preset.hpp"
#include "csympnet/train/gamma_warm_start.hpp"
#include "csympnet/train/refine.hpp"
#include "csympnet/train/trainer.hpp"

namespace csympnet {

// The training recipe of a run: kDefault (the preset's, with the cosine-annealed rate) or
// kPaper (paper_recipe: the paper's constant rate). Spelt "default", "paper": the CLI's
// `run --recipe` and Python's run(recipe=).
enum class RunRecipe { kDefault, kPaper };
std::string to_string(RunRecipe r);
const std::vector<std::string>& run_recipe_names();  // in enum order
// Refuses any other text with an OptionError for `key` naming the accepted spellings.
RunRecipe parse_run_recipe(const std::string& text, const char* key = "recipe");

// The range of the relative observation noise a run adds (core/options.hpp).
inline constexpr OptionRange kSigmaRange{.key = "sigma", .lo = 0.0, .hi = 10.0};

struct RunConfig {
  Preset preset;                   // system, data sizes, architecture, default budget
  std::string model = "csympnet";  // one of model_types()
  std::uint64_t seed = 42;         // training seed: training/validation data and init
  std::uint64_t test_seed = 0;     // data seed of the test trajectories (docs/protocol.md, "Seeds")
  double sigma = 0.0;              // relative observation noise on training/validation pairs
  TrainOptions train;              // epochs default to the preset's budget
  ReferenceOptions reference;      // reference solver for all data
  double beta_init = 0.1;          // CSympNet-ID, DHNN2, pHNN2: initial β (γ̂ = |β|), ≠ 0
  OdeOptions ode;                  // vector-field rollout (docs/protocol.md, "Losses and rollout")
  // Second stage after AdamW for map models (default none: the paper's recipe). Written to
  // the config only when on, so the cache keys of existing runs do not change.
  RefineOptions refine;
  // LM's linear solver chosen by the problem's size (the CLI's default when --refine-solver is
  // not given): refine.linear_solver (dense_qr) when one Ceres iteration fits
  // kMaxCeresIterationFlops, else blas_normal_cholesky. The solver used is what the report's
  // config records; this flag itself is not written, so cache keys do not change.
  bool auto_linear_solver = false;
  // CSympNet-ID: replace beta_init by the closed-form estimate γ₀ from the training pairs
  // (default off; written to the config only when on).
  bool warm_start = false;
  void validate() const;
};
// Config from a preset with the preset's epoch budget.
RunConfig default_run_config(const std::string& preset, const std::string& model);
// c.train as `recipe` has it, with c.train's epoch budget.
void apply_run_recipe(RunConfig& c, RunRecipe recipe);
void to_json(nlohmann::json& j, const RunConfig& c);

// The data of a run, generated from the config alone.
struct RunData {
  PairSet train;
  PairSet val;
  TestSet test;
};
RunData generate_run_data(const RunConfig& config);

struct RunResult {
  Model model;
  Vector theta;  // best-validation parameters
  TrainSummary training;
  RefineSummary refine;                      // method "none" when no second stage ran
  std::optional<GammaWarmStart> warm_start;  // when config.warm_start
  Diagnostics diagnostics;
  RunData data;
  nlohmann::json report;  // the report.json document
};

// When `progress` stops training (stop_reason "callback", e.g. on Ctrl-C) the second stage is
// skipped, and so is the evaluation unless `evaluate_if_stopped` (then r.diagnostics and
// r.report stay empty: `reproduce` discards such runs and should not wait for them).
// `should_stop`, when given, is polled by the second stage (refine_one_step_map); a second
// stage it stops keeps its best iterate and says so in r.refine.stopped.
RunResult run_experiment(const RunConfig& config, const ProgressCallback& progress = {},
                         bool evaluate_if_stopped = true,
                         const std::function<bool()>& should_stop = {});

}  // namespace csympnet
