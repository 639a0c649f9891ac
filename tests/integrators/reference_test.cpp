// The three reference solvers against each other, against closed forms, and the splitting's
// structure (conformal symplecticity, second order, exact tangent).
#include "csympnet/integrators/reference.hpp"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "support/same_bits.hpp"

namespace csympnet {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

System make(const std::string& kind, int d, double gamma = 0.05, double alpha = 0.005) {
  SystemSpec s;
  s.kind = kind;
  s.d = d;
  s.gamma = gamma;
  s.alpha = alpha;
  return System(s);
}

std::vector<System> all_kinds() {
  return {make("oscillator", 1), make("oscillator", 3), make("chain", 10), make("cubic", 1),
          make("cubic", 10)};
}

TEST(Reference, SubstepCountUsesToleratedCeiling) {
  EXPECT_EQ(substep_count(0.1, 1e-3), 100);  // 0.1 / 1e-3 = 100.00000000000001
  EXPECT_EQ(substep_count(0.2, 1e-3), 200);
  EXPECT_EQ(substep_count(0.15, 1e-3), 150);
  EXPECT_EQ(substep_count(0.07, 1e-3), 70);
  EXPECT_EQ(substep_count(0.1001, 1e-3), 101);
  EXPECT_EQ(substep_count(1e-4, 1e-3), 1);
  for (int k = 1; k <= 300; ++k)  // every grid step a user would type
    EXPECT_EQ(substep_count(1e-3 * k, 1e-3), k) << k;
  EXPECT_THROW(substep_count(0.0, 1e-3), Error);
  EXPECT_THROW(substep_count(0.1, -1.0), Error);
}

TEST(Reference, SplittingJacobianIsConformallySymplectic) {
  // Each substep maps J to a² J · ... exactly; in floating point the residual grows by about
  // u ‖J‖_F per substep, so after n substeps it is ≲ n u ‖J‖_F. We allow 4 n u ‖J‖_F.
  Rng rng(11, "reference-test");
  for (const System& sys : all_kinds()) {
    const Matrix J = canonical_j(sys.d());
    for (int rep = 0; rep < 4; ++rep) {
      const Vector z = rng.uniform_vector(sys.dim(), -1.0, 1.0);
      const double h = rng.uniform(0.05, 0.2);
      const Matrix M = conformal_sv_jacobian(sys, z, h);
      const double lambda = std::exp(-sys.gamma() * h);
      const double residual = (M.transpose() * J * M - lambda * J).norm();
      const double tol = 4.0 * static_cast<double>(substep_count(h, 1e-3)) * kEps * J.norm();
      EXPECT_LT(residual, tol) << sys.spec().kind << " d=" << sys.d() << " h=" << h;
      // The check is sharp: a 0.1% error in the conformal factor is far outside it.
      EXPECT_GT((M.transpose() * J * M - std::exp(-sys.gamma() * h * 1.001) * J).norm(),
                100.0 * tol);
    }
  }
}

TEST(Reference, SplittingJacobianMatchesFiniteDifferences) {
  Rng rng(12, "reference-test");
  constexpr double kStep = 1e-6;
  for (const System& sys : all_kinds()) {
    const Vector z = rng.uniform_vector(sys.dim(), -1.0, 1.0);
    const double h = 0.1;
    const Matrix M = conformal_sv_jacobian(sys, z, h);
    Matrix fd(sys.dim(), sys.dim());
    for (Index i = 0; i < sys.dim(); ++i) {
      Vector zp = z, zm = z;
      zp(i) += kStep;
      zm(i) -= kStep;
      fd.col(i) = (conformal_sv_flow(sys, zp, h) - conformal_sv_flow(sys, zm, h)) / (2 * kStep);
    }
    // Rounding u/ε ~ 1e-10 dominates the O(ε²) truncation.
    EXPECT_LT((M - fd).lpNorm<Eigen::Infinity>(), 1e-8) << sys.spec().kind << " d=" << sys.d();
  }
}

TEST(Reference, SplittingIsSecondOrderAgainstExpm) {
  Rng rng(13, "reference-test");
  for (const System& sys : {make("oscillator", 1), make("chain", 10)}) {
    const double h = 1.0;
    const Matrix E = expm_propagator(sys, h);
    for (int rep = 0; rep < 3; ++rep) {
      const Vector z = rng.uniform_vector(sys.dim(), -1.0, 1.0);
      const Vector exact = E * z;
      const double e1 = (conformal_sv_flow(sys, z, h, 0.02) - exact).norm();
      const double e2 = (conformal_sv_flow(sys, z, h, 0.01) - exact).norm();
      const double order = std::log2(e1 / e2);
      EXPECT_GE(order, 1.9) << sys.spec().kind;
      EXPECT_LE(order, 2.1) << sys.spec().kind;
    }
  }
}

TEST(Reference, ExpmMatchesDampedOscillatorClosedForm) {
  SystemSpec s;
  s.d = 1;
  s.omega = 1.3;
  s.gamma = 0.4;
  const System sys(s);
  const double q0 = 0.7, p0 = -0.4, t = 2.3;
  const double wd = std::sqrt(s.omega * s.omega - 0.25 * s.gamma * s.gamma);
  const double A = q0, B = (p0 + 0.5 * s.gamma * q0) / wd;
  const double decay = std::exp(-0.5 * s.gamma * t);
  const double c = std::cos(wd * t), sn = std::sin(wd * t);
  const double q = decay * (A * c + B * sn);
  const double p = decay * (-0.5 * s.gamma * (A * c + B * sn) + wd * (B * c - A * sn));
  const Vector z = expm_propagator(sys, t) * (Vector(2) << q0, p0).finished();
  EXPECT_NEAR(z(0), q, 1e-14);
  EXPECT_NEAR(z(1), p, 1e-14);
  // Through the public entry point too.
  ReferenceOptions opt;
  opt.method = Reference::kExpm;
  const Matrix Z =
      reference_flow(sys, (Matrix(2, 1) << q0, p0).finished(), Vector::Constant(1, t), opt);
  EXPECT_NEAR(Z(0, 0), q, 1e-14);
  EXPECT_NEAR(Z(1, 0), p, 1e-14);
}

TEST(Reference, RkMatchesExpmOnLinearSystems) {
  Rng rng(14, "reference-test");
  for (const System& sys : {make("oscillator", 1), make("chain", 10)}) {
    for (double h : {0.1, 1.0}) {
      const Vector z = rng.uniform_vector(sys.dim(), -1.0, 1.0);
      const Vector exact = expm_propagator(sys, h) * z;
      EXPECT_LT((rk_flow(sys, z, h) - exact).norm(), 1e-10 * exact.norm())
          << sys.spec().kind << " h=" << h;
    }
  }
}

TEST(Reference, RkAndSplittingAgreeToSecondOrderOnCubic) {
  // α = 0.05 makes the cubic term matter over h = 1; the splitting error is C h_ref², far
  // above the rk error, so the difference must shrink fourfold when h_ref halves.
  Rng rng(15, "reference-test");
  const System sys = make("cubic", 10, 0.05, 0.05);
  const Vector z = rng.uniform_vector(sys.dim(), -1.0, 1.0);
  const double h = 1.0;
  const Vector rk = rk_flow(sys, z, h);
  const double e1 = (conformal_sv_flow(sys, z, h, 0.02) - rk).norm();
  const double e2 = (conformal_sv_flow(sys, z, h, 0.01) - rk).norm();
  const double order = std::log2(e1 / e2);
  EXPECT_GE(order, 1.9);
  EXPECT_LE(order, 2.1);
  // At the protocol's h_ref = 1e-3 the two references agree to O(h_ref²).
  EXPECT_LT((conformal_sv_flow(sys, z, h, 1e-3) - rk).norm(), e2 / 50.0);
}

TEST(Reference, PerColumnStepsEqualColumnByColumnBitForBit) {
  Rng rng(16, "reference-test");
  const Vector h = (Vector(7) << 0.1, 0.05, 0.1, 0.137, 0.05, 0.1, 0.149).finished();
  for (const System& sys : {make("cubic", 10), make("chain", 3)}) {
    const Matrix Z = rng.uniform_matrix(sys.dim(), h.size(), -1.0, 1.0);
    for (Reference method : {Reference::kSplitting, Reference::kExpm, Reference::kRk}) {
      if (method == Reference::kExpm && !sys.is_linear()) continue;
      ReferenceOptions opt;
      opt.method = method;
      const Matrix batch = reference_flow(sys, Z, h, opt);
      for (Index j = 0; j < Z.cols(); ++j) {
        const Matrix one = reference_flow(sys, Z.col(j), h.segment(j, 1), opt);
        EXPECT_TRUE(testing::same_bits(batch.col(j), one)) << to_string(method) << " column " << j;
      }
    }
  }
}

TEST(Reference, EqualStepBatchEqualsSingleStateFlowBitForBit) {
  Rng rng(17, "reference-test");
  const System sys = make("cubic", 10);
  const Matrix Z = rng.uniform_matrix(sys.dim(), 9, -1.0, 1.0);
  const Matrix batch = reference_flow(sys, Z, Vector::Constant(9, 0.1));
  for (Index j = 0; j < Z.cols(); ++j)
    EXPECT_TRUE(testing::same_bits(batch.col(j), conformal_sv_flow(sys, Z.col(j), 0.1))) << j;
  // One substep is the splitting over δ with h_ref = δ.
  Matrix one = Z;
  conformal_sv_substep(sys, one, 0.01);
  EXPECT_TRUE(testing::same_bits(one.col(0), conformal_sv_flow(sys, Z.col(0), 0.01, 0.01)));
}

TEST(Reference, SplittingPreservesUndampedEnergyClosely) {
  // γ = 0: a symplectic method keeps H to O(h_ref²) with no drift.
  Rng rng(18, "reference-test");
  const System sys = make("cubic", 10, 0.0);
  const Vector z = rng.uniform_vector(sys.dim(), -1.0, 1.0);
  const Vector z1 = conformal_sv_flow(sys, z, 2.0);
  EXPECT_NEAR(sys.energy(z1), sys.energy(z), 1e-6);
}

TEST(Reference, OptionsAndNames) {
  for (Reference r : {Reference::kSplitting, Reference::kExpm, Reference::kRk})
    EXPECT_EQ(parse_reference(to_string(r)), r);
  try {
    parse_reference("rk45");
    ADD_FAILURE() << "accepted rk45";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("rk45"), std::string::npos);
  }
  ReferenceOptions opt;
  EXPECT_NO_THROW(opt.validate());
  opt.h_ref = 0.0;
  EXPECT_THROW(opt.validate(), Error);
  opt = {};
  opt.h_ref = std::nan("");
  EXPECT_THROW(opt.validate(), Error);
  opt = {};
  opt.rk_rtol = -1e-12;
  EXPECT_THROW(opt.validate(), Error);
  opt = {};
  opt.rk_atol = 0.0;
  EXPECT_THROW(opt.validate(), Error);
}

TEST(Reference, RejectsBadInput) {
  const System cubic = make("cubic", 2);
  ReferenceOptions expm;
  expm.method = Reference::kExpm;
  const Matrix Z = Matrix::Zero(4, 2);
  EXPECT_THROW(reference_flow(cubic, Z, Vector::Constant(2, 0.1), expm), Error);
  EXPECT_THROW(expm_propagator(cubic, 0.1), Error);
  EXPECT_THROW(reference_flow(cubic, Z, Vector::Constant(3, 0.1)), Error);   // h length
  EXPECT_THROW(reference_flow(cubic, Z, Vector::Constant(2, -0.1)), Error);  // h sign
  EXPECT_THROW(reference_flow(cubic, Matrix::Zero(3, 2), Vector::Constant(2, 0.1)), Error);
  EXPECT_THROW(rk_flow(cubic, Vector::Zero(4), 0.1, 0.0, 1e-14), Error);
}

}  // namespace
}  // namespace csympnet
