// The stages of identify() (identify/identify.hpp), each a function or class with one job that
// returns what it found as a value of its own (docs/architecture.md, "The identification in
// stages"); no stage writes into the IdentifyResult, which assemble() (identify.cpp) builds from
// those values in one place:
//
//   inspect_data     → DataFacts       dimension, steps, a summary for the report
//   choose_units     → Units           normalisation (or the init file's units), the data in it
//   split_blocks     → BlockSplit      blocks, held-out blocks, window length, the windows
//   warm_start       → WarmStart       γ₀ from the data, the dof scales, β's start
//   CandidateFit                       per candidate core: AdamW, Levenberg–Marquardt
//   fit_library      → LibraryFit      the Hamiltonian-library candidate, its terms selected
//   choose_core      → CoreChoice      the lowest validation loss wins and continues LM
//   adapt_windows    → WindowChoice    longer windows when the residuals show noise, not misfit
//   fit_core         → CoreFit         the stages above, their choices merged in order
//   fit_whole_record → WholeRecordFit  a record with momenta fitted whole (identify_states.cpp)
//   refine_on_positions → PositionsFit the momenta as hidden states (identify_positions.cpp)
//   interval         → GammaInterval   cluster-robust sandwich over the training blocks, held-out
//                                      inflation; the modes (modal_analysis → Modes) with theirs
//   measure_quality  → HeldOutQuality  held-out residuals, the null model, the structure residual
//   run_checks       → ModelChecks     the model's assumptions tested (identify/model_checks.hpp)
//   confirm_growth   → GrowthRate      growing motion fitted again in reversed time
//   verdict          → Verdict         identified, not identified (and why), or rejected
//   assemble         → IdentifyResult  from the CoreFit and the route's FinalFit
//
// A driven record (identify_driven.cpp) has its own stages and assembles its own result.
//
// Private to the library (src/identify).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/communicator.hpp"
#include "csympnet/identify/identify.hpp"
#include "csympnet/models/dissipation_terms.hpp"
#include "csympnet/models/potential_library.hpp"
#include "csympnet/train/window_loss.hpp"

