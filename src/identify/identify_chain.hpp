// Multiple shooting with continuity (Bock): the segments of a positions-only record linked
// into chains over whole stretches of the record (docs/derivations.md, "Positions only: linked
// segments"; docs/identification.md, "Positions only"). A record with known inputs (its
// trajectories' u) is linked the same way, each segment carrying its steps' inputs
// (identify_driven_link.cpp).
//
// The segment fit of identify_positions.cpp gives every segment its own start state, so the
// decay from one segment to the next, where γ lives, is thrown away. Here the segments are
// merged, four at a time, into longer ones whose start states are carried from the previous
// fit's rollout, and θ and the remaining start states are refitted, until one segment spans
// each stretch of the record (a gap breaks a stretch) or the model stops following the
// positions. Merging two segments is imposing their matching condition exactly (the end state
// of one is the start state of the next); growing the segments by steps keeps each fit within
// the basin of the previous one, which is what multiple shooting's free start states buy.
//
// The held-out blocks stay out of the loss: a chain passes through them unobserved (weight 0),
// the map carrying the state across, and each position of a training block keeps its block as
// its cluster for the sandwich interval.
#pragma once

#include <functional>
#include <optional>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/types.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/train/positions_state.hpp"
#include "csympnet/train/shooting.hpp"
#include "identify_stages.hpp"

namespace csympnet {
class HamiltonianLibraryMap;
}  // namespace csympnet

