// Random parameters, batches and steps for the model tests, plus the structure residual.
#pragma once

#include <cmath>
#include <string>

#include "csympnet/core/rng.hpp"
#include "csympnet/core/types.hpp"
#include "csympnet/data/dataset.hpp"
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

// Pairs of the damped rotation z1 = S_a R(h) S_a z0 (a = e^{−γh/2}, γ = 0.05, ω = 1), the
// exact map of a damped oscillator: z0 ~ U[−1, 1]², h ~ U[0.05, 0.15], drawn from the RNG
// stream (seed, stream).
inline PairSet damped_rotation_pairs(Index n, std::uint64_t seed, const std::string& stream) {
  Rng rng(seed, stream);
  PairSet p;
  p.z0 = rng.uniform_matrix(2, n, -1, 1);
  p.h = rng.uniform_vector(n, 0.05, 0.15);
  p.z1.resize(2, n);
  for (Index j = 0; j < n; ++j) {
    const double h = p.h(j), a = std::exp(-0.05 * h / 2);
    const double q = p.z0(0, j), v = a * p.z0(1, j);
    p.z1(0, j) = std::cos(h) * q + std::sin(h) * v;
    p.z1(1, j) = a * (-std::sin(h) * q + std::cos(h) * v);
  }
  return p;
}

}  // namespace csympnet::testing
