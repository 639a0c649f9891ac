// Mlp's five derivative paths against finite differences (tests/support/gradient_check), at
// parameters scaled to 3x the PyTorch init so that the tanh layers are well inside their
// nonlinear range.
#include <gtest/gtest.h>

#include <vector>

#include "../src/models/mlp.hpp"
#include "csympnet/core/error.hpp"
#include "support/gradient_check.hpp"

namespace csympnet::testing {
namespace {

using Sizes = std::vector<Index>;

Vector scaled_init(const Mlp& mlp, Rng& rng, double scale = 3.0) {
  Vector theta(mlp.n_params());
  mlp.init_params(rng, theta);
  return scale * theta;
}

class MlpTest : public ::testing::TestWithParam<Sizes> {};

TEST_P(MlpTest, BackwardMatchesFiniteDifferences) {
  const Mlp mlp(GetParam());
  Rng rng(11, "mlp-backward");
  const Vector theta = scaled_init(mlp, rng);
  const Matrix x = rng.normal_matrix(mlp.in_dim(), 4, 1.0);
  const Matrix dy = rng.normal_matrix(mlp.out_dim(), 4, 1.0);
  MlpCache cache;
  mlp.forward(theta, x, &cache);
  Vector grad = Vector::Ones(mlp.n_params());  // backward must accumulate
  Matrix dx;
  mlp.backward(theta, cache, dy, grad, &dx);
  grad.array() -= 1.0;
  const auto loss = [&](const Vector& th, const Matrix& xx) {
    return (dy.array() * mlp.forward(th, xx, nullptr).array()).sum();
  };
  const CheckResult d_theta =
      compare(grad, fd_gradient([&](const Vector& th) { return loss(th, x); }, theta), 1e-6);
  EXPECT_TRUE(d_theta.ok()) << d_theta.report("dtheta");
  const CheckResult d_x = compare(
      dx.reshaped(),
      fd_gradient([&](const Vector& xf) { return loss(theta, xf.reshaped(x.rows(), x.cols())); },
                  x.reshaped()),
      1e-6);
  EXPECT_TRUE(d_x.ok()) << d_x.report("dX");
}

TEST_P(MlpTest, InputJacobianMatchesFiniteDifferences) {
  const Mlp mlp(GetParam());
  Rng rng(12, "mlp-jacobian");
  const Vector theta = scaled_init(mlp, rng);
  const Vector x = rng.normal_matrix(mlp.in_dim(), 1, 1.0);
  const CheckResult r =
      check_jacobian([&](const Vector& xx) -> Vector { return mlp.forward(theta, xx, nullptr); },
                     [&](const Vector& xx) { return mlp.input_jacobian(theta, xx); }, x);
  EXPECT_TRUE(r.ok()) << r.report("input_jacobian");
}

INSTANTIATE_TEST_SUITE_P(Sizes, MlpTest,
                         ::testing::Values(Sizes{3, 5, 4, 2}, Sizes{2, 6, 6, 1}, Sizes{4, 1},
                                           Sizes{3, 7, 3}, Sizes{5, 4, 6, 3, 5}));

class ScalarMlpTest : public ::testing::TestWithParam<Sizes> {};

TEST_P(ScalarMlpTest, InputGradientMatchesFiniteDifferencesOfTheScalar) {
  const Mlp mlp(GetParam());
  Rng rng(21, "mlp-gradient");
  const Vector theta = scaled_init(mlp, rng);
  const Matrix x = rng.normal_matrix(mlp.in_dim(), 3, 1.0);
  // ∂/∂X Σ_j s(X_j) has column j = ∇s(X_j).
  const auto total = [&](const Vector& xf) {
    return mlp.forward(theta, xf.reshaped(x.rows(), x.cols()), nullptr).sum();
  };
  const CheckResult r =
      compare(mlp.input_gradient(theta, x).reshaped(), fd_gradient(total, x.reshaped()), 1e-6);
  EXPECT_TRUE(r.ok()) << r.report("input_gradient");
  // The batched gradient agrees with the one-column input Jacobian.
  const Matrix jac = mlp.input_jacobian(theta, x.col(1));
  EXPECT_LE((mlp.input_gradient(theta, x).col(1) - jac.transpose()).norm(), 1e-13);
}

TEST_P(ScalarMlpTest, InputHessianMatchesFiniteDifferencesOfTheGradient) {
  const Mlp mlp(GetParam());
  Rng rng(22, "mlp-hessian");
  const Vector theta = scaled_init(mlp, rng);
  const Vector x = rng.normal_matrix(mlp.in_dim(), 1, 1.0);
  const CheckResult r =
      check_jacobian([&](const Vector& xx) -> Vector { return mlp.input_gradient(theta, xx); },
                     [&](const Vector& xx) { return mlp.input_hessian(theta, xx); }, x);
  EXPECT_TRUE(r.ok()) << r.report("input_hessian");
  const Matrix hess = mlp.input_hessian(theta, x);
  EXPECT_LE((hess - hess.transpose()).norm(), 1e-13 * (1.0 + hess.norm()));
}

// Two independent code paths: the closed-form Hessian and the R-op sweep, which returns
// ∇²s(x) g through input_gradient_backward.
TEST_P(ScalarMlpTest, InputHessianAgreesWithTheRopSweep) {
  const Mlp mlp(GetParam());
  Rng rng(23, "mlp-hessian-rop");
  for (int trial = 0; trial < 5; ++trial) {
    const Vector theta = scaled_init(mlp, rng);
    const Vector x = rng.normal_matrix(mlp.in_dim(), 1, 1.0);
    const Vector g = rng.normal_matrix(mlp.in_dim(), 1, 1.0);
    Vector grad = Vector::Zero(mlp.n_params());
    Matrix hg;
    mlp.input_gradient_backward(theta, x, g, grad, &hg);
    const Vector expected = mlp.input_hessian(theta, x) * g;
    EXPECT_LE((hg.col(0) - expected).norm(), 1e-12 * (1.0 + expected.norm())) << "trial " << trial;
  }
}

// L(θ, X) = Σ_j ⟨G_j, ∇s(X_j)⟩, differentiated by input_gradient_backward (the R-op).
struct RopCase {
  Vector analytic_theta;
  Vector fd_theta;
  Vector analytic_x;
  Vector fd_x;
};

RopCase rop_case(const Mlp& mlp, Rng& rng) {
  const Vector theta = scaled_init(mlp, rng);
  const Matrix x = rng.normal_matrix(mlp.in_dim(), 4, 1.0);
  const Matrix g = rng.normal_matrix(mlp.in_dim(), 4, 1.0);
  const auto loss = [&](const Vector& th, const Matrix& xx) {
    return (g.array() * mlp.input_gradient(th, xx).array()).sum();
  };
  RopCase c;
  c.analytic_theta = Vector::Ones(mlp.n_params());
  Matrix dx;
  mlp.input_gradient_backward(theta, x, g, c.analytic_theta, &dx);
  c.analytic_theta.array() -= 1.0;
  c.analytic_x = dx.reshaped();
  c.fd_theta = fd_gradient([&](const Vector& th) { return loss(th, x); }, theta);
  c.fd_x = fd_gradient(
      [&](const Vector& xf) { return loss(theta, xf.reshaped(x.rows(), x.cols())); }, x.reshaped());
  return c;
}

TEST_P(ScalarMlpTest, InputGradientBackwardMatchesFiniteDifferences) {
  const Mlp mlp(GetParam());
  Rng rng(23, "mlp-rop");
  const RopCase c = rop_case(mlp, rng);
  const CheckResult d_theta = compare(c.analytic_theta, c.fd_theta, 1e-6);
  EXPECT_TRUE(d_theta.ok()) << d_theta.report("R-op dtheta");
  const CheckResult d_x = compare(c.analytic_x, c.fd_x, 1e-6);
  EXPECT_TRUE(d_x.ok()) << d_x.report("R-op dX");
}

INSTANTIATE_TEST_SUITE_P(Sizes, ScalarMlpTest,
                         ::testing::Values(Sizes{2, 6, 6, 1}, Sizes{1, 4, 1}, Sizes{3, 1},
                                           Sizes{20, 16, 16, 1}, Sizes{4, 5, 3, 6, 1}));

TEST(MlpRop, PlantedWrongEntryIsRejected) {
  const Mlp mlp({2, 6, 6, 1});
  Rng rng(31, "mlp-planted");
  RopCase c = rop_case(mlp, rng);
  ASSERT_TRUE(compare(c.analytic_theta, c.fd_theta, 1e-6).ok());
  // A wrong derivative in one weight of the first layer, 1% of the gradient's scale.
  c.analytic_theta(3) += 0.01 * c.analytic_theta.norm();
  EXPECT_FALSE(compare(c.analytic_theta, c.fd_theta, 1e-6).ok());
  c.analytic_x(1) *= 1.001;
  EXPECT_FALSE(compare(c.analytic_x, c.fd_x, 1e-6).ok());
}

TEST(MlpLayout, CountAndInitMatchPyTorchDefaults) {
  const Mlp mlp({2, 32, 32, 1});
  EXPECT_EQ(mlp.n_params(), 2 * 32 + 32 + 32 * 32 + 32 + 32 + 1);
  Vector theta(mlp.n_params());
  Rng rng(5, "init");
  mlp.init_params(rng, theta);
  // Layer 0: W (32 x 2) then b (32), bound 1/√2; layers 1, 2: bound 1/√32.
  const double b0 = 1.0 / std::sqrt(2.0), b1 = 1.0 / std::sqrt(32.0);
  EXPECT_LE(theta.head(96).cwiseAbs().maxCoeff(), b0);
  EXPECT_GT(theta.head(96).cwiseAbs().maxCoeff(), 0.9 * b0);
  EXPECT_LE(theta.tail(theta.size() - 96).cwiseAbs().maxCoeff(), b1);
  EXPECT_GT(theta.tail(theta.size() - 96).cwiseAbs().maxCoeff(), 0.9 * b1);
  // The layout: with W = 0 the output is the last bias.
  Vector zero_w = Vector::Zero(mlp.n_params());
  zero_w(mlp.n_params() - 1) = 0.75;
  EXPECT_DOUBLE_EQ(mlp.forward(zero_w, Matrix::Ones(2, 1), nullptr)(0, 0), 0.75);
}

TEST(MlpErrors, BadSizesAndShapesAreNamed) {
  EXPECT_THROW(Mlp({3}), Error);
  EXPECT_THROW(Mlp({3, 0, 1}), Error);
  const Mlp mlp({3, 4, 2});
  const Vector theta = Vector::Zero(mlp.n_params());
  try {
    mlp.forward(Vector::Zero(5), Matrix::Zero(3, 1), nullptr);
    ADD_FAILURE() << "no throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("theta has 5 entries"), std::string::npos) << e.what();
  }
  EXPECT_THROW(mlp.forward(theta, Matrix::Zero(2, 1), nullptr), Error);
  EXPECT_THROW(mlp.input_gradient(theta, Matrix::Zero(3, 1)), Error);  // out_dim 2
  MlpCache empty;
  Vector grad = Vector::Zero(mlp.n_params());
  EXPECT_THROW(mlp.backward(theta, empty, Matrix::Zero(2, 1), grad, nullptr), Error);
}

}  // namespace
}  // namespace csympnet::testing
