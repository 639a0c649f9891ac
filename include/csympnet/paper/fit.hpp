// Fitting a one-step map to a user's own snapshot pairs (any d, any steps).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/data/dataset.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/train/gamma_bootstrap.hpp"
#include "csympnet/train/gamma_warm_start.hpp"
#include "csympnet/train/refine.hpp"
#include "csympnet/train/trainer.hpp"

namespace csympnet {

// The largest |beta_init| * h a fit starts from: beyond it exp(-|β| h) shrinks every state to
// nearly zero in one step and no gradient reaches β (fit_pairs refuses it).
constexpr double kMaxBetaInitTimesStep = 50.0;

// Refuses a starting β (from --beta-init, or from the warm start) with |β| h_max beyond
// kMaxBetaInitTimesStep. γ = |β| shrinks every state by exp(-|β| h) per step: past that the
// model starts by mapping every state to (nearly) zero, where no gradient reaches β, which
// would then be reported unchanged as γ̂.
void check_beta_start(double beta, double h_max, bool from_warm_start);

// The models fit_pairs trains: CSympNet-ID (identifies γ) and the symplectic SympNet (no
// damping). Spelt "csympnet", "sympnet" (model_types() of models/model.hpp): the one
// spelling in reports, the CLI's --model and Python's model=.
enum class FitModel { kCSympNet, kSympNet };
std::string to_string(FitModel m);
const std::vector<std::string>& fit_model_names();  // in enum order
// The choices of a fit's second stage: "auto" (resolve_auto_refine), then
// refine_method_names(); the CLI's --refine and Python's refine= take these.
const std::vector<std::string>& refine_choice_names();
// Refuses any other text with an OptionError for `key` naming the accepted spellings.
FitModel parse_fit_model(const std::string& text, const char* key = "model");

// The ranges of the fit's own options (core/options.hpp; the others are TrainOptions',
// RefineOptions' and BootstrapOptions'). A fit's epoch budget, when given, is at least 1:
// FitConfig's train.epochs = kAutoEpochs stands for "not given" (by dimension). A held-out
// share's range (kValFractionRange) is train/trainer.hpp's, shared with identify.
inline constexpr long kAutoEpochs = 0;
inline constexpr OptionRange kFitEpochsRange{.key = "epochs", .lo = 1, .hi = 1e8, .whole = true};

// What fit_pairs does, and the recipes the front ends start from. Options that the library
// chooses by the problem's size are std::optional (or kAutoEpochs): nullopt lets fit_pairs
// choose, and FitResult::config holds what it chose. A default-constructed FitConfig is
// identification(), the documented default recipe (docs/identification.md, "the classic
// recipe"): CSympNet-ID, epochs by dimension, the cosine-annealed rate from 1e-3, a warm
// start and the second stage chosen by size. It trains a map: γ̂ is a training outcome,
// with no interval.
struct FitConfig {
  FitModel model = FitModel::kCSympNet;
  nlohmann::json core;        // symplectic core; null → default_core_for(d)
  std::uint64_t seed = 42;    // validation split and initialisation
  double val_fraction = 0.2;  // share of pairs held out when no validation set is given
  // AdamW with the cosine-annealed rate (docs/training.md); epochs kAutoEpochs →
  // default_epochs_for(d).
  TrainOptions train = [] {
    TrainOptions t;
    t.epochs = kAutoEpochs;
    t.lr_schedule = LrSchedule::kCosine;
    return t;
  }();
  double beta_init = 0.1;  // CSympNet-ID: initial β, nonzero (unless warm_start)
  // CSympNet-ID: initial β from the closed-form estimate γ₀ of the data (gamma_warm_start);
  // beta_init is then unused. Falls back to beta_init when the estimate cannot be formed.
  bool warm_start = true;
  // Second stage after AdamW; nullopt → resolve_auto_refine(...). `refine` holds the rest of
  // it (iterations, linear solver, tolerances); fit_pairs sets refine.method.
  std::optional<RefineMethod> refine_method;
  RefineOptions refine;
  // Replicates of a bootstrap of γ̂ over refits on resampled groups (CSympNet-ID), 0 or
  // nullopt = off. Its spread is reported as such ("bootstrap"), never as an interval: the
  // classic recipe trains a map, and only identify() (identify/identify.hpp) gives γ̂ an
  // interval, after the checks of the model's assumptions.
  std::optional<long> bootstrap_replicates;
  // Each replicate's second stage; nullopt → default_replicate_refine_for(refine).
  std::optional<RefineOptions> replicate_refine;
  // The interval's level; fit_pairs sets its replicates, refine and seed from the above.
  BootstrapOptions bootstrap;

  // The recipes (docs/identification.md). identification(): warm start and a second stage
  // chosen by size; what `csympnet fit --recipe classic` and Python's `fit` run. adamw_only():
  // AdamW alone, from beta_init, no interval; what `csympnet train` runs unless told otherwise.
  static FitConfig identification();
  static FitConfig adamw_only();

