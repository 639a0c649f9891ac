// The damping part of a fitted map re-estimated with the core held fixed: the linearisation
// behind the model checks (experiments/model_checks.hpp; docs/derivations.md, "The damping
// profile"). Private to the library; tests include it from src/.
//
// For one-step windows (z0, z1, h) and a damping matrix C acting on p, the balanced residual
// of S_C ∘ Ψ ∘ S_C is r(C) = Ψ(S_C z0) − S_C⁻¹ z1, S_C(q, p) = (q, e^{−Ch/2} p). At C = cI, with
// a = e^{−ch/2}, x = S_c z0 and J = DΨ(x):
//
//   ∂r/∂C_ij = −(h/2) (a p0_j J e_{d+i} + a⁻¹ p1_j e_{d+i}),
//   ∂r/∂c    = Σ_i ∂r/∂C_ii = −(h/2) (a J (0, p0) + a⁻¹ (0, p1)).
#pragma once

#include <functional>
#include <vector>

#include "csympnet/core/types.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/train/window_loss.hpp"

namespace csympnet::detail {

// The free parameters of C: all d² entries (vec(C), row-major: index i·d + j), or the d
// diagonal entries (rates per coordinate) where d² would be too many for the blocks.
enum class DampingFreedom { kFull, kDiagonal };

// Sums over the one-step windows of one block.
struct BlockProfile {
  Index samples = 0;
  double energy = 0.0;  // mean ‖z0‖² (normalised units): the block's energy scale
  double motion = 0.0;  // Σ ‖z1 − z0‖²
  double rss = 0.0;     // Σ ‖r‖²
  double a = 0.0;       // Σ ‖∂r/∂c‖²
  double g = 0.0;       // Σ (∂r/∂c)ᵀ r
  Matrix big_a;         // Σ GᵀG over the entries of C (when asked for)
  Vector big_g;         // Σ Gᵀ r
  double lag0 = 0.0;    // Σ ‖r_k‖² over windows with a successor two steps on
  double lag1 = 0.0;    // Σ r_kᵀ r_{k+1} (consecutive windows of the block)
  double lag2 = 0.0;    // Σ r_kᵀ r_{k+2}
  Index lag1_pairs = 0;
  Index lag2_pairs = 0;
};

class DampingProfile {
 public:
  // `map` at `theta` with its β (theta(damping_index)) set to 0 is the core Ψ. Windows: one
  // step, blocks numbered 0 … B − 1 in w.block, consecutive windows of a block consecutive in w.
  DampingProfile(const OneStepMap& map, const Vector& theta, Index damping_index,
                 WindowSet windows);

  // The balanced residuals at C = cI (2d × N).
  Matrix residuals(double c) const;
  // Per-block sums at C = cI; with `freedom`, also the normal equations of the entries of C.
  // `should_stop` is polled every 64 windows; on true the sums stop (incomplete).
  std::vector<BlockProfile> blocks(double c, const DampingFreedom* freedom,
                                   const std::function<bool()>& should_stop = {}) const;
  // The columns ∂r_k/∂C (2d × n_c) of window k at C = cI (exposed for the derivative test).
  Matrix entry_jacobian(double c, Index k, DampingFreedom freedom) const;
  // ∂r_k/∂c.
  Vector rate_jacobian(double c, Index k) const;

  Index dofs() const { return d_; }
  Index n_blocks() const { return n_blocks_; }
  const WindowSet& windows() const { return w_; }

 private:
  const OneStepMap* map_;
  Vector core_theta_;
  WindowSet w_;
  Index d_;
  Index n_blocks_ = 0;
};

// Number of free entries of C under `freedom` for d degrees of freedom.
Index damping_entries(Index d, DampingFreedom freedom);
// vec(I) in the entries' coordinates: the direction of a common rate.
Vector common_rate_direction(Index d, DampingFreedom freedom);
// C = cI + the entries `delta`, as a d × d matrix.
Matrix damping_matrix(double c, const Vector& delta, Index d, DampingFreedom freedom);

}  // namespace csympnet::detail
