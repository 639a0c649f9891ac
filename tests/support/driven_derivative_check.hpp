// The derivative check of a driven map (models/inputs.hpp) shared by the library core's and the
// neural cores' tests: L = ⟨G, Φ̂(Z; U)⟩ by θ and by Z through backward(), and DΦ̂ at column 0
// through jacobian_driven(), each against central differences.
#pragma once

#include <gtest/gtest.h>

#include "csympnet/core/types.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "support/gradient_check.hpp"

namespace csympnet::testing {

// Runs the three checks (failures reported through gtest) and returns backward()'s dL/dθ, for
// the caller's own checks of it (that B's entries have a slope).
inline Vector check_driven_derivatives(const OneStepMap& map, const Vector& theta, const Matrix& z,
                                       const Vector& h, const Matrix& u, const Matrix& g,
                                       double tolerance) {
  FdOptions o;
  o.tolerance = tolerance;
  const Index n = z.cols();
  ForwardCache cache;
  map.forward_driven(theta, z, h, u, &cache);
  // Accumulated onto ones: backward() adds to grad.
  Vector grad = Vector::Ones(map.n_params());
  Matrix dz;
  map.backward(theta, cache, g, grad, &dz);
  grad.array() -= 1.0;
  const auto loss_theta = [&](const Vector& t) {
    return (g.array() * map.forward_driven(t, z, h, u, nullptr).array()).sum();
  };
  const CheckResult by_theta = compare(grad, fd_gradient(loss_theta, theta, o), o.tolerance);
  EXPECT_TRUE(by_theta.ok()) << by_theta.report("dL/dtheta");
  const auto loss_z = [&](const Vector& zf) {
    const Matrix zz = zf.reshaped(map.dim(), n);
    return (g.array() * map.forward_driven(theta, zz, h, u, nullptr).array()).sum();
  };
  const Vector zflat = z.reshaped();
  const CheckResult by_z =
      compare(Vector(dz.reshaped()), fd_gradient(loss_z, zflat, o), o.tolerance);
  EXPECT_TRUE(by_z.ok()) << by_z.report("dL/dZ");
  const Vector u0 = u.col(0);
  const auto step = [&](const Vector& z0) {
    return Vector(map.forward_driven(theta, z0, h.head(1), u0, nullptr).col(0));
  };
  const CheckResult jac = compare(map.jacobian_driven(theta, z.col(0), h(0), u0),
                                  fd_jacobian(step, z.col(0), o), o.tolerance);
  EXPECT_TRUE(jac.ok()) << jac.report("jacobian");
  return grad;
}

}  // namespace csympnet::testing
