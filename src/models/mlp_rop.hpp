// Internal to src/models: the reverse-over-forward pass of a scalar Mlp in its general form,
// shared by Mlp::input_gradient_backward, Mlp::input_hessian and the H-based vector fields.
#pragma once

#include "mlp.hpp"

namespace csympnet::detail {

// For a scalar network s and L = Σ_j ⟨G_j, ∇x s(X_j)⟩ (docs/derivations.md, "MLP: R-op"):
//   grad  (if not null, n_params entries) += ∂L/∂θ;
//   dX    (if not null) = ∂L/∂X = ∇²s(X_j) G_j per column;
//   input_grad (if not null) = ∇x s(X_j) per column, a by-product of the same sweep (the
//   adjoint of the tangent input), which saves the H-based fields a separate gradient pass.
void scalar_mlp_rop(const Mlp& mlp, ConstParams theta, const Matrix& X, const Matrix& G,
                    double* grad, Matrix* dX, Matrix* input_grad);

}  // namespace csympnet::detail
