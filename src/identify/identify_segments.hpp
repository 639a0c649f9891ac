// Shooting segments cut from the blocks of a record, fitted with θ: shared by the positions
// route (identify_positions.cpp, the momenta hidden) and the whole-record fit of records with
// momenta (identify_states.cpp, the momenta observed with their own noise). Private to the
// library (src/identify).
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/types.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/train/shooting.hpp"
#include "identify_chain.hpp"
#include "identify_stages.hpp"

namespace csympnet::detail {

// The segments of blocks (normalised): consecutive runs of `len` samples, the last run of a
// stretch joined to the one before when shorter than len / 2. A segment never spans a gap (a
// step over kWindowGapFactor times the median step, as a rollout window's): a stretch between
// gaps is cut on its own, and a lone sample between two gaps is left out. Per segment, its
// block and the first column in that block.
struct Cut {
  ShootingSegments segs;
  Index set_aside = 0;                      // samples in stretches under kMinSegmentPositions
  std::vector<std::pair<Index, Index>> at;  // (block, first column)
  Matrix z0;                                // starts from the blocks' states
};
// The fewest positions a segment may have: 2 fix its hidden start (a position and a momentum
// per coordinate) and leave no residual; a third per coordinate is the first that tests the
// dynamics. Shorter stretches are set aside (300 trajectories of 2 positions once ended in a
// Gauss-Newton matrix that could not be factored).
inline constexpr Index kMinSegmentPositions = 3;
// A bound on the fitted start states in the fit's units, where the data have unit spread (the
// normalisation): a momentum a thousand times the data's is no motion they show.
inline constexpr double kMaxAbsState = 1e3;
// Each segment fit's Levenberg–Marquardt budget unless the user gives --lm-iterations (the
// fits end earlier on their convergence rules).
inline constexpr long kPositionsLmIterations = 100;
// The segments a segment length is judged on (segment_length): with L ≥ 10 positions of d
// rows each, the corrected loss of 1,000 segments averages at least 8,000 d residuals, a
// relative standard error of at most √(2 / 8000) = 1.6%, against the 25% the rule allows. On a
// 10⁵-sample record with momenta the lengths' start-state fits on every segment had taken 3.4
// of a fit's 21 CPU s.
inline constexpr Index kLengthSegments = 1000;

// `rows` observed per sample: d (the positions; the default) or 2d (the whole state).
Cut cut_segments(const std::vector<Trajectory>& blocks, Index d, Index len, Index rows = 0);

// Samples per period of the fastest-crossing coordinate of `positions` (d rows), from crossings
// of its mean (the whole record when it never crosses): the scale of the segments.
double samples_per_period(const std::vector<Trajectory>& positions);

// The largest growth of a perturbation of a segment's start state along its fitted rollout,
// ‖∂z_L/∂z_0‖: beyond a few orders of magnitude the start sits on an unstable manifold of the
// map, and the derivatives and the interval mean nothing.
double largest_sensitivity(const OneStepMap& map, ConstParams theta, const Cut& c);

// At most `cap` of c's segments, evenly spread over it in the order cut (all when it has no
// more), with their blocks, places and starts.
Cut evenly_spread_segments(const Cut& c, Index cap);

// The segment length: the longest of 10, 20, 40, 80 (up to two periods, `spp` samples per
// period) over which the model at θ still follows the training blocks, its start states fitted
// (`rows` observed per sample, as cut_segments); every length tried is recorded in `tried`.
// Each length is judged on at most kLengthSegments segments, evenly spread over the record.
Index segment_length(const OneStepMap& map, ConstParams theta,
                     const std::vector<Trajectory>& blocks, Index d, double spp,
                     nlohmann::json& tried, Index rows = 0);

// One candidate's segment fit: start states from several starts, then θ and the starts jointly
// (fit_shooting).
struct SegmentFit {
  Vector theta;
  Cut train, val;
  ShootingReport rep;
};
SegmentFit fit_segments(const OneStepMap& map, const Vector& theta, const Cut& train,
                        const Cut& val, const ShootingOptions& opt);

// θ's first n_free parameters are fitted; from positions alone the learned dof scales (each
// dof's momentum scale, not in the positions) are held where the velocity start put them.
Index free_parameters(const OneStepMap& map, Index d);

// γ̂'s interval (and the modes', the friction's; with the momenta observed, the Hamiltonian's
// terms' too) from the training segments' normal equations with the start states eliminated:
// the sandwich of interval(), with the degrees-of-freedom correction for the fitted start
// states and the held-out inflation (the losses of `at`: the segments' or the chain's).
GammaInterval segments_interval(const OneStepMap& map, const IntervalBasis& at, const Cut& train,
                                const BlockSplit& split, Index n_free, bool momenta_observed,
                                const IdentifyHooks& hooks);

// The training blocks' positions side by side (d x n).
Matrix training_positions(const BlockSplit& split, Index d);

// The velocity stage's terms judged on the linked record, in turn: a richer force law where
// the linking stops (a few rounds, each linking further), the sin/cos or exp groups against
// the powers of their arguments, the powers of degree 3 and 4, and (`auto_dissipation`) the
// friction and drag. `best` (its θ the linked fit's), `linked`, `val.z0` and `states` follow.
// `stage` (may be empty) is told as each of those four parts begins, by its name.
// Returns whether the core changed.
using StageNamer = std::function<void(const char* part)>;
bool judge_terms_on_chain(Candidate& best, Index d, const Matrix& q_train,
                          const std::vector<Trajectory>& nt, const RecordLayout& layout,
                          LinkedFit& linked, Cut& val, const ShootingOptions& opt,
                          std::vector<Matrix>& states, bool auto_dissipation, nlohmann::json& rec,
                          const StageNamer& stage);

}  // namespace csympnet::detail
