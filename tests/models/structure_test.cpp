// Exact structure at random parameters, points and steps:
//   cores:        DΨᵀ J DΨ = J
//   CSympNet-ID:  DΦ̂ᵀ J DΦ̂ = exp(−γ̂h) J                       (paper eq. exact_csp)
//   conjugacy:    S_{1/a} ∘ Φ̂ ∘ S_{1/a} = Ψ, a = exp(−γ̂h/2)     (paper thm. conjugacy)
//
// The residuals are rounding errors of products of O(100) shears, so they scale like
// ε·‖D‖². The parameter scales below keep the Jacobian entries O(1)–O(10) (checked), which
// lets one absolute tolerance of 1e-12 serve every case.
#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include "../src/models/csympnet_id.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet::testing {
namespace {

constexpr double kStructureTolerance = 1e-12;
constexpr int kRepetitions = 200;

struct StructureCase {
  const char* core;  // core spec without d
  Index d;
  double theta_stddev;
};

void PrintTo(const StructureCase& c, std::ostream* out) {
  *out << c.core << " d=" << c.d;
}

class StructureTest : public ::testing::TestWithParam<StructureCase> {
 protected:
  nlohmann::json spec(const char* type) const {
    const StructureCase& c = GetParam();
    return {{"type", type}, {"d", c.d}, {"core", nlohmann::json::parse(c.core)}};
  }
};

TEST_P(StructureTest, CoreIsSymplectic) {
  const auto core = make_one_step_map(spec("sympnet"));
  Rng rng(5, "core-symplectic");
  double worst = 0.0;
  double largest_entry = 0.0;
  for (int rep = 0; rep < kRepetitions; ++rep) {
    const Vector theta = random_theta(*core, rng, GetParam().theta_stddev);
    const Vector z = rng.normal_matrix(core->dim(), 1, 1.0);
    const double h = rng.uniform(0.05, 0.2);
    const Matrix jac = core->jacobian(theta, z, h);
    worst = std::max(worst, conformal_residual(jac, 1.0));
    largest_entry = std::max(largest_entry, jac.cwiseAbs().maxCoeff());
  }
  std::cout << "  worst ||DPsi^T J DPsi - J||_F = " << worst
            << ", max |DPsi_ij| = " << largest_entry << "\n";
  EXPECT_LE(worst, kStructureTolerance);
  EXPECT_GT(largest_entry, 2.0);  // the parameters are large enough to be non-trivial
}

TEST_P(StructureTest, CSympNetIsConformallySymplectic) {
  const auto model = make_one_step_map(spec("csympnet"));
  Rng rng(6, "csympnet-conformal");
  double worst = 0.0;
  for (int rep = 0; rep < kRepetitions; ++rep) {
    const double beta = (rep % 2 == 0 ? 1.0 : -1.0) * rng.uniform(0.05, 3.0);
    const Vector theta = random_theta(*model, rng, GetParam().theta_stddev, beta);
    const Vector z = rng.normal_matrix(model->dim(), 1, 1.0);
    const double h = rng.uniform(0.05, 0.2);
    const Matrix jac = model->jacobian(theta, z, h);
    // λ(h) = exp(−γ̂ h), eq. learned_lambda.
    worst = std::max(worst, conformal_residual(jac, std::exp(-std::abs(beta) * h)));
  }
  std::cout << "  worst ||DPhi^T J DPhi - exp(-gamma h) J||_F = " << worst << "\n";
  EXPECT_LE(worst, kStructureTolerance);
}

TEST_P(StructureTest, ScalingConjugacyRecoversTheCore) {
  const auto model = make_one_step_map(spec("csympnet"));
  const auto core = make_one_step_map(spec("sympnet"));
  const Index d = GetParam().d;
  Rng rng(7, "conjugacy");
  double worst_map = 0.0;
  double worst_symplectic = 0.0;
  for (int rep = 0; rep < kRepetitions; ++rep) {
    const double beta = (rep % 2 == 0 ? 1.0 : -1.0) * rng.uniform(0.05, 3.0);
    const Vector theta = random_theta(*model, rng, GetParam().theta_stddev, beta);
    const Vector theta_core = theta.head(core->n_params());
    const Vector z = rng.normal_matrix(2 * d, 1, 1.0);
    const Vector h = Vector::Constant(1, rng.uniform(0.05, 0.2));
    const double a = std::exp(-0.5 * std::abs(beta) * h(0));
    // S_{1/a} as a matrix: diag(I, I/a).
    Vector inv_scale = Vector::Ones(2 * d);
    inv_scale.tail(d).setConstant(1.0 / a);
    const Vector zs = inv_scale.asDiagonal() * z;
    const Vector conjugated = inv_scale.asDiagonal() * model->apply(theta, zs, h);
    const Vector direct = core->apply(theta_core, z, h);
    worst_map = std::max(worst_map, (conjugated - direct).norm() / (1.0 + direct.norm()));
    const Matrix jac =
        inv_scale.asDiagonal() * model->jacobian(theta, zs, h(0)) * inv_scale.asDiagonal();
    worst_symplectic = std::max(worst_symplectic, conformal_residual(jac, 1.0));
  }
  std::cout << "  worst conjugacy map mismatch (relative) = " << worst_map
            << ", worst symplectic residual = " << worst_symplectic << "\n";
  EXPECT_LE(worst_map, kStructureTolerance);
  EXPECT_LE(worst_symplectic, kStructureTolerance);
}

INSTANTIATE_TEST_SUITE_P(
    Cores, StructureTest,
    ::testing::Values(
        StructureCase{R"({"type":"la","layers":5,"sublayers":20})", 1, 0.5},
        StructureCase{R"({"type":"la","layers":3,"sublayers":4})", 3, 0.7},
        StructureCase{R"({"type":"la","layers":4,"sublayers":10})", 10, 0.3},
        StructureCase{R"({"type":"la","layers":5,"sublayers":20,"step_terms":2})", 1, 0.5},
        StructureCase{R"({"type":"la","layers":3,"sublayers":4,"step_terms":2})", 3, 0.7},
        StructureCase{R"({"type":"g","layers":4,"width":10})", 1, 1.5},
        StructureCase{R"({"type":"g","layers":5,"width":8})", 3, 1.8},
        StructureCase{R"({"type":"g","layers":7,"width":50})", 10, 1.0}));

}  // namespace
}  // namespace csympnet::testing
