// Every model's hand-written derivatives against finite differences (one shared harness),
// and jacobian() against the Jacobian assembled from backward() (two independent paths).
#include <gtest/gtest.h>

#include "csympnet/models/one_step_map.hpp"
#include "support/gradient_check.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet::testing {
namespace {

struct GradientCase {
  const char* spec;
  double theta_stddev;  // large enough that the sigmoids leave their linear range
  double beta;          // damping parameter, if the model has one
};

void PrintTo(const GradientCase& c, std::ostream* out) {
  *out << c.spec << " beta " << c.beta;
}

class ModelGradientTest : public ::testing::TestWithParam<GradientCase> {};

TEST_P(ModelGradientTest, BackwardAndJacobianMatchFiniteDifferences) {
  const GradientCase& c = GetParam();
  const auto model = make_one_step_map(nlohmann::json::parse(c.spec));
  Rng rng(2024, c.spec);
  constexpr int kRepetitions = 3;
  constexpr Index kBatch = 5;
  for (int rep = 0; rep < kRepetitions; ++rep) {
    const Vector theta = random_theta(*model, rng, c.theta_stddev, c.beta);
    const Matrix z = rng.normal_matrix(model->dim(), kBatch, 1.0);
    const Vector h = random_steps(kBatch, rng);
    const ModelCheck check = check_one_step_map(*model, theta, z, h, rng);
    EXPECT_TRUE(check.ok()) << check.report();
  }
}

TEST_P(ModelGradientTest, JacobianEqualsRowsFromBackward) {
  const GradientCase& c = GetParam();
  const auto model = make_one_step_map(nlohmann::json::parse(c.spec));
  Rng rng(77, c.spec);
  const Vector theta = random_theta(*model, rng, c.theta_stddev, c.beta);
  const Vector z = rng.normal_matrix(model->dim(), 1, 1.0);
  const Vector h = random_steps(1, rng);
  ForwardCache cache;
  model->forward(theta, z, h, &cache);
  // Row i of DΦ̂ is dL/dz for L = e_iᵀ Φ̂(z).
  Matrix from_backward(model->dim(), model->dim());
  Vector grad = Vector::Zero(model->n_params());
  Matrix dz_in;
  for (Index i = 0; i < model->dim(); ++i) {
    model->backward(theta, cache, Matrix::Identity(model->dim(), model->dim()).col(i), grad,
                    &dz_in);
    from_backward.row(i) = dz_in.col(0).transpose();
  }
  const Matrix forward_mode = model->jacobian(theta, z, h(0));
  EXPECT_LE((forward_mode - from_backward).norm(), 1e-13 * (1.0 + forward_mode.norm()))
      << "forward mode\n"
      << forward_mode << "\nreverse mode\n"
      << from_backward;
}

INSTANTIATE_TEST_SUITE_P(
    Cores, ModelGradientTest,
    ::testing::Values(
        GradientCase{R"({"type":"la","d":1,"layers":1,"sublayers":1})", 0.5, 0.0},
        GradientCase{R"({"type":"la","d":1,"layers":3,"sublayers":4})", 0.3, 0.0},
        GradientCase{R"({"type":"la","d":1,"layers":5,"sublayers":20})", 0.3, 0.0},
        GradientCase{R"({"type":"la","d":3,"layers":2,"sublayers":3})", 0.3, 0.0},
        GradientCase{R"({"type":"la","d":3,"layers":4,"sublayers":2})", 0.3, 0.0},
        GradientCase{R"({"type":"la","d":10,"layers":2,"sublayers":2})", 0.2, 0.0},
        // Step polynomials: the coefficients c are drawn like every entry.
        GradientCase{R"({"type":"la","d":1,"layers":3,"sublayers":4,"step_terms":2})", 0.5, 0.0},
        GradientCase{R"({"type":"la","d":3,"layers":3,"sublayers":3,"step_terms":2})", 0.5, 0.0},
        GradientCase{R"({"type":"g","d":1,"layers":2,"width":5})", 0.5, 0.0},
        GradientCase{R"({"type":"g","d":3,"layers":3,"width":4})", 0.5, 0.0},
        GradientCase{R"({"type":"g","d":2,"layers":4,"width":7})", 0.4, 0.0},
        GradientCase{R"({"type":"g","d":10,"layers":2,"width":8})", 0.3, 0.0}));

INSTANTIATE_TEST_SUITE_P(
    Wrappers, ModelGradientTest,
    ::testing::Values(
        GradientCase{R"({"type":"sympnet","d":1,"core":{"type":"la","layers":3,"sublayers":3}})",
                     0.3, 0.0},
        GradientCase{R"({"type":"sympnet","d":3,"core":{"type":"g","layers":3,"width":4}})", 0.4,
                     0.0},
        GradientCase{R"({"type":"csympnet","d":1,"core":{"type":"la","layers":3,"sublayers":4}})",
                     0.3, 0.7},
        GradientCase{R"({"type":"csympnet","d":1,"core":{"type":"la","layers":5,"sublayers":20}})",
                     0.3, -0.4},
        GradientCase{R"({"type":"csympnet","d":3,"core":{"type":"la","layers":3,"sublayers":2}})",
                     0.3, -1.3},
        GradientCase{R"({"type":"csympnet","d":1,"core":{"type":"g","layers":3,"width":5}})", 0.5,
                     -0.8},
        GradientCase{
            R"({"type":"csympnet","d":1,"core":{"type":"la","layers":5,"sublayers":20,"step_terms":2}})",
            0.3, 0.6},
        GradientCase{
            R"({"type":"csympnet","d":2,"core":{"type":"la","layers":3,"sublayers":2,"step_terms":2}})",
            0.4, -0.9},
        GradientCase{R"({"type":"csympnet","d":3,"core":{"type":"g","layers":4,"width":6}})", 0.4,
                     1.5}));

}  // namespace
}  // namespace csympnet::testing
