// A dense network sizes[0] → sizes[1] → … → sizes.back(): tanh on every hidden layer, a
// linear output layer, a bias on every layer. The building block of the baselines.
//
// Batches are column-major like everywhere else: X is sizes[0] x N.
//
// Layout of θ: for each layer l = 0, 1, … in order, W_l (sizes[l+1] x sizes[l], column-major)
// then b_l (sizes[l+1]). n_params = Σ_l (sizes[l] + 1) sizes[l+1].
// Derivations of every derivative below: docs/derivations.md, "MLP".
#pragma once

#include <vector>

#include "csympnet/core/rng.hpp"
#include "csympnet/core/types.hpp"

namespace csympnet {

// Intermediates of Mlp::forward (hidden activations), reused across calls of one batch size.
struct MlpCache {
  std::vector<Matrix> acts;
};

class Mlp {
 public:
  // At least two sizes (input and output), all >= 1; throws Error otherwise.
  explicit Mlp(std::vector<Index> sizes);

  Index n_params() const;
  Index in_dim() const;
  Index out_dim() const;
  const std::vector<Index>& sizes() const;

  // PyTorch's nn.Linear default: weights and biases ~ U(−1/√fan_in, 1/√fan_in).
  void init_params(Rng& rng, ParamsRef theta) const;

  Matrix forward(ConstParams theta, const Matrix& X, MlpCache* cache) const;
  // grad += ∂/∂θ ⟨dY, forward(X)⟩; dX (if not null) = ∂/∂X of the same.
  void backward(ConstParams theta, const MlpCache& cache, const Matrix& dY, ParamsRef grad,
                Matrix* dX) const;
  // ∂forward/∂x at one input, out_dim x in_dim.
  Matrix input_jacobian(ConstParams theta, const Vector& x) const;

  // Scalar networks (out_dim() == 1) only:
  // ∇x s at every column of X (in_dim x N).
  Matrix input_gradient(ConstParams theta, const Matrix& X) const;
  // ∇²x s at one input (in_dim x in_dim).
  Matrix input_hessian(ConstParams theta, const Vector& x) const;
  // grad += ∂/∂θ Σ_j ⟨G_j, ∇x s(X_j)⟩ (reverse mode through the forward-mode tangent pass);
  // dX (if not null) = ∂/∂X of the same, i.e. ∇²x s(X_j) G_j per column.
  void input_gradient_backward(ConstParams theta, const Matrix& X, const Matrix& G, ParamsRef grad,
                               Matrix* dX) const;

 private:
  std::vector<Index> sizes_;
  Index n_params_ = 0;
};

}  // namespace csympnet
