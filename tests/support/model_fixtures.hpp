// Random parameters, batches and steps for the model tests, plus the structure residual.
#pragma once

#include "csympnet/core/rng.hpp"
#include "csympnet/core/types.hpp"
#include "csympnet/models/one_step_map.hpp"

namespace csympnet::testing {

// θ ~ N(0, stddev²) entrywise; for models with a damping parameter, β is set to `beta`.
inline Vector random_theta(const OneStepMap& model, Rng& rng, double stddev, double beta = 0.3) {
  Vector theta = rng.normal_matrix(model.n_params(), 1, stddev);
  if (const auto index = model.damping_param_index()) theta(*index) = beta;
  return theta;
}

// Per-sample steps h_j ~ U[0.05, 0.2].
inline Vector random_steps(Index n, Rng& rng) {
  return rng.uniform_vector(n, 0.05, 0.2);
}

// ‖Dᵀ J D − λ J‖_F: 0 for an exactly conformal symplectic Jacobian with factor λ.
inline double conformal_residual(const Matrix& jac, double lambda) {
  const Matrix j = canonical_j(jac.rows() / 2);
  return (jac.transpose() * j * jac - lambda * j).norm();
}

}  // namespace csympnet::testing
