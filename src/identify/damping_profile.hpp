// The damping part of a fitted map re-estimated with the core held fixed: the linearisation
// behind the model checks (identify/model_checks.hpp; docs/derivations.md, "The damping
// profile"). Private to the library; tests include it from src/.
//
// For one-step windows (z0, z1, h) and a damping matrix C acting on p, the balanced residual
// of S_C ∘ Ψ ∘ S_C is r(C) = Ψ(S_C z0) − S_C⁻¹ z1, S_C(q, p) = (q, e^{−Ch/2} p). At C = cI, with
// a = e^{−ch/2}, x = S_c z0 and J = DΨ(x):
//
//   ∂r/∂C_ij = −(h/2) (a p0_j J e_{d+i} + a⁻¹ p1_j e_{d+i}),
//   ∂r/∂c    = Σ_i ∂r/∂C_ii = −(h/2) (a J (0, p0) + a⁻¹ (0, p1)),
// and along a direction E of C, Σ_ij E_ij ∂r/∂C_ij = −(h/2) (a J (0, E p0) + a⁻¹ (0, E p1)).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "csympnet/core/types.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/train/window_loss.hpp"

namespace csympnet::detail {

// The free directions of C around cI: C = cI + Σ_m δ_m E_m. `common` holds the coefficients
// with Σ_m common_m E_m = I (the direction of a common rate). Three bases:
//  - all d² entries (E_{i·d+j} = e_i e_jᵀ);
//  - the d diagonal entries (a rate per coordinate);
//  - a rate per mode: E_k = P e_k e_kᵀ P⁻¹ for the columns of P, the momentum directions of
//    the core's linear modes (modal damping C = P diag(rates) P⁻¹; docs/derivations.md).
// The core's linear modes: angular frequencies (ascending, per unit of normalised time) and
// the momentum direction of each (columns of p).
struct LinearModes {
  Vector frequency;
  Matrix p;
  std::string where;  // "at its equilibrium" or "averaged over the data"
};
// Newton on map(z) = z from z with step h (least-norm steps), backtracking on
// ‖map(z) − z‖: the point reached and its residual ‖map(z) − z‖.
struct FixedPoint {
  Vector z;
  double residual = 0.0;
};
FixedPoint nearest_fixed_point(const OneStepMap& map, const Vector& theta, Vector z, double h);
// Its point when the residual is at rounding (≤ 1e-8 (1 + ‖z‖)); empty otherwise.
std::optional<Vector> map_fixed_point(const OneStepMap& map, const Vector& theta, Vector z,
                                      double h);

// The modes of a linear map with d conjugate pairs of eigenvalues near the unit circle, at
// distinct angles ωh, whose eigenvectors' p parts are real directions (a natural mechanical
// system's); empty otherwise.
std::optional<LinearModes> modes_of_linear_map(const Matrix& jac, double h);

struct DampingBasis {
  std::string name;
  std::vector<Matrix> e;
  Vector common;
  Index size() const { return static_cast<Index>(e.size()); }
  // cI + Σ δ_m E_m.
  Matrix matrix(double c, const Vector& delta) const;
};
DampingBasis full_damping_basis(Index d);
DampingBasis coordinate_damping_basis(Index d);
// The modal basis of the columns of P (d × d, invertible).
DampingBasis modal_damping_basis(const Matrix& p);

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
  // Per-block sums at C = cI; with `basis`, also the normal equations of its coefficients.
  // `should_stop` is polled every 64 windows; on true the sums stop (incomplete).
  std::vector<BlockProfile> blocks(double c, const DampingBasis* basis,
                                   const std::function<bool()>& should_stop = {}) const;
  // The columns ∂r_k/∂δ_m (2d × basis.size()) of window k at C = cI (exposed for the
  // derivative test).
  Matrix entry_jacobian(double c, Index k, const DampingBasis& basis) const;
  // The core's linear modes: Ψ is linearised at its fixed point nearest the data (Newton from
  // the data's mean state), or, where that has no d oscillating modes, its Jacobian is
  // averaged over the observed states; each conjugate pair of eigenvalues e^{±iωh} gives the
  // real direction of its eigenvector's p part. Empty where neither is well defined (a
  // hyperbolic or degenerate linearisation, an ill-conditioned set of directions).
  std::optional<LinearModes> linear_modes() const;
  // ∂r_k/∂c.
  Vector rate_jacobian(double c, Index k) const;

  Index dofs() const { return d_; }
  Index n_blocks() const { return n_blocks_; }
  const WindowSet& windows() const { return w_; }

 private:
  // ∂Ψ/∂p at x (the core, one step of h) times dirs (d × k): 2d × k. Forward-mode tangents
  // where the map has them (k passes' worth of one step), else its Jacobian's p columns.
  Matrix momentum_jacobian_times(const Vector& x, double h, const Matrix& dirs) const;

  const OneStepMap* map_;
  Vector core_theta_;
  WindowSet w_;
  Index d_;
  Index n_blocks_ = 0;
};

}  // namespace csympnet::detail