  // Refuses an option out of its range, or two that do not go together, with an OptionError
  // naming it by its key (core/options.hpp) and saying what was expected; make_fit_config and
  // fit_pairs call it.
  void validate() const;
};
// The configuration as reports write it; an option left to fit_pairs reads "auto".
void to_json(nlohmann::json& j, const FitConfig& c);

// What a front end (the CLI, Python) was given, as plain values: each option set only if the
// user gave it. Text options take the spellings of to_string (refine: also "auto").
struct FitSettings {
  std::optional<std::string> model;
  nlohmann::json core;  // null: the recipe's
  std::optional<std::uint64_t> seed;
  std::optional<double> val_fraction, beta_init, lr, lr_final_fraction, weight_decay;
  std::optional<long> epochs, val_every, refine_iterations, bootstrap, chunk_pairs, batch_size;
  std::optional<int> threads;
  std::optional<std::string> lr_schedule, refine, refine_solver;
  std::optional<bool> decay_damping, warm_start;
};
// `recipe` with the settings given applied: the one place a FitConfig is built from a front
// end's values, and where they are checked, before any work: a misspelt value, a value out
// of its range (FitConfig::validate) and an option that needs another (refine_solver needs
// refine "lm") are refused with an OptionError naming the option by its key, which the front
// end spells its own way ("--refine-solver", "refine_solver").
FitConfig make_fit_config(const FitConfig& recipe, const FitSettings& settings);

// The presets' cores, chosen by dimension: LA(5,20) for d = 1, LA(4,10) up to d = 20,
// LA(4,4) beyond.
nlohmann::json default_core_for(Index d);
// 50,000 epochs up to d = 20 (the s1/s2 budget, docs/training.md), 3,000 beyond.
long default_epochs_for(Index d);
// LM's limits for the default second stage: the residual Jacobian (N·2d × P doubles) and
// the P × P normal matrix it factors each iteration (docs/identification.md, "Defaults").
// Up to kMaxLmParams, Ceres' dense QR (the better conditioned); up to kMaxNormalLmParams, the
// normal equations on BLAS (train/levenberg_marquardt.hpp), whose P × P matrix and its
// factor take 2 · 8 P² bytes (580 MB at the limit).
constexpr long kAutoBootstrapReplicates = 100;  // what --bootstrap suggests; never automatic
// Why a map trained by fit_pairs carries no interval for γ̂.
inline constexpr const char* kNoIntervalNote =
    "no interval: this recipe trains a map; `csympnet fit` with its default recipe (Python: "
    "csympnet.identify, CSympNetID) identifies gamma with an interval and checks";
constexpr double kMaxJacobianEntries = 2.5e7;
constexpr Index kMaxLmParams = 1000;
constexpr double kMaxNormalLmJacobianEntries = 5e7;
constexpr Index kMaxNormalLmParams = 6000;
// What `--refine auto` becomes: lm within kMaxJacobianEntries and kMaxLmParams; lm with
// linear solver blas_normal_cholesky within the kMaxNormalLm limits; else lbfgs. Sets
// refine.method, and refine.linear_solver in the middle case only.
void resolve_auto_refine(RefineOptions& refine, Index n_pairs, Index dim, Index n_params);
// The second stage of each bootstrap replicate, started from the fitted θ̂ and keeping its
// last iterate: 10 LM iterations (with the fit's linear solver) after an LM fit (near θ̂
// Gauss–Newton converges in a few), else 100 L-BFGS iterations.
RefineOptions default_replicate_refine_for(const RefineOptions& refine);

// Deterministic split of `all` into (train, val) with round(val_fraction·N) ≥ 1 validation
// pairs (N ≥ 2 required).
std::pair<PairSet, PairSet> split_pairs(const PairSet& all, double val_fraction, Rng& rng);

// How well the fitted map explains the data, and how exact its structure is there.
struct FitQuality {
  double train_loss = 0.0;  // one-step loss on the training pairs
  double val_loss = 0.0;    // ... on the validation pairs
  // ‖Φ̂(z0) − z1‖_F / ‖z1 − z0‖_F on the validation pairs: the share of the change over one
  // step that the map does not explain.
  double val_relative_residual = 0.0;
  // Self residual ‖DΦ̂ᵀJDΦ̂ − λ_own J‖_F at every validation z0 with its own h
  // (λ_own = e^{−γ̂h} for CSympNet-ID, the projection λ̂ otherwise): rounding level for an
  // exactly conformally symplectic map.
  double structure_residual_mean = 0.0;
  double structure_residual_max = 0.0;
};
void to_json(nlohmann::json& j, const FitQuality& q);
FitQuality fit_quality(const Model& model, const Vector& theta, const PairSet& train,
                       const PairSet& val);

struct FitResult {
  Model model;  // a map model (csympnet or sympnet)
  Vector theta;
  TrainSummary training;
  RefineSummary refine;
  std::optional<GammaWarmStart> warm_start;
  std::string warm_start_note;  // why no warm start was used, when config asked for one
  std::optional<GammaInterval> interval;
  std::string interval_note;  // why γ̂ has no interval (this recipe trains a map)
  // Set when the data's scale is far from 1: this recipe trains in the data's own units.
  std::string scale_note;
  PairSet train;
  std::vector<Index> train_groups;  // trajectory of each training pair (empty: unknown)
  PairSet val;
  bool val_split = false;  // `val` was split off the training pairs (no validation set given)
  FitConfig config;        // with every choice made (no nullopt left)
  bool stopped = false;    // a stage ended early because the caller asked
};

// Trains on `train`; validates on `val` if given, else on a split of `train`. `groups`, when
// not empty, names the trajectory of each pair of `train`, and the bootstrap then resamples
// whole trajectories. `should_stop` (an interrupt), when given, is polled by the second stage
// and the bootstrap (AdamW stops through `progress`); a fit stopped there keeps its best
// iterate, says `stopped`, and has no interval (interval_note says why).
FitResult fit_pairs(const PairSet& train, const std::optional<PairSet>& val,
                    const FitConfig& config, const ProgressCallback& progress = {},
                    const std::vector<Index>& groups = {},
                    const std::function<bool()>& should_stop = {});

// The report of a fit (report.json of `csympnet fit --recipe classic` and `csympnet train`):
// every field but wall times. "data" is null and "validation" is "split" or null: a caller
// that read the pairs from files sets them to the file names.
nlohmann::json fit_report(const FitResult& r);

}  // namespace csympnet