namespace csympnet::detail {

// v with `digits` significant digits (printf's %g), for the sentences of the report.
std::string significant(double v, int digits = 4);

// What the data are, before anything is fitted.
struct DataFacts {
  Index d = 0;
  double h_min = 0.0, h_max = 0.0;
  bool varying_steps = false;
  nlohmann::json summary;  // the report's "data"
};
DataFacts inspect_data(const std::vector<Trajectory>& trajs, bool pairs_only);

// The units the fit works in: the normalisation chosen (or the init file's), and the data in
// those units.
struct Units {
  Normalization normalization;
  bool normalize = true;                              // the report's config.normalize
  nlohmann::json choices = nlohmann::json::object();  // why, for an init file's units
  std::vector<Trajectory> trajectories;               // the data, normalised
};
Units choose_units(const std::vector<Trajectory>& trajs, bool pairs_only,
                   const IdentifyConfig& config);

// Blocks and windows.
struct BlockSplit {
  std::vector<Trajectory> blocks;  // every block, normalised, in order
  std::vector<Trajectory> train_blocks, val_blocks;
  // Per block of `blocks`: its trajectory and first sample there (neighbouring blocks of one
  // trajectory share an end sample); which blocks train and which are held out, in order.
  std::vector<std::pair<Index, Index>> origin;
  std::vector<Index> train_ids, val_ids;
  Index m = 1;             // the window length in use
  Index m_long = 1;        // the length an automatic window may grow to
  bool adaptive = false;   // an automatic window: starts at one step, may grow (adapt_windows)
  WindowSet train, val;    // windows of m steps; training blocks numbered 0 … B_t − 1
  nlohmann::json summary;  // the report's choices.blocks
  void set_window(Index len);
};
BlockSplit split_blocks(const std::vector<Trajectory>& nt, bool pairs_only,
                        const IdentifyConfig& config);

// γ₀ from the one-step pairs, the dof scales chosen, and β's start.
struct WarmStart {
  double beta_init = 0.1;               // |γ₀| (at least 1e-6), or 0.1 without γ₀
  std::optional<GammaWarmStart> gamma;  // γ₀ in the fit's units
  std::string note;                     // why there is no γ₀
  DofScales dof_scales = DofScales::kFixed;
  nlohmann::json choices = nlohmann::json::object();  // dof_scales and why
};
WarmStart warm_start(const BlockSplit& split, Index d, const IdentifyConfig& given);

// The candidate cores when none is given (LA and G, by dimension).
std::vector<nlohmann::json> default_cores(Index d, bool varying_steps);
std::string core_name(const nlohmann::json& core);

// One candidate model and how far its training got.
struct Candidate {
  nlohmann::json core;
  Model inner;
  Vector theta;
  TrainSummary training;
  LmReport lm;
  long lm_best_iteration = 0;
  double lm_seconds = 0.0;
  double val_loss = std::numeric_limits<double>::infinity();
  bool pretrained = false;  // trained before choose_core (the library candidate)
};
std::vector<Candidate> make_candidates(const std::vector<nlohmann::json>& cores, Index d,
                                       double beta_init, const IdentifyConfig& c,
                                       std::uint64_t seed);

// Training of candidates on the split's windows: AdamW and LM with their budgets by work.
class CandidateFit {
 public:
  CandidateFit(const IdentifyConfig& given, const IdentifyConfig& resolved,
               const IdentifyHooks& hooks, const Communicator& comm, const BlockSplit& split,
               double share);
  long epochs_for(const Candidate& x) const;
  // LM iterations for about `target` seconds on one core (at least `floor`; 0 with more
  // than 6,000 parameters).
  long lm_budget(const Candidate& x, double target, long floor = 5) const;
  void adamw(Candidate& x, const std::string& label) const;
  // What ends an LM besides its budget and held-out patience: the χ² rule
  // (kLmChi2Tolerance) always; once the core is chosen, also the damping rate's
  // (kDampingConvergedSe). The fits that choose (the candidates', the library's selection and
  // final fit) run without it: ended earlier, their held-out losses changed the core chosen on
  // records with differenced momenta, and the coverage there fell (docs/benchmarks.md).
  enum class LmEnd { kChi2, kChi2OrGammaSettled };
  void lm(Candidate& x, long budget, const std::string& label, LmEnd end = LmEnd::kChi2);
  // One Gauss–Newton step on the training windows from x.theta, −(A + μD)⁻¹g with μ a ridge at
  // 1e-9 of the diagonal (grown only if A + μD cannot be factored); empty when stopped. It
  // measures how far a small change of the model moves the fit, where an LM run kept to the
  // best validation loss would report no move.
  Vector gauss_newton_step(const Candidate& x) const;
  double loss(const Candidate& x, const WindowSet& w) const;
  bool stop_requested() const;
  // Remembers a stop requested now (polled between stages).
  void note_stop() {
    if (stop_requested()) stopped_ = true;
  }
  bool stopped() const { return stopped_; }
  const BlockSplit& split() const { return *split_; }
  // The same fit (options, hooks, ranks) on another split: the library's selection on a
  // thinned one (fit_library).
  CandidateFit on(const BlockSplit& other) const {
    CandidateFit f = *this;
    f.split_ = &other;
    return f;
  }

