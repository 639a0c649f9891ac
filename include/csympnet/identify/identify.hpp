// Identification on a user's own data: `csympnet fit` (docs/identification.md).
//
//   trajectories (or pairs), any units
//     ─> normalise (data/normalization.hpp: q shift, per-dof scales with α_i β_i = c, τ)
//     ─> blocks: whole trajectories, or segments of long ones; ~20% of the blocks validate
//     ─> windows of m steps inside each block (train/window_loss.hpp)
//     ─> warm start γ₀; for each candidate core (LA, G): AdamW on the balanced window loss,
//        Levenberg–Marquardt on the same residuals (normal equations formed in chunks), best
//        validation kept; the lowest validation loss wins and continues LM
//     ─> interval: cluster-robust sandwich over the training blocks (train/gamma_sandwich.hpp),
//        inflated by the held-out over training loss when above 1
//     ─> checks of the model's assumptions on every block (identify/model_checks.hpp)
//     ─> verdict: identified; not identified, and why; or the model rejected by a check
//     ─> the model in the user's units (NormalizedMap), exactly conformally symplectic.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/communicator.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/data/normalization.hpp"
#include "csympnet/identify/model_checks.hpp"
#include "csympnet/models/model.hpp"
#include "csympnet/train/gamma_sandwich.hpp"
#include "csympnet/train/gamma_warm_start.hpp"
#include "csympnet/train/levenberg_marquardt.hpp"
#include "csympnet/train/trainer.hpp"

