#include "csympnet/diagnostics/diagnostics.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace csympnet {
namespace {

// M = c·R with R a rotation in the (q, p) plane: MᵀJM = c²J, so λ̂ = c² and R = |c² − λ*|·√2.
TEST(Structure, ScaledRotationHasKnownFactor) {
  const double c = 0.9, th = 0.3;
  Matrix m(2, 2);
  m << std::cos(th), std::sin(th), -std::sin(th), std::cos(th);
  m *= c;
  const StructureAt s = structure_at(m, 0.5);
  EXPECT_NEAR(s.lambda_hat, c * c, 1e-15);
  EXPECT_NEAR(s.residual, std::abs(c * c - 0.5) * std::sqrt(2.0), 1e-15);
  EXPECT_NEAR(s.self_residual, 0.0, 1e-15);
  EXPECT_NEAR(structure_at(m, 0.5, 0.5).self_residual, std::abs(c * c - 0.5) * std::sqrt(2.0),
              1e-15);
}

// A map that is not conformally symplectic has a nonzero self residual.
TEST(Structure, ShearInQIsNotConformal) {
  Matrix m = Matrix::Identity(4, 4);
  m(0, 1) = 0.7;  // q1 += 0.7 q2 alone breaks symplecticity
  EXPECT_GT(structure_at(m, 1.0).self_residual, 0.1);
}

// Exact decay map z ↦ e^{-h} z: L2 error of a map that decays at e^{-2h} is hand-computable.
TEST(Evaluate, L2ErrorIsTheRightRectangleQuadrature) {
  SystemSpec spec;  // oscillator, d = 1
  const System sys(spec);
  Trajectory traj;
  const Index n = 5;
  const double h = 0.2;
  traj.t = Vector::LinSpaced(n + 1, 0.0, h * n);
  traj.z.resize(2, n + 1);
  for (Index k = 0; k <= n; ++k)
    traj.z.col(k) = std::exp(-h * static_cast<double>(k)) * Vector::Ones(2);
  LearnedMap map;
  map.step = [](const Vector& z, double s) -> Vector { return std::exp(-2 * s) * z; };
  map.jacobian = [](const Vector&, double s) -> Matrix {
    return std::exp(-2 * s) * Matrix::Identity(2, 2);
  };
  map.gamma_hat = 4.0;  // e^{-2s}·e^{-2s} = e^{-4s}
  const Diagnostics d = evaluate(map, sys, {traj}, h);
  double sq = 0;
  for (Index k = 1; k <= n; ++k) {
    const double tk = h * static_cast<double>(k);
    sq += 2 * std::pow(std::exp(-tk) - std::exp(-2 * tk), 2) * h;
  }
  EXPECT_NEAR(d.l2_error, std::sqrt(sq), 1e-15);
  EXPECT_EQ(d.n_points, n + 1);
  EXPECT_NEAR(d.lambda_hat_mean, std::exp(-4 * h), 1e-15);
  EXPECT_NEAR(d.lambda_star, std::exp(-0.05 * h), 1e-16);
  EXPECT_NEAR(d.structure_residual_max, 0.0, 1e-15);
  EXPECT_NEAR(*d.gamma_abs_err, 4.0 - 0.05, 1e-15);
  ASSERT_EQ(d.energy_pred.size(), 1u);
  EXPECT_NEAR(d.energy_pred[0](1), sys.energy(d.rollouts[0].col(1)), 0.0);
}

}  // namespace
}  // namespace csympnet
