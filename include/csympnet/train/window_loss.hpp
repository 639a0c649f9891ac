// The identification loss of `csympnet fit`: windows of m consecutive steps along a
// trajectory, with balanced residuals (docs/derivations.md, "Balanced residuals" and
// "Windows"; docs/identification.md measures both against the plain one-step loss).
//
// A window i starts at an observed state z0_i and ends m steps later at the observed zm_i,
// after steps h_{0,i}, …, h_{m−1,i} (any sizes, total H_i). Its residual is
//
//   r_i = W_i (Φ̂_{h_{m−1,i}} ∘ … ∘ Φ̂_{h_{0,i}}(z0_i) − zm_i),
//   W_i = diag(1 on the q rows, w_i on the p rows),  w_i = e^{γ̂ H_i / 2}  ("balanced"),
//
// and W_i = I when balancing is off or the map has no damping rate. The loss is
// L(θ) = (1/N) Σ_i ‖r_i‖². With m = 1 and no balancing it is the paper's one-step loss.
//
// Why balanced: for one step of CSympNet-ID, W_i r_i = S_a⁻¹(Φ̂(z0) − z1) = Ψ(S_a z0) − S_a⁻¹ z1,
// the mismatch in the middle of the map, where noise on z0 and on z1 pulls γ̂ equally in
// opposite directions. The plain one-step loss treats z0 as exact, and noise on it biases γ̂
// upwards (errors in variables); windows divide what remains by about m.
#pragma once

#include <functional>

#include <vector>

#include "csympnet/core/types.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/train/residual_jacobian.hpp"

namespace csympnet {

struct WindowSet {
  Index m = 1;               // steps per window
  Matrix z0;                 // 2d × N observed start states
  Matrix zm;                 // 2d × N observed end states, m steps later
  Matrix h;                  // m × N: row k holds step k of every window
  std::vector<Index> block;  // resampling block of each window (a trajectory or a segment)
  Index size() const { return z0.cols(); }
  Index dim() const { return z0.rows(); }
  // Total time H_i of each window.
  Vector span() const { return h.colwise().sum().transpose(); }
  // Throws Error (prefixed by `where`) on inconsistent shapes, steps ≤ 0 or non-finite values.
  void validate(const std::string& where = "windows") const;
};

// All windows of m steps inside each trajectory (every start with m steps after it), in
// trajectory order; window blocks are `block_of[k]` for trajectory k (empty: k itself).
// Trajectories shorter than m steps give none; throws Error if none gives any.
WindowSet windows_from_trajectories(const std::vector<Trajectory>& trajs, Index m,
                                    const std::vector<Index>& block_of = {});
// One-step windows from pairs; blocks `block` (empty: every pair its own block).
WindowSet windows_from_pairs(const PairSet& pairs, const std::vector<Index>& block = {});
// The windows `idx`, in that order.
WindowSet select_windows(const WindowSet& w, const std::vector<Index>& idx);

// L(θ); when grad is not null it is overwritten with dL/dθ. `caches` (m of them, resized here)
// may be kept across calls so that a training loop does not reallocate every epoch.
double window_loss(const OneStepMap& map, ConstParams theta, const WindowSet& w, bool balanced,
                   Vector* grad = nullptr, std::vector<ForwardCache>* caches = nullptr);
// The share of a loss over `total` windows that the windows w contribute,
// (1/total) Σ_{i ∈ w} ‖r_i‖², and its gradient: the shares of the chunks of a partition of the
// windows sum to L (chunk_tree.hpp). window_loss(w) is window_loss_part(w, w.size()).
double window_loss_part(const OneStepMap& map, ConstParams theta, const WindowSet& w, bool balanced,
                        Index total, Vector* grad = nullptr,
                        std::vector<ForwardCache>* caches = nullptr);

// The residuals r (sample-major, N·2d, not divided by √N).
Vector window_residuals(const OneStepMap& map, ConstParams theta, const WindowSet& w,
                        bool balanced);

// Rows i·2d … i·2d + 2d − 1 of J = ∂r/∂θ for the windows `first` … `first + count − 1`,
// into jac (count·2d × P, row-major), and their residuals into r (count·2d). One forward
// pass of the window alone, then one reverse pass through its m steps per component.
void window_jacobian_rows(const OneStepMap& map, ConstParams theta, const WindowSet& w,
                          bool balanced, Index first, Index count, Eigen::Ref<RowMajorMatrix> jac,
                          Eigen::Ref<Vector> r);

// What Gauss–Newton and the interval need, accumulated over chunks of windows so that J is
// never held whole: A = JᵀJ (lower triangle), g = Jᵀr, cost ½‖r‖², and, per block b, the
// score s_b = Σ_{i ∈ b} J_iᵀ r_i (columns of `scores`, blocks numbered as in w.block, which
// must then be 0 … B − 1). All with r and J scaled by `scale` (1/√N makes ½‖r‖² = L/2).
// `should_stop`, when given, is polled before each chunk (a few ms to a second of work): on
// true the sums stop there, incomplete, with `stopped` set.
struct NormalEquations {
  Matrix a;  // P × P, lower triangle
  Vector g;  // P
  double cost = 0.0;
  Matrix scores;  // P × B when asked for, else empty
  bool stopped = false;
  // Per block, the information on the parameters its rows add to the rest (P × P each), when
  // computed (shooting_block_equations); the intervals' degrees of freedom come from it.
  std::vector<Matrix> block_information;
};
// One Gauss–Newton step from these normal equations, −(A + μD)⁻¹ g with D = diag A and μ a
// ridge at 1e-9 (raised a hundredfold while A + μD cannot be factored); zero when it never can.
Vector gauss_newton_step(const NormalEquations& ne);
// θ moved by the Gauss–Newton step constrained to put the parameters `zeroed` at 0: the
// quadratic model ½ δᵀAδ + gᵀδ minimised with δ_D = −θ_D (D = zeroed) gives
// δ_K = −A_KK⁻¹ (g_K + A_KD δ_D) on the rest (A_KK with the same 1e-9 ridge). Empty when
// nothing is zeroed, nothing is left, or A_KK cannot be factored.
Vector gauss_newton_with_zeros(const NormalEquations& ne, const Vector& theta,
                               const std::vector<Index>& zeroed);

NormalEquations window_normal_equations(const OneStepMap& map, ConstParams theta,
                                        const WindowSet& w, bool balanced, double scale,
                                        bool with_scores = false,
                                        const std::function<bool()>& should_stop = {});

}  // namespace csympnet
