// Multiple shooting on observed positions: the loss of `csympnet fit` when a record has
// positions and no momenta (docs/derivations.md, "Positions only: the momenta as hidden
// states").
//
// A segment s is L_s consecutive observed positions q_{s,0}, …, q_{s,L−1} (d × L) after steps
// h_{s,0}, …, h_{s,L−2}. Its start state z_s = (q, p) is unknown, fitted with θ. The map rolls
// it out, z_{s,k+1} = Φ̂_{h_{s,k}}(z_{s,k}), and the residuals are the positions alone:
//
//   r_{s,k} = P_q z_{s,k} − q_{s,k},   k = 0 … L_s − 1   (P_q: the q rows).
//
// The loss is L = (1/n) Σ ‖r‖², n the number of residuals. Every observed position enters
// once, as a residual; nothing observed is treated as exact, so noise on q causes no
// errors-in-variables bias.
//
// The unknowns of each segment enter only its own residuals, so Gauss–Newton's normal
// equations are eliminated segment by segment (a Schur complement, as in bundle adjustment):
// with A_s = ∂r_s/∂θ, B_s = ∂r_s/∂z_s, U_s = B_sᵀB_s and W_s = A_sᵀB_s,
//
//   (Σ_s A_sᵀA_s − W_s U_s⁻¹ W_sᵀ) δθ = −Σ_s (A_sᵀr_s − W_s U_s⁻¹ B_sᵀr_s),
//   δz_s = −U_s⁻¹ (B_sᵀr_s + W_sᵀ δθ).
//
// A_s comes from the forward sensitivity S_{k+1} = DΦ̂(z_k) S_k + ∂Φ̂/∂θ(z_k) (S_0 = 0), B_s
// from T_{k+1} = DΦ̂(z_k) T_k (T_0 = I): one reverse pass per component of each step, not per
// residual.
#pragma once

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "csympnet/core/types.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/train/window_loss.hpp"