 private:
  const IdentifyConfig* given_;
  const IdentifyConfig* c_;
  const IdentifyHooks* hooks_;
  const Communicator* comm_;
  const BlockSplit* split_;
  double share_;
  bool stopped_ = false;
};

inline constexpr long kLmPatience = 100;
// The one-step LMs end once the Gauss–Newton step left would lower χ² by less than this
// (LmSettings::chi2_tolerance): θ is then within about 0.032 standard errors of where the LM
// would go on to, and further iterations cost seconds for nothing the interval can see.
inline constexpr double kLmChi2Tolerance = 1e-3;
// Every LM of the identification, on windows or on positions, ends once the damping rate has
// stopped moving (LmSettings::watch_index, ShootingOptions::watch_index): three
// near-Gauss–Newton steps in a row each move it by less than this share of its standard error.
inline constexpr double kDampingConvergedSe = 0.01;

// Every candidate trained; the lowest validation loss wins and continues LM.
struct CoreChoice {
  std::size_t index = 0;  // the winner in the candidates
  nlohmann::json core;    // its core
  long epochs = 0;        // its AdamW epochs and LM iterations, the report's config
  long lm_iterations = 0;
  nlohmann::json choices = nlohmann::json::object();  // core, its candidates and why; budgets
};
CoreChoice choose_core(std::vector<Candidate>& cand, CandidateFit& fit, bool choosing,
                       bool varying_steps, const IdentifyConfig& given);

// The Hamiltonian-library candidate (identify_library.cpp): given_core {"type": "library"}
// selects its terms (forward selection by Gauss–Newton gain, kept by the held-out loss, pruned
// by their intervals); with "terms" it fits those. `record` is the report's
// choices.library.
// The largest d at which the library core is a default candidate. Beyond d = 4 its pool holds
// the neighbours' differences alone, so an LM iteration costs about d² (d terms, d + 2d
// tangent columns); on chains of 8 and 10 masses from positions it took a quarter and a half of
// the neural cores' CPU time, with intervals 1.1-1.3 times a parametric fit's width
// (docs/benchmarks.md, "A fit's cost against d"). At d = 20 one fit took 10 minutes from
// positions and over 25 with momenta.
inline constexpr Index kLibraryMaxD = 10;
struct LibraryFit {
  Candidate cand;
  nlohmann::json record;
  bool thinned = false;  // its final fit saw the thinned windows (`start_only`)
};
// `dissipation`: IdentifyConfig::dissipation ("auto" selects Coulomb friction and drag beside
// γ; "viscous" none; "viscous+coulomb", "viscous+drag" fit that term as given). On more than
// 20,000 training windows the selection runs on 20,000 of them, evenly spread, and the final fit
// on all (record["selection_windows"]), or with `start_only` (a later fit of the record refits
// θ) on the 20,000 too.
LibraryFit fit_library(CandidateFit& fit, const nlohmann::json& given_core, Index d,
                       double beta_init, const Normalization& units, bool balanced,
                       const Communicator& comm, const std::string& dissipation = "auto",
                       bool start_only = false);

// The dissipation terms beside γ (identify_dissipation.cpp; docs/identification.md, "Dry
// friction and drag"):
// one term of `kind` on every coordinate;
std::vector<DissipationTerm> dissipation_group(DissipationKind kind, Index d);
// the rates of the library candidate's dissipation terms from index `first` on, and a change
// of β, started by least squares on the training windows' momentum residuals of the candidate
// with those rates at 0 (the residual over a window of span H is about −H times the new
// forces at the window's mean momentum);
void dissipation_start(Candidate& y, std::size_t first, const WindowSet& train);
// the amplitude check (model_checks.hpp, amplitude_check) of a candidate on every block;
ModelCheck amplitude_of(const Candidate& x, const BlockSplit& split,
                        const std::function<bool()>& should_stop);

// A relative one-step residual (relative_residual) at or below this is clean data explained:
// noise of that size biases nothing the data can see (its bias in θ is of its square).
inline constexpr double kCleanRelativeResidual = 1e-7;

// Whether the candidate explains the held-out windows to the noise floor (white one-step
// residuals, or a clean fit), with the sentence saying which.
bool at_noise_floor(const Candidate& x, const BlockSplit& split, bool balanced, std::string& why);

// The correlation of consecutive windows' residuals (res: window_residuals of w) within a
// block: about −1/2 for one-step residuals of pure measurement noise, positive for a misfit.
double lag_one_correlation(const Vector& res, const WindowSet& w);
// ‖res‖ / ‖steps‖ (res: window_residuals of w): the residuals' size against the windows' own
// moves, in any units.
double relative_residual(const Vector& res, const WindowSet& w);

// The library's selection (start, additions, drops, dissipation) sees at most this many
// training and this many held-out windows, evenly spread over the record; the final fit sees
// them all. A
// term is kept when it lowers the held-out loss by a share g of at least 2e-3. The fitted
// parameters' own noise costs a model of p parameters about p / n of the loss (1e-4 for two
// added terms), and on n held-out residuals the paired change of the loss is seen at about
// √(g n) / 2 standard errors (4.5 at the threshold for 20,000 one-dof windows): a longer record
// buys a narrower interval, not another choice. On 10⁵ samples the selection had taken a third
// of a fit's time, and on 10⁶ a quarter.
inline constexpr Index kSelectionWindows = 20000;
// The split with at most `cap` training and `cap` held-out windows, evenly spread; the blocks
// as they are (identify_library.cpp).
BlockSplit selection_split(const BlockSplit& split, Index cap);

// Longer windows when noise dominates misfit (an automatic window only); LM continues on them.
// With `start_only` (a fit of the whole record or of the positions refits θ after) that LM
// sees at most kSelectionWindows training and held-out windows, evenly spread (`thinned`):
// the windows' θ is then a start, and a start needs no more windows than a choice of terms.
struct WindowChoice {
  nlohmann::json choices = nlohmann::json::object();  // why this window; the LM spent on it
  bool thinned = false;
};
WindowChoice adapt_windows(Candidate& best, CandidateFit& fit, BlockSplit& split,
                           const IdentifyConfig& given, bool pairs_file, bool balanced,
                           bool start_only);

// The largest absolute normalised coordinate: the data's scale for the interval's rounding term.
double data_scale(const std::vector<Trajectory>& nt);

// What the modes' intervals share with γ̂'s.
struct ModeIntervalInput {
  const NormalEquations* ne = nullptr;  // null: the modes without intervals
  Index n_residuals = 0;
  double residual_scale = 1.0;        // of the residuals in ne
  double data_scale = 0.0;            // for the rounding term
  double inflation = 1.0;             // the held-out inflation applied to γ̂'s interval
  std::function<bool()> should_stop;  // polled per parameter; true: stopped, no intervals
};

// What the Hamiltonian's intervals share with γ̂'s (null ne: no intervals).
struct HamiltonianIntervalInput {
  const NormalEquations* ne = nullptr;
  Index n_residuals = 0;
  double residual_scale = 1.0;
  double inflation = 1.0;
  double level = 0.95;
};
// A library map's Hamiltonian in the user's units (identify_hamiltonian.cpp): the report's
// "hamiltonian"; null for any other map.
nlohmann::json hamiltonian_report(const OneStepMap& map, const Vector& theta,
                                  const Normalization& units, const HamiltonianIntervalInput& in);
// A library map's dissipation terms beside γ in the user's units, with their intervals (null
// ne: none): the report's "dissipation" terms after the viscous one (identify_dissipation.cpp);
// an empty list for any other map.
// `integrator`: per term, the relative change of its value at twice the substeps, added in
// quadrature to its standard error (as gamma's integrator share); empty: none.
// Per dissipation term of a library map, |value at `moved` − value at `theta`| / |value at
// theta| (its value in the user's units is a fixed multiple of W_ii μ or c / W_ii, so the ratio
// needs no units); empty for any other map.
std::vector<double> dissipation_relative_changes(const OneStepMap& map, const Vector& theta,
                                                 const Vector& moved);
nlohmann::json dissipation_terms_report(const OneStepMap& map, const Vector& theta,
                                        const Normalization& units,
                                        const HamiltonianIntervalInput& in,
                                        const std::vector<double>& integrator = {});

// The fitted map linearised at its fixed point nearest the training windows' mean state: each
// oscillating mode's natural frequency and damping ratio (user's time units: time_scale), with
// intervals at `level` when `in.ne` is given (identify_modes.cpp).
struct Modes {
  std::vector<Mode> list;  // ascending frequency
  std::string note;        // why fewer than d modes, or none
  bool stopped = false;    // interrupted: the modes without intervals
};
Modes modal_analysis(const OneStepMap& map, ConstParams theta, const WindowSet& train,
                     double time_scale, double level, const ModeIntervalInput& in);

// What γ̂'s interval is formed at: the fitted θ, and the fit's losses for the held-out inflation.
struct IntervalBasis {
  Vector theta;         // the fit's units
  Normalization units;  // γ̂ and the terms in the user's units
  double level = 0.95;
  bool balanced = true;
  double train_loss = 0.0, val_loss = 0.0;
  // choices.library when the core is the library core (its integrator's shares), else null.
  nlohmann::json library;
  // The library core's spec (with its substeps) when the core is the library core, else null:
  // the shooting routes measure the integrator's share on their own fit (identify_segments).
  nlohmann::json library_core;
};
// γ̂'s interval in the user's time units, with what shares its normal equations: the modes',
// the Hamiltonian's and the friction's.
struct GammaInterval {
  std::optional<SandwichInterval> interval;
  Modes modes;
  nlohmann::json hamiltonian;                       // with intervals; null: none formed
  std::optional<nlohmann::json> dissipation;        // with intervals; none: none formed
  std::vector<std::string> reasons;                 // why no interval could be formed
  std::optional<double> degrees_of_freedom_factor;  // segments: for the fitted start states
  bool stopped = false;                             // interrupted: no interval
  double seconds = 0.0;
};
// From the training windows (interval of the windows' fit).
GammaInterval interval(const OneStepMap& map, const IntervalBasis& at, const BlockSplit& split,
                       const std::vector<Trajectory>& nt, const IdentifyHooks& hooks,
                       const Communicator& comm);

// The quality on the validation windows (IdentifyQuality's shares; the losses are the fit's).
struct HeldOutQuality {
  double val_relative_residual = 0.0;
  double null_ratio = 0.0;
  double structure_residual_max = 0.0;
};
HeldOutQuality measure_quality(const OneStepMap& map, ConstParams theta, const BlockSplit& split,
                               Index d);

// The model's assumptions tested on every block (model_checks.hpp, check_model), in the user's
// time units (time_scale).
using ModelChecks = std::vector<ModelCheck>;
ModelChecks run_checks(const OneStepMap& map, ConstParams theta, const BlockSplit& split,
                       double time_scale, double level, const IdentifyHooks& hooks);

// What the verdict weighs: the fit, its interval, its quality and the checks.
struct Evidence {
  double gamma = 0.0;  // γ̂, user's units
  std::optional<SandwichInterval> interval;
  IdentifyQuality quality;
  StopReason training_stop = TrainSummary{}.stop_reason;
  double level = 0.95;
  bool stopped = false;
  ModelChecks checks;                // the data's own check first
  std::vector<std::string> reasons;  // the stages' before (no interval could be formed)
};
// Identified, not identified (and why: failed checks first), or the model rejected.
struct Verdict {
  bool identified = false;
  bool rejected = false;
  std::string text;  // "identified", "not identified", "model rejected" or "interrupted"
  std::vector<std::string> reasons;
  ModelChecks checks;  // as judged: undecided where the model explains too little to test
};
Verdict verdict(const BlockSplit& split, double h_max, bool lm_fits, Evidence e);

// The stages up to the chosen core trained (inspect_data … adapt_windows), with what each
// found; choices and config merged from them in order.
struct CoreFit {
  DataFacts facts;
  Units units;            // units.trajectories: the data in the fit's units
  ModelCheck data_check;  // measured_momenta_check of the data (derived_momenta applied)
  BlockSplit split;
  WarmStart warm;
  std::vector<Candidate> cand;
  CoreChoice choice;
  WindowChoice windows;
  std::size_t best = 0;  // the chosen candidate
  // The chosen core's last window fit saw thinned windows, a refit of the record to follow
  // (the library's final fit, or the LM on longer windows): windows_on_every_window.
  bool thinned_start = false;
  bool lm_fits = true;     // at most 6,000 parameters: LM and an interval
  bool stopped = false;    // a stop was requested during training
  IdentifyConfig config;   // with every automatic choice resolved
  nlohmann::json choices;  // every stage's, merged in order
  // The chosen core as the windows left it: θ, γ̂ (user's time units), its window losses, its
  // training and LM (the whole-record and positions fits refit θ, not these records).
  Vector theta;
  double gamma = 0.0;
  double train_loss = 0.0, val_loss = 0.0;
  TrainSummary training;
  LmReport lm;
  long lm_best_iteration = 0;
  double adamw_seconds = 0.0, lm_seconds = 0.0;  // over every candidate
};
// Whether the library core explains the data to the noise, so that the neural cores are not
// trained; `why` says what was measured. The default judges the held-out one-step residuals
// (at_noise_floor); the positions route judges the positions (identify_positions.cpp), and may
// replace the library candidate by one with terms judged there (its record in `record`).
using FloorTest = std::function<bool(Candidate& library, const BlockSplit& split, std::string& why,
                                     nlohmann::json& record)>;
// Whether a later stage refits θ on the record (the whole-record fit, the positions fit) when
// `core` is chosen: the windows' θ is then a start (fit_library's and adapt_windows'
// `start_only`).
using RefitFollows = std::function<bool(const nlohmann::json& core)>;
CoreFit fit_core(const std::vector<Trajectory>& trajs, bool pairs_only,
                 const IdentifyConfig& config, const IdentifyHooks& hooks,
                 const FloorTest& floor_test = {}, const RefitFollows& refit_follows = {});
// Where the chosen core was fitted on thinned windows as a start (CoreFit::thinned_start) and
// the refit that was to follow was not made: its LM continued on every window, f's θ, γ̂,
// losses and LM record from it.
void windows_on_every_window(CoreFit& f, const IdentifyConfig& config, const IdentifyHooks& hooks);

// Whether a record with momenta is fitted as a whole (config.record_fit: "whole", "windows",
// or "auto": identify_states.cpp says when).
bool whole_record_wanted(const nlohmann::json& core, const IdentifyConfig& config);
// The whole-record fit of a record with momenta (identify_states.cpp): from the windows' fit,
// θ and every segment's start state fitted to the observed q and p, the segments linked over
// the record; the chosen candidate (f.cand[f.best]) carries its θ and core.
struct WholeRecordFit {
  // Whether the whole record was fitted: false when no block has segments to fit (the
  // windows' θ and interval then stand) or on a stop request.
  bool fitted = false;
  bool stopped = false;
  nlohmann::json record;               // choices.whole_record
  std::optional<nlohmann::json> core;  // when the chain's judgement of the terms changed it
  // When fitted: θ, γ̂ (user's time units), the chain's losses, and the interval (with the
  // modes', the Hamiltonian's and the friction's) or the reason there is none.
  Vector theta;
  double gamma = 0.0;
  double train_loss = 0.0, val_loss = 0.0;
  GammaInterval interval;
};
WholeRecordFit fit_whole_record(CoreFit& f, const IdentifyConfig& given,
                                const IdentifyHooks& hooks);

// The model in the user's units: the inner map wrapped in the normalisation (unless an init
// file without one fixed the units).
Model user_model(const Model& inner, const Normalization& units, const IdentifyInit* init);

// Where a route's last fit ended and how it was judged: assemble() (identify.cpp) puts it
// beside the CoreFit into the IdentifyResult.
struct FinalFit {
  std::string observed = "positions and momenta";
  Vector theta;                                       // the fit's units
  double gamma = 0.0;                                 // user's time units
  std::optional<nlohmann::json> core;                 // when the route changed the core
  nlohmann::json choices = nlohmann::json::object();  // the route's records, over fit_core's
  std::optional<TrainSummary> training;               // when the route chose another candidate
  std::optional<LmReport> lm;
  IdentifyQuality quality;
  GammaInterval interval;  // its interval, modes and timing
  nlohmann::json hamiltonian;
  nlohmann::json dissipation = nlohmann::json::array();
  Verdict verdict;
  bool stopped = false;  // a stage after fit_core was interrupted
};
IdentifyResult assemble(const CoreFit& f, const FinalFit& end);
// The basis of an interval at θ of the model with `core` (the losses: the held-out inflation's).
IntervalBasis interval_basis(const CoreFit& f, const Vector& theta, const nlohmann::json& core,
                             double train_loss, double val_loss);
// What the verdict weighs of a route's end (its γ̂, interval, quality and training) beside the
// checks and the reasons the stages gave before.
Evidence evidence(const CoreFit& f, const FinalFit& end, ModelChecks checks,
                  std::vector<std::string> reasons, bool stopped);

// A library candidate with one sin/cos or exp group replaced by the powers of the same
// argument (1..4 of a coordinate; 2..4 of a difference, its linear part on the two
// coordinates), started from the group's potential fitted by that polynomial over the
// arguments of the positions q (d × N, the fit's units): one per such group
// (identify_library_swap.cpp).
struct PolynomialAlternative {
  std::string replaced, by;
  Candidate candidate;
};
std::vector<PolynomialAlternative> polynomial_alternatives(const Candidate& lib, Index d,
                                                           const Matrix& q);
// The reverse, for a coordinate without a sinusoid: its powers of degree 3 and 4 replaced by a
// sin/cos pair of it (its linear and square terms kept or added), the pair started from the
// powers' potential fitted by q_i, q_i², sin(κ q_i) and cos(κ q_i) over the positions q,
// κ = 1 / the coordinate's half range.
std::vector<PolynomialAlternative> periodic_alternatives(const Candidate& lib, Index d,
                                                         const Matrix& q);
// The library candidate with a linear term qI for every coordinate that has none (coefficients
// 0, the rest of θ as it was), or none when it has them all or is no library core. From
// positions alone the rest position is not known: the normalisation's shift (the mean of the
// positions) misses it by a share of the amplitude that, at low noise, is larger than the noise
// (identify_library_swap.cpp).
std::optional<Candidate> with_rest_position_terms(const Candidate& lib, Index d);
// The library candidate with the terms `next`: the mass, β and each kept term's coefficient
// (and wavenumber) carried over from `lib`, a new term at 0. Throws for a candidate that is no
// library core.
Candidate library_with_terms(const Candidate& lib, Index d, const std::vector<LibraryTerm>& next);
// The same with the dissipation terms `next_dissipation` (a kept one's rate carried over, a new
// one at HamiltonianLibraryMap::kDissipationInit).
Candidate library_with(const Candidate& lib, Index d, const std::vector<LibraryTerm>& next,
                       const std::vector<DissipationTerm>& next_dissipation);

// identify_positions() after the core is trained on the positions with velocities from a
// local polynomial: the momenta as hidden states (identify_positions.cpp), fitted with θ on the
// positions, the segments linked; its interval and quality. The chosen candidate
// (f.cand[f.best]) carries the final θ and core, f.split the blocks with the reconstructed
// momenta. `given` is the configuration as the user gave it: library terms named there are
// fitted as given, and its lm_iterations (0: automatic, 100) bounds each positions fit.
struct PositionsFit {
  nlohmann::json record;               // choices.positions
  std::optional<nlohmann::json> core;  // when the route changed the core
  // When the positions chose another candidate than the velocity start: why, and its
  // training records.
  std::optional<nlohmann::json> core_reason;
  std::optional<TrainSummary> training;
  std::optional<LmReport> lm;
  std::vector<std::string> reasons;  // why nothing was fitted on the positions
  // Whether the positions were fitted: false with no segment to fit, a stop, no LM or a
  // diverged training (the velocity start's θ then stands, unassessed).
  bool fitted = false;
  bool stopped = false;
  // When fitted: γ̂ (user's time units), the final losses, the interval, the quality on the
  // positions, the friction and drag, and the largest sensitivity of a segment's rollout.
  double gamma = 0.0;
  double train_loss = 0.0, val_loss = 0.0;
  GammaInterval interval;
  HeldOutQuality quality;
  nlohmann::json dissipation = nlohmann::json::array();
  double sensitivity = 0.0;
};
PositionsFit refine_on_positions(const std::vector<Trajectory>& positions, CoreFit& f,
                                 const IdentifyConfig& given, const IdentifyHooks& hooks);
// identify_positions() of a record whose given momenta were set aside: `set_aside` (the data's
// measured_momenta check, passed, saying why) stands for the positions route's own check.
IdentifyResult positions_in_place_of_momenta(const std::vector<Trajectory>& positions,
                                             const IdentifyConfig& config,
                                             const IdentifyHooks& hooks,
                                             const ModelCheck& set_aside);

// The data in reversed time: each trajectory (a pair is a two-point trajectory) read from its
// end, t' = t_end − t (identify.cpp).
std::vector<Trajectory> reversed_in_time(const std::vector<Trajectory>& trajs);
// When the dissipation check finds growing motion: `refit` (the same pipeline) on the record
// in reversed time, where growing motion decays, gives the growth rate and its interval for
// the check's sentence; a record that seems to grow both ways leaves the check undecided.
struct GrowthRate {
  ModelChecks checks;    // the checks, the failed dissipation check completed
  bool stopped = false;  // the fit in reversed time was interrupted
};
using Refit = std::function<IdentifyResult(const std::vector<Trajectory>&)>;
GrowthRate confirm_growth(const std::vector<Trajectory>& trajs, const Refit& refit,
                          const IdentifyConfig& config, const IdentifyHooks& hooks,
                          ModelChecks checks, bool stopped);

}  // namespace csympnet::detail
