// Known inputs of CSympNet-ID with a neural core (models/inputs.hpp; docs/derivations.md, "Known
// inputs: the neural cores"): Φ̂ = S_a ∘ K_{h/2, u(t₀+h)} ∘ Ψ ∘ K_{h/2, u(t₀)} ∘ S_a.
//   - reverse mode (θ, B included, and the input state) and the forward-mode Jacobian with
//     inputs against central differences, at random parameters and inputs, both holds, LA and G
//     cores, d = 1 and 2, m = 1 and 2;
//   - exact conformal symplecticity DΦᵀJDΦ = e^{−γh}J at random parameters and inputs;
//   - with every input 0 (and with no input at all) the free map of θ without B, to the bit;
//   - the half-kicks give the hold's impulse of the input over a step, (h/2) B (u₀ + u₁) under
//     the first-order hold (exact for an input linear in time) and h B u₀ under the zero-order;
//   - specs and model files carry the inputs; bad ones are refused with the reason.
#include <cmath>
#include <iostream>
#include <memory>

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/models/inputs.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "support/driven_derivative_check.hpp"
#include "support/gradient_check.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet::testing {
namespace {

struct NeuralDrivenCase {
  const char* core;  // "la" or "g"
  Index d;
  Index m;
  InputHold hold;
};

nlohmann::json core_spec(const NeuralDrivenCase& c) {
  if (std::string(c.core) == "la") return {{"type", "la"}, {"layers", 3}, {"sublayers", 2}};
  return {{"type", "g"}, {"layers", 4}, {"width", 5}};
}

nlohmann::json driven_spec(const NeuralDrivenCase& c) {
  return {{"type", "csympnet"},
          {"d", c.d},
          {"core", core_spec(c)},
          {"inputs", {{"m", c.m}, {"hold", hold_name(c.hold)}}}};
}

nlohmann::json free_spec(const NeuralDrivenCase& c) {
  return {{"type", "csympnet"}, {"d", c.d}, {"core", core_spec(c)}};
}

// θ ~ N(0, 0.5²) with β as given; B's entries N(0, 1).
Vector neural_driven_theta(const OneStepMap& map, Rng& rng, double beta) {
  return random_theta(map, rng, 0.5, beta);
}

class NeuralDrivenTest : public ::testing::TestWithParam<NeuralDrivenCase> {};

TEST_P(NeuralDrivenTest, DerivativesMatchCentralDifferences) {
  const NeuralDrivenCase c = GetParam();
  Rng rng(91 + c.d * 5 + c.m, std::string("neural-driven-fd-") + c.core);
  const auto map = make_one_step_map(driven_spec(c));
  ASSERT_EQ(map->n_inputs(), c.m);
  const auto free = make_one_step_map(free_spec(c));
  ASSERT_EQ(map->n_params(), free->n_params() + c.d * c.m);
  for (int rep = 0; rep < 3; ++rep) {
    const Vector theta = neural_driven_theta(*map, rng, rep % 2 == 0 ? 0.4 : -0.3);
    const Index n = 4;
    const Matrix z = rng.normal_matrix(map->dim(), n, 0.6);
    const Matrix u = rng.normal_matrix(2 * c.m, n, 1.0);
    const Vector h = rng.uniform_vector(n, 0.05, 0.3);
    const Matrix g = rng.normal_matrix(map->dim(), n, 1.0);
    const Vector grad = check_driven_derivatives(*map, theta, z, h, u, g, 1e-6);
    // B's block (between the core's parameters and β) has a slope the check above sees.
    const Index nc = free->n_params() - 1;
    EXPECT_GT(grad.segment(nc, c.d * c.m).cwiseAbs().sum(), 1e-3);
  }
}

TEST_P(NeuralDrivenTest, ConformallySymplecticAtRandomParametersAndInputs) {
  const NeuralDrivenCase c = GetParam();
  Rng rng(101 + c.d + c.m, std::string("neural-driven-structure-") + c.core);
  const auto map = make_one_step_map(driven_spec(c));
  double worst = 0.0;
  for (int rep = 0; rep < 50; ++rep) {
    const double beta = (rep % 2 == 0 ? 1.0 : -1.0) * rng.uniform(0.05, 3.0);
    const Vector theta = neural_driven_theta(*map, rng, beta);
    const Vector z = rng.normal_matrix(map->dim(), 1, 0.6);
    const Vector u = rng.normal_matrix(2 * c.m, 1, 3.0);
    const double h = rng.uniform(0.05, 0.4);
    const Matrix jac = map->jacobian_driven(theta, z, h, u);
    worst = std::max(worst, conformal_residual(jac, std::exp(-std::abs(beta) * h)) /
                                std::max(1.0, jac.squaredNorm()));
  }
  std::cout << "  worst ||DPhi^T J DPhi - exp(-gamma h) J||_F / ||DPhi||^2 = " << worst << "\n";
  EXPECT_LE(worst, 1e-13);
}

// Zero inputs, and none at all, give the free map of θ without B to the bit (forward, the
// input gradient and the Jacobian); with inputs the map moves.
TEST_P(NeuralDrivenTest, ZeroInputGivesTheFreeMapToTheBit) {
  const NeuralDrivenCase c = GetParam();
  Rng rng(111 + c.d + c.m, std::string("neural-driven-zero-") + c.core);
  const auto map = make_one_step_map(driven_spec(c));
  const auto free = make_one_step_map(free_spec(c));
  const Vector theta = neural_driven_theta(*map, rng, 0.3);
  const Index nc = free->n_params() - 1;
  Vector free_theta(free->n_params());
  free_theta << theta.head(nc), theta(map->n_params() - 1);
  const Index n = 5;
  const Matrix z = rng.normal_matrix(map->dim(), n, 0.7);
  const Vector h = rng.uniform_vector(n, 0.05, 0.3);
  const Matrix zero = Matrix::Zero(2 * c.m, n);
  const Matrix reference = free->forward(free_theta, z, h, nullptr);
  EXPECT_EQ(map->forward_driven(theta, z, h, zero, nullptr), reference);
  EXPECT_EQ(map->forward(theta, z, h, nullptr), reference);
  const Matrix g = rng.normal_matrix(map->dim(), n, 1.0);
  ForwardCache fc, dc;
  free->forward(free_theta, z, h, &fc);
  map->forward_driven(theta, z, h, zero, &dc);
  Vector fg = Vector::Zero(free->n_params()), dg = Vector::Zero(map->n_params());
  Matrix fdz, ddz;
  free->backward(free_theta, fc, g, fg, &fdz);
  map->backward(theta, dc, g, dg, &ddz);
  EXPECT_EQ(fdz, ddz);
  EXPECT_EQ(Vector(dg.head(nc)), Vector(fg.head(nc)));
  EXPECT_EQ(dg(map->n_params() - 1), fg(nc));
  EXPECT_EQ(map->jacobian_driven(theta, z.col(0), h(0), Vector(zero.col(0))),
            free->jacobian(free_theta, z.col(0), h(0)));
  const Matrix u = rng.normal_matrix(2 * c.m, n, 1.0);
  EXPECT_GT((map->forward_driven(theta, z, h, u, nullptr) - reference).norm(), 1e-3);
}

INSTANTIATE_TEST_SUITE_P(Cases, NeuralDrivenTest,
                         ::testing::Values(NeuralDrivenCase{"la", 1, 1, InputHold::kFirst},
                                           NeuralDrivenCase{"la", 2, 2, InputHold::kZero},
                                           NeuralDrivenCase{"g", 1, 2, InputHold::kZero},
                                           NeuralDrivenCase{"g", 2, 1, InputHold::kFirst}),
                         [](const auto& param_info) {
                           return std::string(param_info.param.core) + "_d" +
                                  std::to_string(param_info.param.d) + "_m" +
                                  std::to_string(param_info.param.m) + "_" +
                                  hold_name(param_info.param.hold);
                         });

// The impulse of one step: with the G core's parameters all 0 its modules move nothing (Ψ = the
// identity) and γ̂ tiny (a = 1), so p₁ − p₀ is the kicks' alone: (h/2) B (u₀ + u₁) under the
// first-order hold, the exact impulse of an input linear in time, and h B u₀ under the zero-order
// hold.
TEST(NeuralDrivenKicks, TheImpulseIsTheHoldsIntegralOfTheInput) {
  for (const InputHold hold : {InputHold::kFirst, InputHold::kZero}) {
    const nlohmann::json spec = {{"type", "csympnet"},
                                 {"d", 1},
                                 {"core", {{"type", "g"}, {"layers", 2}, {"width", 3}}},
                                 {"inputs", {{"m", 1}, {"hold", hold_name(hold)}}}};
    const auto map = make_one_step_map(spec);
    Vector theta = Vector::Zero(map->n_params());
    const Index bi = map->n_params() - 1;
    theta(bi) = 1e-300;   // γ̂ = 1e-300: a = 1 to the bit
    theta(bi - 1) = 1.7;  // B
    Matrix z(2, 1);
    z << 0.3, -0.2;
    Vector h(1);
    h << 0.25;
    Matrix u(2, 1);
    u << 0.8, -0.4;
    const Matrix out = map->forward_driven(theta, z, h, u, nullptr);
    const double impulse = hold == InputHold::kFirst ? 0.25 * (0.8 - 0.4) / 2.0 : 0.25 * 0.8;
    EXPECT_NEAR(out(1, 0) - z(1, 0), 1.7 * impulse, 1e-15) << hold_name(hold);
  }
}

TEST(NeuralDrivenSpec, ModelFilesCarryTheInputsAndBadOnesAreRefused) {
  const NeuralDrivenCase c{"la", 2, 1, InputHold::kZero};
  const auto map = make_one_step_map(driven_spec(c));
  const nlohmann::json spec = map->hyperparams();
  ASSERT_TRUE(spec.contains("inputs"));
  EXPECT_EQ(spec.at("inputs").at("m"), 1);
  EXPECT_EQ(spec.at("inputs").at("hold"), "zoh");
  const auto rebuilt = make_one_step_map(spec);
  EXPECT_EQ(rebuilt->n_inputs(), 1);
  EXPECT_EQ(rebuilt->n_params(), map->n_params());
  EXPECT_FALSE(make_one_step_map(free_spec(c))->hyperparams().contains("inputs"));
  // A free map refuses inputs; a driven one refuses inputs of the wrong shape.
  const auto free = make_one_step_map(free_spec(c));
  const Vector ft = Vector::Zero(free->n_params());
  const Vector dt = Vector::Zero(map->n_params());
  const Matrix z = Matrix::Zero(4, 2);
  const Vector h = Vector::Constant(2, 0.1);
  EXPECT_THROW(free->forward_driven(ft, z, h, Matrix::Zero(2, 2), nullptr), Error);
  try {
    map->forward_driven(dt, z, h, Matrix::Zero(3, 2), nullptr);
    ADD_FAILURE() << "inputs of 3 rows accepted by a map of 1 input";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("expected 2 x 2"), std::string::npos) << e.what();
  }
  nlohmann::json bad = driven_spec(c);
  bad["inputs"]["m"] = 0;
  EXPECT_THROW(make_one_step_map(bad), Error);
  bad = driven_spec(c);
  bad["inputs"]["hold"] = "cubic";
  EXPECT_THROW(make_one_step_map(bad), Error);
  // The library core takes its inputs inside the core, where its kicks are.
  nlohmann::json lib = {{"type", "csympnet"},
                        {"d", 1},
                        {"core", {{"type", "library"}, {"terms", {"q1^2"}}}},
                        {"inputs", {{"m", 1}}}};
  EXPECT_THROW(make_one_step_map(lib), Error);
  // The per-dof scales do not pass inputs on.
  nlohmann::json scaled = driven_spec(c);
  scaled["dof_scales"] = "learned";
  EXPECT_THROW(make_one_step_map(scaled), Error);
}

}  // namespace
}  // namespace csympnet::testing