namespace csympnet {

struct ShootingSegments {
  Index d = 0;
  std::vector<Matrix> q;     // per segment, d × L observed positions (L ≥ 2), or 2d × L states
  std::vector<Vector> h;     // per segment, the L − 1 steps
  std::vector<Index> block;  // per segment, its resampling block (0 … B − 1)
  // Optional (empty: every position observed): per segment, L weights, 1 where the position
  // enters the loss and 0 where the rollout only passes through it (a held-out stretch inside a
  // linked chain: the map carries the state across it, its positions are not fitted).
  std::vector<Vector> observed;
  // Optional (empty: the segment's `block`): per segment, each position's resampling block, for
  // a segment that spans several blocks (a chain of the whole record).
  std::vector<std::vector<Index>> column_block;
  // Optional (empty: a free map): per segment, the known inputs of each step, 2m × (L − 1) (per
  // step the input at its start, then at its end: models/inputs.hpp), for a driven map.
  std::vector<Matrix> u;
  // Optional (empty: all 1): one weight per observed row, multiplying its residuals. With the
  // momenta observed (q holding 2d rows, the whole state), the momenta's rows are weighted
  // against the positions' by the ratio of their noise levels (an errors-in-variables fit).
  Vector row_weight;
  // The rows observed per position: d (positions; the residuals above) or 2d (the whole state,
  // positions and momenta: r = z − y).
  Index observed_rows() const;
  // Segment s's inputs, or an empty matrix (no inputs).
  const Matrix& inputs(Index s) const;
  Index size() const { return static_cast<Index>(q.size()); }
  Index n_residuals() const;  // observed rows × the observed positions: what the loss averages
  Index n_rows()
      const;  // Σ_s L_s × observed rows: the residual vector's length, unobserved ones too
  double weight(Index s, Index k) const {
    return observed.empty() ? 1.0 : observed[static_cast<std::size_t>(s)](k);
  }
  Index block_of(Index s, Index k) const {
    return column_block.empty()
               ? block[static_cast<std::size_t>(s)]
               : column_block[static_cast<std::size_t>(s)][static_cast<std::size_t>(k)];
  }
  // Throws Error (prefixed by `where`) on inconsistent shapes, fewer than 2 positions in a
  // segment, steps ≤ 0 or non-finite values.
  void validate(const std::string& where = "segments") const;
};

// The states along segment s from start state z0: 2d × L, driven by u (2m × (L − 1); empty: the
// free map).
Matrix shooting_states(const OneStepMap& map, ConstParams theta, const Vector& z0, const Vector& h,
                       const Matrix& u = Matrix());

// The residuals of every segment (sample-major: segment by segment, d per position), unscaled;
// an unobserved position's are 0 (length n_rows()).
Vector shooting_residuals(const OneStepMap& map, ConstParams theta, const Matrix& z0,
                          const ShootingSegments& segs);

// The loss (1/n) Σ ‖r‖² over the segments.
double shooting_loss(const OneStepMap& map, ConstParams theta, const Matrix& z0,
                     const ShootingSegments& segs);

// One segment's residuals r (L·o, o = q's rows: d positions or 2d states), A = ∂r/∂θ
// restricted to θ's first n_free parameters (L·o × n_free, row-major) and B = ∂r/∂z0
// (L·o × 2d); each position's rows multiplied by its weight w (L; empty: all 1), so an
// unobserved position's rows are 0, and each observed row by its row weight rw (o; empty: 1).
void shooting_segment_jacobian(const OneStepMap& map, ConstParams theta, const Vector& z0,
                               const Matrix& q, const Vector& h, Index n_free, RowMajorMatrix& a,
                               Matrix& b, Vector& r, const Vector& w = Vector(),
                               const Matrix& u = Matrix(), const Vector& rw = Vector());

// The normal equations with the start states eliminated, at (θ, z0), over θ's first n_free
// parameters, all scaled by `scale` (as window_normal_equations): a = the reduced JᵀJ (lower
// triangle), g = the reduced Jᵀr, cost = ½ scale² ‖r‖², and per block the efficient score
// Σ_{s ∈ b} (A_sᵀr_s − W_s U_s⁻¹ B_sᵀr_s). `should_stop` is polled per segment.
NormalEquations shooting_normal_equations(const OneStepMap& map, ConstParams theta,
                                          const Matrix& z0, const ShootingSegments& segs,
                                          Index n_free, double scale, bool with_scores,
                                          const std::function<bool()>& should_stop = {});

// `segs` with each block's positions cut, in record order, into runs of `run` positions (the
// last run of a block may be shorter), each run a resampling block of its own (column_block),
// numbered 0 … B' − 1 in order of first appearance; a run never spans two blocks. Segments
// must list each block's positions in record order (as cut from a record).
ShootingSegments split_blocks_into_runs(const ShootingSegments& segs, Index run);

// The same normal equations with, per block, the information on θ that its rows add to the
// rest of the record (`block_information`: Ã − Ã_(−b), Ã_(−b) the reduced matrix without the
// block's rows, each segment they touch keeping its other rows and its start state). The
// intervals read from it how many blocks they rest on (gamma_sandwich.hpp). Beyond
// kBlockInformationMaxNumbers (blocks × n_free²) it is left empty.
inline constexpr double kBlockInformationMaxNumbers = 4e6;
NormalEquations shooting_block_equations(const OneStepMap& map, ConstParams theta, const Matrix& z0,
                                         const ShootingSegments& segs, Index n_free, double scale,
                                         const std::function<bool()>& should_stop = {});

// The start states alone fitted, θ fixed: Levenberg–Marquardt per segment on its 2d unknowns
// (held-out segments, the start of the joint fit, a rollout from observed positions).
// several_starts: each segment is also fitted from its first position with p = 0 and with the
// p that carries it to the second position in one step, and the lowest fit kept (a start far
// from the motion, or in another basin, is then not final); a start equal to the given one, as
// a cut's first observed state is, is not fitted twice. Returns the loss after.
// max_abs: a bound on every component of a start state (a trial step beyond it is refused): in
// a direction the positions do not fix (a saturated core), the fit would otherwise run off.
// tolerance: a segment's fit ends after an accepted step that lowers its ‖r‖² by at most this
// fraction of itself (the default, to rounding; kScoringTolerance where only the loss is used),
// or when a trial fails with ‖r‖² below kRoundingShare of the weighted positions' own sum of
// squares.
double fit_start_states(const OneStepMap& map, ConstParams theta, const ShootingSegments& segs,
                        Matrix& z0, long iterations = 30, bool several_starts = false,
                        double max_abs = std::numeric_limits<double>::infinity(),
                        double tolerance = 1e-14);

// fit_start_states' tolerance where the loss only scores θ (held-out segments, a comparison of
// segment lengths): that loss is compared at the level of its standard error, loss · √(2/n),
// above 1e-3 of itself for up to 10⁶ residuals, so a start state converged further than 1e-8
// of ‖r‖² only repeats rollouts.
inline constexpr double kScoringTolerance = 1e-8;

// A weighted residual sum of squares below this share of the weighted observations' own sum of
// squares is at rounding level: the model reproduces them to 1e-10 of their size, where double's
// rounding, accumulated over a segment's steps, is what is left. There a Levenberg–Marquardt
// trial that fails is taken as the end (fit_start_states, fit_shooting): λ would otherwise
// climb through a dozen more rollouts that fail alike. Steps that still lower the loss go on
// to the floor. Noisy or quantised records stay far above it (noise of 1e-9 of the motion is a
// share of 1e-18).
inline constexpr double kRoundingShare = 1e-20;
// The loss per residual at that level for these segments: kRoundingShare of their weighted
// observations' own mean square. A fit's loss at or below it cannot tell two models apart.
double rounding_loss(const ShootingSegments& segs);

struct ShootingOptions {
  long iterations = 100;  // trial steps at most
  long patience = 20;     // trial steps without a better validation loss
  Index n_free = -1;      // θ's first n_free parameters are fitted (−1: all)
  // A bound on every component of a start state (fit_start_states' max_abs).
  double max_abs_state = std::numeric_limits<double>::infinity();
  // Polled before every iteration and per segment inside one: true stops with the best iterate.
  std::function<bool()> should_stop;
  // After every accepted step: iteration, training loss, validation loss.
  std::function<void(long, double, double)> on_accepted;
  // Convergence in the data's own units: a step that lowers the training loss by less than
  // this many units of χ² (n · Δloss / loss, n the residuals) counts as small, and three small
  // steps in a row end the fit. 1e-3 moves θ by about 0.03 of its standard error per step; the
  // default 0 keeps only the rule below (a change under 1e-10 of the loss itself).
  double converged_chi2 = 0.0;
  // Convergence of the one parameter asked about (the damping rate's): three accepted steps in
  // a row, each near Gauss–Newton's (λ ≤ 1e-2), lowering χ² by less than 1 and moving
  // θ[watch_index] by less than converged_se of its standard error (the Gauss–Newton one,
  // σ̂² [A⁻¹], the start states eliminated), end the fit. A fit that creeps along a direction
  // the positions barely fix then ends once γ has stopped moving; −1: not used.
  //
  // Both rules are also decided from one prediction, before a trial: where the fall of χ² that
  // the Gauss–Newton step is predicted to give is at most converged_se² (it then moves every
  // parameter by at most converged_se of its standard error), at most converged_chi2, or under
  // 1e-10 of the loss (its rounding level), the fit ends without the trial.
  Index watch_index = -1;
  double converged_se = 0.0;
};

struct ShootingReport {
  long iterations = 0;
  long accepted = 0;
  long best_iteration = 0;
  double initial_loss = 0.0, final_loss = 0.0;  // training, at the start and at the best iterate
  double val_loss = 0.0;                        // at the best iterate
  bool stopped = false;
  bool watch_converged = false;  // ended by ShootingOptions::watch_index's rule
  double watch_se = 0.0;         // that parameter's standard error at the last step (0: none)
  std::string message;
};

// θ and the training segments' start states fitted jointly by Levenberg–Marquardt with the
// start states eliminated; after each accepted step the held-out segments' start states are
// refitted (θ fixed). Kept: the latest iterate whose held-out loss is within one standard error
// (the loss times √(2/n)) of the lowest (val_z0 updated with it).
ShootingReport fit_shooting(const OneStepMap& map, Vector& theta, Matrix& z0,
                            const ShootingSegments& train, Matrix& val_z0,
                            const ShootingSegments& val, const ShootingOptions& options);

}  // namespace csympnet

namespace csympnet {

// The state at the last of a window of observed positions q (d × L, L ≥ 2) at times t: the
// window's start state fitted with θ fixed (as a held-out segment's), rolled out to t[L−1].
// For a prediction or a rollout from positions alone (fit_start_states with several starts
// from p = 0). `rms` receives the
// root-mean-square position residual of that fit. u: the window's inputs (2m × (L − 1), per
// step start and end; empty: none). `residuals` receives the fitted motion's positions less q
// (d × L).
Vector state_from_positions(const OneStepMap& map, ConstParams theta, const Matrix& q,
                            const Vector& t, double* rms = nullptr, const Matrix& u = Matrix(),
                            Matrix* residuals = nullptr);

}  // namespace csympnet