namespace csympnet {

// Per-dof momentum scales as parameters (models/dof_scaled_map.hpp), for velocities or per-dof
// units of p: kAuto (learned when d > 1), kLearned or kFixed. Spelt "auto", "learned",
// "fixed": the CLI's --dof-scales, Python's dof_scales= and the report.
enum class DofScales { kAuto, kLearned, kFixed };
std::string to_string(DofScales s);
const std::vector<std::string>& dof_scales_names();  // in enum order
// The spellings of IdentifyConfig::dissipation, "auto" first.
const std::vector<std::string>& dissipation_choices();
// The names of IdentifyConfig::record_fit.
const std::vector<std::string>& record_fit_choices();

// Refuses any other text with an OptionError for `key` naming the accepted spellings.
DofScales parse_dof_scales(const std::string& text, const char* key = "dof_scales");

// The residuals of the window loss: "balanced" (IdentifyConfig::balanced) or "one-step";
// the CLI's --loss and Python's loss= take these.
const std::vector<std::string>& identify_loss_names();

// The ranges of the identification's own options (core/options.hpp); lr and threads are
// TrainOptions' (kLrRange, kThreadsRange), val_fraction the fit's (kValFractionRange). 0 is
// "automatic" for window, epochs and lm_iterations. A level beyond 0.9999 asks for a quantile
// the few blocks here cannot give; fewer than 3 blocks leave none to validate.
inline constexpr OptionRange kWindowRange{.key = "window", .lo = 0, .hi = 64, .whole = true};
inline constexpr OptionRange kIdentifyEpochsRange{
    .key = "epochs", .lo = 1, .hi = 1e8, .whole = true, .zero_means = "automatic"};
inline constexpr OptionRange kLmIterationsRange{
    .key = "lm_iterations", .lo = 0, .hi = 100000, .whole = true};
inline constexpr OptionRange kBlocksRange{.key = "blocks", .lo = 3, .hi = 10000, .whole = true};
inline constexpr OptionRange kLevelRange{.key = "level", .lo = 0.5, .hi = 0.9999};

// A model file to start from (`csympnet fit --init FILE`, Python's init=): a CSympNet-ID, bare
// or wrapped in its units ("normalization") and learned dof scales ("dof_scales"). The fit
// keeps its architecture, β and θ, and its units: the data are normalised with the file's
// normalisation, or fitted in their own units when the file has none (a map in the user's
// units), so that θ means what it meant. docs/identification.md, "Starting from a model file".
struct IdentifyInit {
  std::string file;      // the path, as given
  std::string checksum;  // the file's checksum (model_file.hpp)
  Model model;           // the whole model of the file (normalisation included)
  Vector theta;
  nlohmann::json inner_spec;                   // the file's spec without "normalization"
  std::optional<Normalization> normalization;  // the file's, if it has one
  bool dof_scales = false;                     // the file learns per-dof momentum scales
};
// Reads and checks FILE: a model file of CSympNet-ID (a one-step map with γ). Refuses any other
// file, or another model kind, with an OptionError for `init` that names the file.
std::shared_ptr<const IdentifyInit> load_identify_init(const std::string& file);

struct IdentifyConfig {
  // null: chosen by validation loss between an LA core (by dimension, with step polynomials
  // when steps vary) and a G core (docs/identification.md); else the core used.
  nlohmann::json core;
  std::uint64_t seed = 42;  // blocks held out, initialisation
  long window = 0;          // steps per window; 0: automatic (1 for pairs, else ≤ 4)
  bool balanced = true;     // balanced residuals (false: the plain one-step residuals)
  bool normalize = true;    // remove units and offsets first
  DofScales dof_scales = DofScales::kAuto;
  long epochs = 0;  // AdamW budget; 0: scaled to the data
  double lr = 1e-3;
  // LM budget (per candidate core); 0: scaled to the work per iteration, and the chosen core
  // continues with a further share.
  long lm_iterations = 0;
  double val_fraction = 0.2;  // share of blocks held out
  long target_blocks = 20;    // a long trajectory is cut into about this many segments
  double level = 0.95;        // interval level
  int threads = 1;
  // Momenta that the measured_momenta check finds computed from noisy positions: false (the
  // default) sets them aside and fits the positions alone; true uses them as given, with a
  // warning in that check (key "derived_momenta": "set_aside" or "use").
  bool use_derived_momenta = false;
  // Start from this model file's architecture, θ and units instead of fresh cores; AdamW then
  // runs only when `epochs` is given (0: none, LM alone refines the file's θ).
  std::shared_ptr<const IdentifyInit> init;
  // The dissipation beside the viscous rate γ, for the library core (docs/identification.md,
  // "Dry friction and drag"): "auto" (Coulomb friction and quadratic drag enter when the
  // held-out loss and the amplitude check both call for them), "viscous" (γ alone),
  // "viscous+coulomb" or "viscous+drag" (that term on every coordinate, fitted as given, with
  // the library core as the only candidate). The CLI's --dissipation, Python's dissipation=.
  std::string dissipation = "auto";
  // How a record of trajectories with momenta is fitted (docs/identification.md, "Records with
  // momenta"): "windows" (the balanced windows of a few steps), "whole" (then the whole record
  // by multiple shooting with q and p observed, each with its own noise, and its interval), or
  // "auto". The CLI's --record-fit, Python's record_fit=.
  std::string record_fit = "auto";
  // Refuses a value out of its range with an OptionError naming it by its key.
  void validate() const;
};
void to_json(nlohmann::json& j, const IdentifyConfig& c);

// The one place an IdentifyConfig is built from a front end's settings (the CLI's options,
// Python's `identify` keywords): the defaults above, overridden by each key given. Keys:
// core, seed, window, balanced, normalize, dof_scales, epochs, lr, lm_iterations,
// val_fraction, blocks, level, threads, derived_momenta, init (a model file's path:
// load_identify_init; it refuses a given core, normalize = false with a file that has a
// normalisation, and dof_scales that disagree with the file). A key not in that list is refused by
// name; a value misspelt or out of its range with an OptionError naming its key
// (IdentifyConfig::validate, which identify() calls again), before any work.
IdentifyConfig make_identify_config(const nlohmann::json& settings);

// What the fit did at each stage: `stage` is called as each begins ("warm start", "AdamW",
// "LM", "LM on longer windows …", "interval"); `progress` after each AdamW validation and each
// accepted LM step (TrainProgress::stage "adamw" or "lm"; false ends that stage, keeping its
// best iterate); `should_stop` is polled by AdamW (each validation) and LM (each iteration and
// between blocks of a large factorisation): an interrupt, which ends the whole fit.
struct IdentifyHooks {
  ProgressCallback progress;
  std::function<void(const std::string& stage)> stage;
  std::function<bool()> should_stop;
  // The ranks sharing the window sums (null: this process alone). Every rank then calls
  // identify() with the same data and settings, and `progress` and `should_stop` must give
  // every rank the same answer (an agreement over the ranks): the result has the same bits on
  // every rank and for any number of ranks (docs/architecture.md, "Identification over MPI
  // ranks").
  const Communicator* communicator = nullptr;
};

struct IdentifyQuality {
  double train_loss = 0.0;             // window loss (normalised units) on training windows
  double val_loss = 0.0;               // ... on validation windows
  double val_relative_residual = 0.0;  // ‖Φ̂ᵐ(z0) − zm‖ / ‖zm − z0‖ on validation windows
  // Held-out squared error of the model over that of the best pure contraction zm ≈ c z0 + b.
  double null_ratio = 0.0;
  double structure_residual_max = 0.0;  // self residual of DΦ̂ at validation starts
};
void to_json(nlohmann::json& j, const IdentifyQuality& q);

// One oscillating mode of the fitted map, linearised at its equilibrium: the map's eigenvalues
// e^{(−ζω ± iω√(1−ζ²)) h} give the natural angular frequency ω (user's time units) and the
// damping ratio ζ (= γ̂ / (2ω) for one rate). Their intervals come from the same sandwich as
// γ̂'s (sandwich_interval_of), present when γ̂ is identified. For a nonlinear system they are
// the small oscillations' about the equilibrium.
struct Mode {
  double frequency = 0.0;
  double damping_ratio = 0.0;
  std::optional<SandwichInterval> frequency_interval, damping_ratio_interval;
};

struct IdentifyResult {
  Model model;  // in the user's units: carries the normalisation
  Vector theta;
  Normalization normalization;
  double gamma = 0.0;                        // γ̂ in the user's time units
  std::optional<SandwichInterval> interval;  // in the user's time units
  bool identified = false;
  // A check of the model's assumptions failed (then not identified): the data break the model.
  bool rejected = false;
  // "identified", "not identified", "model rejected" or "interrupted".
  std::string verdict;
  std::vector<std::string> reasons;  // why not, when not: failed checks first
  std::vector<ModelCheck> checks;    // the assumptions tested (empty when no interval was formed)
  std::vector<Mode> modes;           // ascending frequency; empty when the map has none
  std::string modes_note;            // why fewer than d modes, or none
  // The library core's Hamiltonian in the user's units with intervals (report key
  // "hamiltonian"); null for the LA and G cores.
  nlohmann::json hamiltonian;
  // The dissipation beyond γ in the user's units: a list of {"kind": "coulomb" | "drag",
  // "dof", "value", "low", "high", "unit"} (intervals null unless γ̂ is identified), empty for
  // a purely viscous model. The report's "dissipation" puts the viscous term first.
  nlohmann::json dissipation = nlohmann::json::array();
  std::optional<GammaWarmStart> warm_start;
  std::string warm_start_note;
  TrainSummary training;
  LmReport lm;
  long lm_best_iteration = 0;
  IdentifyQuality quality;
  IdentifyConfig config;   // with every automatic choice resolved
  nlohmann::json choices;  // what was chosen automatically, and why
  nlohmann::json data;     // a summary of the data: d, trajectories, samples, steps, blocks
  bool stopped = false;    // a stage was interrupted
  // What the record holds: "positions and momenta" or "positions" (identify_positions).
  std::string observed = "positions and momenta";
  // A driven record's inputs (identify_driven): {"m", "hold", "B", "B_ci_low", "B_ci_high", …};
  // null for a free record (the report then has no "input").
  nlohmann::json input;
  // Wall times (not in the report, which stays the same run to run), over every candidate.
  double adamw_seconds = 0.0;
  double lm_seconds = 0.0;
  double interval_seconds = 0.0;
};

// `trajs`: the user's trajectories (a pairs file: one two-point trajectory per pair).
// `pairs_only`: the data are independent pairs (windows of one step, each pair a block).
IdentifyResult identify(const std::vector<Trajectory>& trajs, bool pairs_only,
                        const IdentifyConfig& config, const IdentifyHooks& hooks = {});

// A record of positions alone: each trajectory's z holds the d position rows (d × n). The
// momenta are hidden states fitted with the map, the loss is on the positions
// (docs/derivations.md, "Positions only: the momenta as hidden states"); the interval, checks
// and verdict are those of identify(). Trajectories only: a pair needs a state.
IdentifyResult identify_positions(const std::vector<Trajectory>& positions,
                                  const IdentifyConfig& config, const IdentifyHooks& hooks = {});

// A record driven by known inputs u(t) (each trajectory's u, m rows, sampled with its positions;
// z holds the d positions, or 2d states whose momenta are set aside): the Hamiltonian-library
// core with the input's gain B, H = H₀ − qᵀB u(t), fitted by multiple shooting on the positions
// with the inputs (docs/identification.md, "Driven records"); `positions_only`: z holds the d
// positions (else 2d states). Refuses, as an OptionError naming the option, what this route does
// not support: a neural core, an init file, friction or drag.
IdentifyResult identify_driven(const std::vector<Trajectory>& trajs, bool positions_only,
                               const IdentifyConfig& config, const IdentifyHooks& hooks = {});

// The dissipation found, in one sentence: "viscous gamma = 0.0301 [0.0292, 0.0310] plus dry
// friction mu = 0.0412 [0.0398, 0.0427] (q unit per time unit squared)"; intervals only when
// identified.
std::string dissipation_sentence(const IdentifyResult& r);

// Every decision between models the identification took, one row each: {"decision",
// "criterion", "chosen", "chosen_value", "runner_up", "runner_up_value", "margin",
// "margin_unit" ("BIC", "standard errors" or "relative"), "margin_means"}. The values are the
// losses the criterion is computed from (mean squared residuals, normalised units; null where
// none was recorded). Report key "model_selection"; read from the stages' records in r.choices.
nlohmann::json model_selection(const IdentifyResult& r);

// The report of an identification (report.json of `csympnet fit`): the same run to run, so
// without the stages' wall times.
nlohmann::json identify_report(const IdentifyResult& r);
// The wall seconds the stages recorded in r.choices, by their path there (e.g.
// "choices.positions.seconds"): what identify_report leaves out (timings.json of `fit`).
nlohmann::json identify_wall_seconds(const IdentifyResult& r);

}  // namespace csympnet
