// The one-step residuals of a map model and their exact Jacobian with respect to θ, for
// Gauss–Newton-type solvers (Levenberg–Marquardt) on the one-step loss.
//
//   r(θ) ∈ R^{N·2d},  r[j·2d + k] = (Φ̂_{h_j}(z0_j) − z1_j)_k        (sample-major)
//   L(θ) = (1/N) ‖r‖²,   J(θ) = ∂r/∂θ ∈ R^{(N·2d) × P}
//
// Row j·2d + k of J is the parameter gradient of the scalar (Φ̂_{h_j}(z0_j))_k, i.e. one
// reverse pass of OneStepMap::backward on the single sample j with upstream e_k
// (docs/identification.md, "The residual Jacobian").
#pragma once

#include <functional>

#include <Eigen/Core>

#include "csympnet/data/dataset.hpp"
#include "csympnet/models/one_step_map.hpp"

namespace csympnet {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// r(θ), sample-major, length N·2d.
Vector one_step_residuals(const OneStepMap& map, ConstParams theta, const PairSet& pairs);

// Writes J(θ) into `jac`, which must be (N·2d) × P. Row-major, so that each row is a
// contiguous gradient (and so that Ceres can use the buffer as is).
// `should_stop`, when given, is polled every 32 samples; once it returns true the remaining
// rows are left as they were, and the caller, who asked, must not use `jac`.
void residual_jacobian(const OneStepMap& map, ConstParams theta, const PairSet& pairs,
                       Eigen::Ref<RowMajorMatrix> jac,
                       const std::function<bool()>& should_stop = {});
RowMajorMatrix residual_jacobian(const OneStepMap& map, ConstParams theta, const PairSet& pairs);

}  // namespace csympnet