namespace csympnet::detail {

// `options` watching this map's damping parameter (unchanged for a map without one).
inline ShootingOptions watching_damping(const OneStepMap& map, ShootingOptions options) {
  if (const std::optional<Index> b = map.damping_param_index()) options.watch_index = *b;
  return options;
}

// Per normalised trajectory: which positions are training positions, and their block.
struct RecordLayout {
  std::vector<Vector> observed;           // per trajectory: 1 at a training position, else 0
  std::vector<std::vector<Index>> block;  // per trajectory: each position's training block
  double gap = 0.0;  // a step above this breaks a chain (kWindowGapFactor × the median)
  // The rows observed per sample: d (positions; 0 means d) or 2d (the whole state, its
  // momenta observed), and their weights (ShootingSegments::row_weight; empty: 1).
  Index observed_rows = 0;
  Vector row_weight;
};
RecordLayout record_layout(const std::vector<Trajectory>& nt, const BlockSplit& split);

// The known inputs of trajectory t's steps from sample `first` over `len` samples, per step its
// input at its start, then at its end (2m × (len − 1), ShootingSegments::u); empty when t has no
// inputs.
Matrix step_inputs(const Trajectory& t, Index first, Index len);

// Segments over the stretches of the record, each holding at least `per_piece` training
// positions (a shorter rest joins the one before), starts read from `states` (per trajectory,
// 2d × n: the current estimate of the state at every sample). `nt`'s z has 2d rows (the first d
// or all 2d observed: layout.observed_rows); a trajectory with inputs gives its segments theirs.
struct Chain {
  ShootingSegments segs;
  Matrix z0;
  std::vector<std::pair<Index, Index>> span;  // per segment: trajectory, first sample
  Index longest_stretch = 0;                  // training positions in the longest stretch
};
Chain cut_chain(const std::vector<Trajectory>& nt, const RecordLayout& layout, Index per_piece,
                const std::vector<Matrix>& states);

// The fitted rollouts of the chain's segments written into `states`.
void write_chain_states(const OneStepMap& map, ConstParams theta, const Chain& c,
                        std::vector<Matrix>& states);

struct LinkedFit {
  Chain chain;                // the segments of the last accepted stage
  ShootingReport report;      // its fit
  bool linked_fully = false;  // one segment per stretch
  Index per_piece = 0;        // the training positions per segment of the last accepted stage
  nlohmann::json record;      // what was tried and why it stopped
};

// From the segment fit (θ, `states` from its rollouts, the held-out segments and their starts),
// segments grown fourfold per stage up to whole stretches. A stage is kept while its training
// loss, corrected for the unknowns fitted (θ's n_free and 2d per segment), stays within three
// standard errors of the previous stage's, or is at rounding level (rounding_loss: a clean
// in-model record, where a rise is rounding): a model that cannot follow the positions over the
// longer segments stops the linking there, and the report says so. A stage skips the lengths
// over which a rollout with θ as it is already follows the positions (a corrected loss at most
// twice the last stage's), with the iterations of the stages it skips; a skip not kept falls
// back to the fourfold steps. θ, `states` and `val_z0` are those of the last kept stage.
LinkedFit link_segments(const OneStepMap& map, Vector& theta, const std::vector<Trajectory>& nt,
                        const RecordLayout& layout, Index first_length, std::vector<Matrix>& states,
                        const ShootingSegments& val, Matrix& val_z0, const ShootingOptions& options,
                        const ShootingReport& segment_fit);

// A richer force law where the chain breaks (identify_force_law.cpp): when the linking
// stopped because the library core does not follow the positions over the next stage's longer
// segments, each coordinate's missing powers (q^3, q^4) and its sin/cos pair are offered as
// additions, fitted over that longer stage's chain, and the best is made while it lowers the
// information criterion there; then the linking goes on from that stage with the richer core.
// The velocity start's selection judges one-step residuals, which at many samples per period
// hardly see a force's anharmonic part; the longer segments do. `q`: the training positions
// (d x n, for the wavenumbers' start). Every trial is recorded in rec["force_law_on_chain"];
// returns whether a group was added (then `linked` is the new linking, from that stage on);
// throws Error on a stop request. identify_positions.cpp calls it again at the next break, a
// few rounds at most.
bool richer_force_law_on_chain(Candidate& lib, Index d, const Matrix& q,
                               const std::vector<Trajectory>& nt, const RecordLayout& layout,
                               LinkedFit& linked, const ShootingSegments& val, Matrix& val_z0,
                               const ShootingOptions& options, std::vector<Matrix>& states,
                               nlohmann::json& rec);

// The library core's map inside a library candidate (its inner map is always one).
const HamiltonianLibraryMap& library_map(const Candidate& c);

// A change of the information criterion above this is very strong evidence against the change
// (Kass and Raftery's scale: a Bayes factor beyond e^5). A change that raised it by more than
// this in a round is not tried again after another change was made (a lazy greedy search).
inline constexpr double kClearlyWorse = 10.0;
// A trial change's fit on a chain is judged after at most this many Levenberg–Marquardt steps
// (most end on their convergence rules well before); the change made is then fitted on to
// convergence. On a record of 10^5 samples a step costs about a second, and a trial that crept
// on for 100 steps cost 95 s of a fit's 350.
inline constexpr long kTrialIterations = 25;

// One way to change the library core on a chain: its name, the candidate, how many parameters
// it removes (negative: adds), and for a swap the new terms. `fixed_at_zero`: for a drop that
// is the current core with these parameters (indices into the current θ) held at 0, and
// nothing else changed; empty for any other change.
struct ChainChange {
  std::string name;
  Candidate candidate;
  Index parameters = 0;
  std::string replaced_by;
  std::vector<Index> fixed_at_zero;
};
// The force law's additions to a library core (identify_force_law.cpp), per coordinate: its
// missing powers 3 and 4 as one change, and its sin/cos pair (when the coordinate has no sinusoid
// or exponential yet), the pair's wavenumber started so that the argument spans about ±1 over
// the positions `q` (d x n, normalised units).
std::vector<ChainChange> force_law_additions(const Candidate& c, Index d, const Matrix& q);

// Greedy selection over a chain (identify_prune.cpp): every change `changes` offers is refitted
// (θ and the start states, from the current fit), and the one that lowers the information
// criterion most is made; then again, until none lowers it (a change that raised it by more
// than 10 in a round is not tried again: a lazy greedy search); nothing is changed where the fit
// is at rounding level (rounding_loss), which no criterion can judge. A drop with `fixed_at_zero`
// is first put to the Wald test at the current fit: where even a quarter of the rise of the
// loss that the Gauss–Newton model predicts would raise the criterion by more than 10, it is
// recorded with the prediction and not refitted. (A score test of the force law's additions,
// the same way, was tried and dropped: on a Duffing record from positions it predicted no fall
// for a quartic whose refit lowered the criterion by 40.) `lib`, `linked`'s start states and
// report, `val_z0` and `states` follow; each trial goes into `trials`. Returns whether anything
// changed.
bool change_while_the_criterion_falls(
    Candidate& lib, LinkedFit& linked, const ShootingSegments& val, Matrix& val_z0,
    const ShootingOptions& options, std::vector<Matrix>& states,
    const std::function<std::vector<ChainChange>(const Candidate&)>& changes,
    nlohmann::json& trials);

// The Wald test behind the screen above: the loss per residual over the chain that the
// Gauss–Newton model at the current fit (lib.theta, linked's start states) predicts once the
// parameters `fixed` (indices into lib.theta) are held at 0 and the rest, start states
// included, refitted. Empty where the model cannot tell (a dropped direction the positions do
// not fix). Throws Error on a stop request.
std::optional<double> wald_loss_of_dropping(const Candidate& lib, const LinkedFit& linked,
                                            const std::vector<Index>& fixed,
                                            const ShootingOptions& options);

// The change of the Bayesian information criterion, n log(loss) + k log n, when `dropped`
// parameters are removed and the mean squared residual goes from loss_with to loss_without
// (negative: dropping them is preferred); +inf when either loss is not a positive number.
double bic_change_of_dropping(double loss_with, double loss_without, Index n_residuals,
                              Index dropped);

// Parsimony over the linked chain (identify_prune.cpp): while dropping one of the library
// core's powers of degree 3 or 4 lowers the information criterion of the positions fit, the
// best such drop is made, θ and the start states refitted. `lib` (its θ the linked fit's),
// `linked`'s start states and report, `val_z0` and `states` follow; every trial is recorded in
// rec["terms_pruned"]. Returns whether a term was dropped; throws Error on a stop request.
bool prune_library_terms(Candidate& lib, Index d, LinkedFit& linked, const ShootingSegments& val,
                         Matrix& val_z0, const ShootingOptions& options,
                         std::vector<Matrix>& states, nlohmann::json& rec);

// Parsimony between families over the linked chain (identify_prune.cpp): while replacing a
// sin/cos or exp group of the library core by the powers of its argument (their start fitted
// to the group's potential over `q`, the training positions, d x n) lowers the information
// criterion of the linked positions fit, the best such swap is made, θ and the start states
// refitted. Judged on short segments, a cosine and a quartic differ by less than the noise
// even at 1.5 rad of swing; over the linked record the force law shows. Every trial is
// recorded in rec["polynomial_preferred"]; returns whether a group was replaced; throws Error
// on a stop request.
bool prefer_polynomials_on_chain(Candidate& lib, Index d, const Matrix& q, LinkedFit& linked,
                                 const ShootingSegments& val, Matrix& val_z0,
                                 const ShootingOptions& options, std::vector<Matrix>& states,
                                 nlohmann::json& rec);

// The dissipation of a positions record judged on the positions (identify_prune.cpp): the
// velocity start's choice judges velocities from local fits, whose errors grow with the
// amplitude (on a linear viscous chain at 0.2% noise it added drag). While dropping the
// library core's Coulomb friction or its drag (every coordinate's) lowers the information
// criterion of the linked fit, the best such drop is made, θ and the start states refitted.
// Every trial is recorded in rec["dissipation_on_positions"]; returns whether a group was
// dropped; throws Error on a stop request.
bool drop_dissipation_on_chain(Candidate& lib, Index d, LinkedFit& linked,
                               const ShootingSegments& val, Matrix& val_z0,
                               const ShootingOptions& options, std::vector<Matrix>& states,
                               nlohmann::json& rec);

// Dry friction offered on the linked chain (identify_friction_on_chain.cpp) when the core lacks
// it: Coulomb friction on every coordinate, started from three splits of the damping between γ
// and μ, is fitted over the chain; the best enters when it lowers the information criterion by
// more than 10, the held-out loss does not rise by more than its standard error (both against
// the current core fitted on as long as a trial) and its rate stands more than 3 standard
// errors clear of 0. `lib`, `linked`'s start states and report, `val_z0` and `states` follow;
// the trials go into rec["dissipation_added_on_positions"]. Returns whether it entered; throws
// Error on a stop request.
bool add_dissipation_on_chain(Candidate& lib, Index d, LinkedFit& linked,
                              const ShootingSegments& val, Matrix& val_z0,
                              const ShootingOptions& options, std::vector<Matrix>& states,
                              nlohmann::json& rec);

}  // namespace csympnet::detail
