// Adaptive Dormand–Prince 5(4) (Boost.Odeint's runge_kutta_dopri5 with its step-size
// controller) for learned vector fields: the rollout of the vector-field baselines and the
// Jacobian of their induced time-h map.
#pragma once

#include <functional>
#include <utility>

#include "csympnet/core/types.hpp"

namespace csympnet {

struct OdeOptions {
  double rtol = 1e-7;        // relative tolerance (docs/protocol.md, "Losses and rollout")
  double atol = 1e-9;        // absolute tolerance (docs/protocol.md, "Losses and rollout")
  long max_steps = 1000000;  // accepted + rejected steps per call before giving up with Error
  void validate() const;
};

// dz/dt = f(z); f writes into its second argument (same size as z).
using VectorField = std::function<void(const Vector& z, Vector& dzdt)>;
// Df(z), n x n.
using VectorFieldJacobian = std::function<Matrix(const Vector& z)>;

// z(h) from z(0) = z0, for any h > 0. Throws Error if the solution leaves the finite numbers
// or the step budget is exhausted.
Vector dopri5_flow(const VectorField& f, const Vector& z0, double h, const OdeOptions& opt = {});

// z(h) and M(h) = ∂z(h)/∂z0 from the variational equation dM/dt = Df(z) M, M(0) = I,
// integrated together with z as one augmented state under the same controller.
std::pair<Vector, Matrix> dopri5_flow_jacobian(const VectorField& f, const VectorFieldJacobian& df,
                                               const Vector& z0, double h,
                                               const OdeOptions& opt = {});

}  // namespace csympnet
