// LA-SympNet with step polynomials (step_terms = 2): the coefficients are extra parameters that
// leave the paper's core unchanged at c = 0, and give Ψ_h an h-dependence the paper's core
// cannot have (docs/identification.md, "An h-dependent core").
#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet::testing {
namespace {

nlohmann::json la(Index d, Index step_terms) {
  nlohmann::json spec = {{"type", "la"}, {"d", d}, {"layers", 3}, {"sublayers", 4}};
  if (step_terms != 1) spec["step_terms"] = step_terms;
  return spec;
}

// At c = 0 the map, its parameter gradient (on the shared entries) and its Jacobian are those
// of the paper's core, to the bit, for the scalar (d = 1) and the matrix (d = 3) code paths.
TEST(StepPolynomial, ZeroCoefficientsGiveThePapersCoreToTheBit) {
  for (const Index d : {Index{1}, Index{3}}) {
    SCOPED_TRACE("d = " + std::to_string(d));
    const auto plain = make_one_step_map(la(d, 1));
    const auto poly = make_one_step_map(la(d, 2));
    // L m + L - 1 coefficients.
    ASSERT_EQ(poly->n_params(), plain->n_params() + 3 * 4 + 2);
    Rng rng(3, "step-poly");
    const Vector theta = random_theta(*plain, rng, 0.4);
    Vector theta2 = Vector::Zero(poly->n_params());
    theta2.head(plain->n_params()) = theta;
    const Matrix z = rng.normal_matrix(2 * d, 6, 1.0);
    const Vector h = random_steps(6, rng);

    ForwardCache c1, c2;
    const Matrix out1 = plain->forward(theta, z, h, &c1);
    const Matrix out2 = poly->forward(theta2, z, h, &c2);
    EXPECT_EQ(out1, out2);
    const Matrix up = rng.normal_matrix(2 * d, 6, 1.0);
    Vector g1 = Vector::Zero(plain->n_params()), g2 = Vector::Zero(poly->n_params());
    Matrix dz1, dz2;
    plain->backward(theta, c1, up, g1, &dz1);
    poly->backward(theta2, c2, up, g2, &dz2);
    EXPECT_EQ(g1, g2.head(plain->n_params()));
    EXPECT_EQ(dz1, dz2);
    EXPECT_TRUE(g2.tail(poly->n_params() - plain->n_params()).allFinite());
    EXPECT_EQ(plain->jacobian(theta, z.col(0), 0.1), poly->jacobian(theta2, z.col(0), 0.1));
  }
}

// A coefficient c of one unit acts as that unit's step h (1 + c h): moving it changes Ψ_h
// by an amount that grows like h², unlike any rescaling of the unit's own parameters, which
// scales with h.
TEST(StepPolynomial, ACoefficientActsAtSecondOrderInTheStep) {
  const auto poly = make_one_step_map(la(1, 2));
  Rng rng(9, "step-poly-order");
  Vector theta = random_theta(*poly, rng, 0.4);
  constexpr Index kCoefficients = 3 * 4 + 2;
  theta.tail(kCoefficients).setZero();
  Vector moved = theta;
  moved(poly->n_params() - kCoefficients) = 0.5;  // the first linear sublayer's coefficient
  const Vector z = rng.normal_matrix(2, 1, 1.0);
  double previous = 0.0;
  for (const double h : {0.2, 0.1, 0.05}) {
    const Vector hv = Vector::Constant(1, h);
    const double change = (poly->apply(moved, z, hv) - poly->apply(theta, z, hv)).norm();
    if (previous > 0.0) {
      EXPECT_NEAR(previous / change, 4.0, 0.4) << "h = " << h;  // ~h²
    }
    previous = change;
  }
}

TEST(StepPolynomial, SpecRoundTripsAndBadValuesAreRefused) {
  const auto poly = make_one_step_map(la(2, 2));
  EXPECT_EQ(poly->hyperparams().at("step_terms"), 2);
  EXPECT_FALSE(make_one_step_map(la(2, 1))->hyperparams().contains("step_terms"));
  EXPECT_EQ(make_one_step_map(poly->hyperparams())->n_params(), poly->n_params());
  for (const int bad : {0, 3}) {
    try {
      make_one_step_map(la(2, bad));
      ADD_FAILURE() << "step_terms " << bad << " accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("step_terms"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace csympnet::testing
