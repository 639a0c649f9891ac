// Adaptive dopri5 flow and its variational Jacobian against closed forms (linear fields,
// exp(hA)), against finite differences of the flow (nonlinear fields), and its failure modes.
// The "[measured]" lines feed the numbers quoted in docs/rollout.md.
#include "csympnet/integrators/dopri5.hpp"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unsupported/Eigen/MatrixFunctions>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "support/same_bits.hpp"

namespace csympnet {
namespace {

// A = P B P⁻¹ with B block-diagonal [[a_k, b_k], [−b_k, a_k]], a_k < 0: eigenvalues a_k ± i b_k,
// i.e. damped rotations as in a damped oscillator, seen through a random well-conditioned basis.
Matrix damped_generator(Index n, std::uint64_t seed) {
  Rng rng(seed, "dopri5-test-generator");
  Matrix b = Matrix::Zero(n, n);
  for (Index k = 0; k + 1 < n; k += 2) {
    const double a = -rng.uniform(0.05, 0.5);
    const double w = rng.uniform(0.5, 3.0);
    b(k, k) = a;
    b(k + 1, k + 1) = a;
    b(k, k + 1) = w;
    b(k + 1, k) = -w;
  }
  const Matrix p = Matrix::Identity(n, n) + rng.uniform_matrix(n, n, -0.3, 0.3);
  return p * b * p.inverse();
}

VectorField linear_field(const Matrix& a) {
  return [a](const Vector& z, Vector& dz) { dz.noalias() = a * z; };
}
VectorFieldJacobian constant_jacobian(const Matrix& a) {
  return [a](const Vector&) { return a; };
}

// Damped pendulum q' = p, p' = −sin q − γ p.
constexpr double kGamma = 0.1;
void pendulum(const Vector& z, Vector& dz) {
  dz.resize(2);
  dz << z(1), -std::sin(z(0)) - kGamma * z(1);
}
Matrix pendulum_jacobian(const Vector& z) {
  Matrix j(2, 2);
  j << 0.0, 1.0, -std::cos(z(0)), -kGamma;
  return j;
}

// Two coupled damped cubic oscillators, V = ½‖q‖² + α s³ with s = q₁ + q₂:
// q' = p, p' = −q − 3α s² 𝟙 − γ p.
constexpr double kAlpha = 0.3;
void cubic(const Vector& z, Vector& dz) {
  const double s = z(0) + z(1);
  dz.resize(4);
  dz << z(2), z(3), -z(0) - 3 * kAlpha * s * s - kGamma * z(2),
      -z(1) - 3 * kAlpha * s * s - kGamma * z(3);
}
Matrix cubic_jacobian(const Vector& z) {
  const double c = 6 * kAlpha * (z(0) + z(1));
  Matrix j = Matrix::Zero(4, 4);
  j(0, 2) = 1.0;
  j(1, 3) = 1.0;
  j.bottomLeftCorner(2, 2).setConstant(-c);
  j(2, 0) -= 1.0;
  j(3, 1) -= 1.0;
  j(2, 2) = -kGamma;
  j(3, 3) = -kGamma;
  return j;
}

double rel_err(const Matrix& got, const Matrix& want) {
  return (got - want).lpNorm<Eigen::Infinity>() / want.lpNorm<Eigen::Infinity>();
}

void report_measured(const std::string& what, double value) {
  std::printf("[measured] %-58s %.3e\n", what.c_str(), value);
}

OdeOptions tight(double rtol, double atol) {
  OdeOptions o;
  o.rtol = rtol;
  o.atol = atol;
  return o;
}

std::string message_of(const std::function<void()>& call) {
  try {
    call();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no Error thrown)";
}

// Default tolerances (rtol 1e-7, atol 1e-9): the global error over h ≤ 1 stays within a small
// multiple of rtol, so 1e-6 relative (10 rtol) is the bound; with rtol 1e-10 the bound is 1e-9.
TEST(Dopri5, LinearFieldMatchesMatrixExponential) {
  struct Tol {
    OdeOptions opt;
    double bound;
    const char* name;
  };
  const std::vector<Tol> tols = {{OdeOptions{}, 1e-6, "default"},
                                 {tight(1e-10, 1e-12), 1e-9, "rtol1e-10"}};
  for (const Index n : {Index{2}, Index{6}}) {
    const Matrix a = damped_generator(n, 7 + static_cast<std::uint64_t>(n));
    const Vector z0 = Rng(3, "dopri5-test-z0").uniform_vector(n, -1.0, 1.0);
    for (const double h : {0.05, 0.2, 1.0}) {
      const Matrix exact = (h * a).exp();
      for (const Tol& tol : tols) {
        const std::string tag =
            "n=" + std::to_string(n) + " h=" + std::to_string(h) + " " + tol.name;
        const double e_flow = rel_err(dopri5_flow(linear_field(a), z0, h, tol.opt), exact * z0);
        const auto [zj, m] =
            dopri5_flow_jacobian(linear_field(a), constant_jacobian(a), z0, h, tol.opt);
        const double e_jac = rel_err(m, exact);
        const double e_zj = rel_err(zj, exact * z0);
        report_measured("linear flow  " + tag, e_flow);
        report_measured("linear M     " + tag, e_jac);
        EXPECT_LT(e_flow, tol.bound) << tag;
        EXPECT_LT(e_jac, tol.bound) << tag;
        EXPECT_LT(e_zj, tol.bound) << tag;
      }
    }
  }
}

TEST(Dopri5, TinyStepIsAccurate) {
  const Matrix a = damped_generator(6, 11);
  const Vector z0 = Rng(5, "dopri5-test-z0").uniform_vector(6, -1.0, 1.0);
  const double h = 1e-6;
  const Matrix exact = (h * a).exp();
  const auto [z, m] = dopri5_flow_jacobian(linear_field(a), constant_jacobian(a), z0, h);
  EXPECT_LT(rel_err(dopri5_flow(linear_field(a), z0, h), exact * z0), 1e-12);
  EXPECT_LT(rel_err(z, exact * z0), 1e-12);
  EXPECT_LT(rel_err(m, exact), 1e-12);
  // M(h) = I + hA + O(h²): the increment itself must be right, not just M ≈ I.
  const Matrix increment = (m - Matrix::Identity(6, 6)) / h;
  EXPECT_LT(rel_err(increment, a), 1e-5);
}

// Central differences of the flow with rtol 1e-12: FD truncation ~ ε² ‖∂³Φ‖ ≈ 1e-8 and
// solver noise ~ rtol/ε ≈ 1e-8 at ε = 1e-4, so 1e-6 relative leaves a wide margin but would
// still catch a wrong Df or a transposed M.
void check_against_fd(const VectorField& f, const VectorFieldJacobian& df, const Vector& z0,
                      double h, const std::string& tag) {
  const OdeOptions opt = tight(1e-12, 1e-14);
  const double eps = 1e-4;
  const Index n = z0.size();
  Matrix fd(n, n);
  for (Index j = 0; j < n; ++j) {
    Vector zp = z0;
    Vector zm = z0;
    zp(j) += eps;
    zm(j) -= eps;
    fd.col(j) = (dopri5_flow(f, zp, h, opt) - dopri5_flow(f, zm, h, opt)) / (2 * eps);
  }
  const double e = rel_err(dopri5_flow_jacobian(f, df, z0, h, opt).second, fd);
  report_measured("nonlinear M vs central FD " + tag, e);
  EXPECT_LT(e, 1e-6) << tag;
}

TEST(Dopri5, NonlinearJacobianMatchesFiniteDifferences) {
  Vector zp(2);
  zp << 1.2, -0.4;  // well away from the linear regime of the pendulum
  Vector zc(4);
  zc << 0.5, -0.2, 0.3, 0.6;
  for (const double h : {0.05, 0.2, 1.0}) {
    check_against_fd(pendulum, pendulum_jacobian, zp, h, "pendulum h=" + std::to_string(h));
    check_against_fd(cubic, cubic_jacobian, zc, h, "cubic h=" + std::to_string(h));
  }
}

// The augmented run controls the error of M too, so it takes its own step sequence: z agrees with
// the plain flow to within the tolerance, not bitwise.
TEST(Dopri5, AugmentedStateAgreesWithPlainFlow) {
  Vector z0(4);
  z0 << 0.5, -0.2, 0.3, 0.6;
  for (const double h : {0.05, 0.2, 1.0}) {
    const Vector z = dopri5_flow(cubic, z0, h);
    const Vector zj = dopri5_flow_jacobian(cubic, cubic_jacobian, z0, h).first;
    const double e = rel_err(zj, z);
    report_measured("cubic z(jacobian run) vs z(flow) h=" + std::to_string(h), e);
    EXPECT_LT(e, 1e-6);
  }
}

TEST(Dopri5, Deterministic) {
  Vector z0(4);
  z0 << 0.5, -0.2, 0.3, 0.6;
  EXPECT_TRUE(testing::same_bits(dopri5_flow(cubic, z0, 0.7), dopri5_flow(cubic, z0, 0.7)));
  const auto r1 = dopri5_flow_jacobian(cubic, cubic_jacobian, z0, 0.7);
  const auto r2 = dopri5_flow_jacobian(cubic, cubic_jacobian, z0, 0.7);
  EXPECT_TRUE(testing::same_bits(r1.first, r2.first));
  EXPECT_TRUE(testing::same_bits(r1.second, r2.second));
}

TEST(Dopri5, ZeroStateOfLinearFieldStaysZero) {
  // f(z0) = 0 exercises the starting-step fallback (‖f0‖ = 0 in the weighted norm).
  const Matrix a = damped_generator(2, 9);
  const auto [z, m] =
      dopri5_flow_jacobian(linear_field(a), constant_jacobian(a), Vector::Zero(2), 0.2);
  EXPECT_EQ(z.lpNorm<Eigen::Infinity>(), 0.0);
  EXPECT_LT(rel_err(m, (0.2 * a).exp()), 1e-6);
}

TEST(Dopri5, RejectsBadH) {
  const Matrix a = damped_generator(2, 9);
  const Vector z0 = Vector::Ones(2);
  for (const double h : {0.0, -0.1, std::numeric_limits<double>::quiet_NaN(),
                         std::numeric_limits<double>::infinity()}) {
    const std::string msg = message_of([&] { dopri5_flow(linear_field(a), z0, h); });
    EXPECT_NE(msg.find("h must be a finite number > 0"), std::string::npos) << msg;
    EXPECT_THROW(dopri5_flow_jacobian(linear_field(a), constant_jacobian(a), z0, h), Error);
  }
  EXPECT_NE(message_of([&] { dopri5_flow(linear_field(a), z0, -0.1); }).find("-0.1"),
            std::string::npos);
  EXPECT_NE(message_of([&] {
              dopri5_flow(linear_field(a), z0, std::numeric_limits<double>::quiet_NaN());
            }).find("nan"),
            std::string::npos);
}

TEST(Dopri5, RejectsBadOptionsNamingTheField) {
  const Matrix a = damped_generator(2, 9);
  const Vector z0 = Vector::Ones(2);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  struct Case {
    OdeOptions opt;
    const char* field;
  };
  std::vector<Case> cases(5);
  cases[0].opt.rtol = 0.0;
  cases[0].field = "rtol";
  cases[1].opt.rtol = nan;
  cases[1].field = "rtol";
  cases[2].opt.atol = -1e-9;
  cases[2].field = "atol";
  cases[3].opt.atol = std::numeric_limits<double>::infinity();
  cases[3].field = "atol";
  cases[4].opt.max_steps = 0;
  cases[4].field = "max_steps";
  for (const Case& c : cases) {
    const std::string msg = message_of([&] { dopri5_flow(linear_field(a), z0, 0.1, c.opt); });
    EXPECT_NE(msg.find(std::string("OdeOptions.") + c.field), std::string::npos) << msg;
    EXPECT_THROW(dopri5_flow_jacobian(linear_field(a), constant_jacobian(a), z0, 0.1, c.opt),
                 Error);
  }
  EXPECT_NO_THROW(OdeOptions{}.validate());
}

// z' = z², z(0) = 1 has z(t) = 1/(1 − t), which leaves the reals at t = 1 < h = 2.
TEST(Dopri5, FiniteTimeBlowUpThrows) {
  const VectorField f = [](const Vector& z, Vector& dz) { dz = z.cwiseProduct(z); };
  const VectorFieldJacobian df = [](const Vector& z) { return Matrix(2.0 * z.asDiagonal()); };
  const Vector z0 = Vector::Ones(1);
  const std::string msg = message_of([&] { dopri5_flow(f, z0, 2.0); });
  std::printf("[measured] blow-up message: %s\n", msg.c_str());
  EXPECT_EQ(msg.rfind("dopri5: ", 0), 0u) << msg;
  EXPECT_THROW(dopri5_flow_jacobian(f, df, z0, 2.0), Error);
  // Before the singularity the same field is fine: z(0.5) = 2.
  EXPECT_NEAR(dopri5_flow(f, z0, 0.5)(0), 2.0, 1e-6);
}

TEST(Dopri5, StepBudgetThrows) {
  const Matrix a = damped_generator(2, 9);
  OdeOptions opt;
  opt.max_steps = 3;
  const std::string msg =
      message_of([&] { dopri5_flow(linear_field(a), Vector::Ones(2), 50.0, opt); });
  EXPECT_NE(msg.find("step budget of 3 exhausted at t = "), std::string::npos) << msg;
  EXPECT_THROW(
      dopri5_flow_jacobian(linear_field(a), constant_jacobian(a), Vector::Ones(2), 50.0, opt),
      Error);
}

TEST(Dopri5, NaNFieldThrows) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const VectorField always = [nan](const Vector& z, Vector& dz) { dz.setConstant(z.size(), nan); };
  EXPECT_THROW(dopri5_flow(always, Vector::Ones(2), 0.2), Error);
  // NaN only once the trajectory crosses z = 1.5 (z' = 1 from 0): fails mid-integration.
  const VectorField late = [nan](const Vector& z, Vector& dz) {
    dz.setConstant(z.size(), z(0) > 1.5 ? nan : 1.0);
  };
  const VectorFieldJacobian zero_jac = [](const Vector& z) {
    return Matrix(Matrix::Zero(z.size(), z.size()));
  };
  const std::string msg = message_of([&] { dopri5_flow(late, Vector::Zero(1), 2.0); });
  EXPECT_NE(msg.find("non-finite"), std::string::npos) << msg;
  EXPECT_THROW(dopri5_flow_jacobian(late, zero_jac, Vector::Zero(1), 2.0), Error);
  EXPECT_NEAR(dopri5_flow(late, Vector::Zero(1), 1.0)(0), 1.0, 1e-12);
}

TEST(Dopri5, RejectsMisshapenFieldAndJacobian) {
  const VectorField short_f = [](const Vector&, Vector& dz) { dz = Vector::Zero(1); };
  EXPECT_THROW(dopri5_flow(short_f, Vector::Ones(2), 0.1), Error);
  const Matrix a = damped_generator(2, 9);
  const VectorFieldJacobian bad_df = [](const Vector&) { return Matrix(Matrix::Zero(3, 2)); };
  EXPECT_THROW(dopri5_flow_jacobian(linear_field(a), bad_df, Vector::Ones(2), 0.1), Error);
  Vector bad_z0 = Vector::Ones(2);
  bad_z0(1) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(dopri5_flow(linear_field(a), bad_z0, 0.1), Error);
  EXPECT_THROW(dopri5_flow(linear_field(a), Vector(), 0.1), Error);
}

}  // namespace
}  // namespace csympnet
