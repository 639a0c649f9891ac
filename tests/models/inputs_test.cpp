// Known inputs of the Hamiltonian-library map (models/inputs.hpp; docs/derivations.md, "Known
// inputs"): H = H₀ − qᵀB u(t), the input a force in each kick.
//   - the map's derivative paths with inputs (reverse mode for θ, B included, and for the input
//     state; the forward-mode input Jacobian) against central differences, at random parameters
//     and inputs, both holds, d = 1, 2, full and diagonal masses, orders 2, 4, 6;
//   - exact conformal symplecticity DΦᵀJDΦ = e^{−γh}J at random parameters and random inputs;
//   - the order of the composition for the forced flow (an input linear in time, which both
//     holds of the right kind represent exactly: the error falls as (h/n)^order), and the cost
//     of the hold for a smooth input (first-order hold: global error ∝ h², zero-order: ∝ h);
//   - zero input, and no input at all, give the free map to the bit;
//   - specs and model files carry m and the hold; bad ones are refused with the reason, and a
//     free map refuses inputs.
#include <cmath>
#include <functional>
#include <iostream>

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/models/inputs.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "support/driven_derivative_check.hpp"
#include "support/gradient_check.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet::testing {
namespace {

struct DrivenCase {
  Index d;
  Index m;
  int order;
  Index substeps;
  bool full_mass;
  InputHold hold;
};

std::vector<LibraryTerm> some_terms(Index d) {
  std::vector<std::string> names = {"q1^2", "q1^4", "cos(q1)"};
  if (d > 1) names.insert(names.end(), {"q2^2", "(q1-q2)^2", "sin(q2)"});
  std::vector<LibraryTerm> terms;
  for (const std::string& n : names) terms.push_back(parse_term(n, d, "test"));
  return terms;
}

HamiltonianLibraryMap driven_library_map(const DrivenCase& c) {
  return HamiltonianLibraryMap(c.d, some_terms(c.d), c.order, c.substeps, c.full_mass, 0.1, {}, {},
                               InputSpec{c.m, c.hold});
}

Vector driven_theta(const HamiltonianLibraryMap& map, Rng& rng, double beta) {
  Vector theta(map.n_params());
  Rng unused(1, "unused");
  map.init_params(unused, theta);
  for (Index k = 0; k < static_cast<Index>(map.terms().size()); ++k) {
    theta(map.coefficient_index(k)) = rng.uniform(0.1, 0.6);
    if (map.wavenumber_index(k) >= 0)
      theta(map.wavenumber_index(k)) = map.terms()[k].kappa_sign * rng.uniform(0.3, 1.5);
  }
  for (Index k = 0; k < map.mass_size(); ++k) theta(k) += 0.1 * rng.normal();
  theta(*map.damping_param_index()) = beta;
  for (Index r = 0; r < map.d(); ++r)
    for (Index j = 0; j < map.n_inputs(); ++j) theta(map.input_index(r, j)) = rng.normal();
  return theta;
}

class DrivenMapTest : public ::testing::TestWithParam<DrivenCase> {};

// L = ⟨G, Φ̂(Z; U)⟩ by θ and by Z through backward(); DΦ̂ at column 0 through jacobian_driven().
TEST_P(DrivenMapTest, DerivativesMatchCentralDifferences) {
  const DrivenCase c = GetParam();
  Rng rng(61 + c.d * 7 + c.order + c.m, "driven-fd");
  const HamiltonianLibraryMap map = driven_library_map(c);
  for (int rep = 0; rep < 3; ++rep) {
    const Vector theta = driven_theta(map, rng, rep % 2 == 0 ? 0.4 : -0.3);
    const Index n = 3;
    const Matrix z = rng.normal_matrix(map.dim(), n, 0.6);
    const Matrix u = rng.normal_matrix(2 * c.m, n, 1.0);
    const Vector h = rng.uniform_vector(n, 0.05, 0.3);
    const Matrix g = rng.normal_matrix(map.dim(), n, 1.0);
    const Vector grad = check_driven_derivatives(map, theta, z, h, u, g, 1e-6);
    // B's entries have a slope: the check above sees them (they are not all zero).
    double b_grad = 0.0;
    for (Index r = 0; r < c.d; ++r)
      for (Index j = 0; j < c.m; ++j) b_grad += std::abs(grad(map.input_index(r, j)));
    EXPECT_GT(b_grad, 1e-3);
  }
}

TEST_P(DrivenMapTest, ConformallySymplecticAtRandomParametersAndInputs) {
  const DrivenCase c = GetParam();
  Rng rng(71 + c.d + c.m, "driven-structure");
  const HamiltonianLibraryMap map = driven_library_map(c);
  double worst = 0.0;
  for (int rep = 0; rep < 50; ++rep) {
    const double beta = (rep % 2 == 0 ? 1.0 : -1.0) * rng.uniform(0.05, 3.0);
    const Vector theta = driven_theta(map, rng, beta);
    const Vector z = rng.normal_matrix(map.dim(), 1, 0.6);
    const Vector u = rng.normal_matrix(2 * c.m, 1, 2.0);
    const double h = rng.uniform(0.05, 0.4);
    const Matrix jac = map.jacobian_driven(theta, z, h, u);
    const double lambda = std::exp(-std::abs(beta) * h);
    worst = std::max(worst, conformal_residual(jac, lambda) / std::max(1.0, jac.squaredNorm()));
  }
  std::cout << "  worst ||DPhi^T J DPhi - exp(-gamma h) J||_F / ||DPhi||^2 with inputs = " << worst
            << "\n";
  EXPECT_LE(worst, 1e-13);
}

// With U = 0, and with no U at all, the driven map is the free map (θ's head) to the bit.
TEST_P(DrivenMapTest, ZeroInputGivesTheFreeMapToTheBit) {
  const DrivenCase c = GetParam();
  Rng rng(81 + c.d, "driven-zero");
  const HamiltonianLibraryMap with = driven_library_map(c);
  const HamiltonianLibraryMap without(c.d, some_terms(c.d), c.order, c.substeps, c.full_mass, 0.1);
  ASSERT_EQ(with.n_params(), without.n_params() + c.d * c.m);
  const Vector theta = driven_theta(with, rng, 0.3);
  const Vector head = theta.head(without.n_params());
  const Matrix z = rng.normal_matrix(with.dim(), 4, 0.6);
  const Vector h = rng.uniform_vector(4, 0.05, 0.3);
  const Matrix zero = Matrix::Zero(2 * c.m, 4);
  const Matrix bar = rng.normal_matrix(with.dim(), 4, 1.0);
  ForwardCache ca, cb, cc;
  const Matrix a = with.forward_driven(theta, z, h, zero, &ca);
  const Matrix b = without.forward(head, z, h, &cb);
  const Matrix free_pass = with.forward(theta, z, h, &cc);
  EXPECT_EQ(a, b);
  EXPECT_EQ(free_pass, b);
  EXPECT_EQ(with.jacobian_driven(theta, z.col(0), h(0), zero.col(0)),
            without.jacobian(head, z.col(0), h(0)));
  EXPECT_EQ(with.jacobian(theta, z.col(0), h(0)), without.jacobian(head, z.col(0), h(0)));
  Vector ga = Vector::Zero(with.n_params()), gb = Vector::Zero(without.n_params());
  Vector gc = Vector::Zero(with.n_params());
  Matrix da, db, dc;
  with.backward(theta, ca, bar, ga, &da);
  without.backward(head, cb, bar, gb, &db);
  with.backward(theta, cc, bar, gc, &dc);
  EXPECT_EQ(Vector(ga.head(without.n_params())), gb);
  EXPECT_EQ(Vector(gc.head(without.n_params())), gb);
  EXPECT_EQ(da, db);
  EXPECT_EQ(dc, db);
}

INSTANTIATE_TEST_SUITE_P(Cases, DrivenMapTest,
                         ::testing::Values(DrivenCase{1, 1, 2, 1, true, InputHold::kFirst},
                                           DrivenCase{1, 2, 4, 3, true, InputHold::kZero},
                                           DrivenCase{1, 1, 6, 2, false, InputHold::kFirst},
                                           DrivenCase{2, 2, 4, 2, true, InputHold::kFirst},
                                           DrivenCase{2, 1, 4, 1, false, InputHold::kZero},
                                           DrivenCase{2, 3, 6, 1, true, InputHold::kFirst}));

// The forced Duffing oscillator q̇ = p, ṗ = −ω²q − 4c q³ − γp + B u(t) (H₀ = ½p² + ½ω²q² + c q⁴),
// m = 2 inputs, integrated by classic RK4 with `steps` steps from t0 to t1 (its error, ∝
// (t1 − t0)/steps to the fourth, lies far below what the tests measure).
constexpr double kOmega = 2.0, kQuartic = 0.3, kGamma = 0.3;
const double kB[2] = {0.7, -0.4};

Vector reference_flow(Vector z, double t0, double t1, const std::function<Vector(double)>& u,
                      int steps) {
  const auto field = [&](const Vector& y, double t) {
    const Vector ut = u(t);
    Vector f(2);
    f(0) = y(1);
    f(1) = -kOmega * kOmega * y(0) - 4 * kQuartic * y(0) * y(0) * y(0) - kGamma * y(1) +
           kB[0] * ut(0) + kB[1] * ut(1);
    return f;
  };
  const double dt = (t1 - t0) / steps;
  for (int k = 0; k < steps; ++k) {
    const double t = t0 + k * dt;
    const Vector k1 = field(z, t), k2 = field(z + 0.5 * dt * k1, t + 0.5 * dt);
    const Vector k3 = field(z + 0.5 * dt * k2, t + 0.5 * dt), k4 = field(z + dt * k3, t + dt);
    z += dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  return z;
}

HamiltonianLibraryMap duffing_map(int order, Index n, InputHold hold, Vector& theta) {
  HamiltonianLibraryMap map(1, {parse_term("q1^2", 1, "t"), parse_term("q1^4", 1, "t")}, order, n,
                            true, kGamma, {}, {}, InputSpec{2, hold});
  theta.resize(map.n_params());
  Rng r(1, "x");
  map.init_params(r, theta);
  theta(map.coefficient_index(0)) = 0.5 * kOmega * kOmega;
  theta(map.coefficient_index(1)) = kQuartic;
  theta(map.input_index(0, 0)) = kB[0];
  theta(map.input_index(0, 1)) = kB[1];
  return map;
}

// An input linear in time is what the first-order hold represents exactly: the one-step error
// then falls as (h/n)^order, so the stages' kick times are right (a kick at the wrong time costs
// an error of first order, whatever the composition).
TEST(DrivenMapOrder, ErrorFallsAsTheOrderSaysForAnInputLinearInTime) {
  const double t0 = 0.3, h = 0.5;
  const auto u = [](double t) {
    return Vector((Vector(2) << 0.8 - 1.5 * t, 0.2 + 2.0 * t).finished());
  };
  const Vector z0 = (Vector(2) << 0.7, -0.2).finished();
  const Vector exact = reference_flow(z0, t0, t0 + h, u, 4000);
  Vector ucol(4);
  ucol << u(t0), u(t0 + h);
  for (int order : {2, 4, 6}) {
    double previous = 0.0;
    for (Index n : {2, 4, 8}) {
      Vector theta;
      const HamiltonianLibraryMap map = duffing_map(order, n, InputHold::kFirst, theta);
      const Vector out =
          map.forward_driven(theta, z0, Vector::Constant(1, h), ucol, nullptr).col(0);
      const double err = (out - exact).norm();
      if (n > 2) {
        const double rate = std::log2(previous / err);
        std::cout << "  order " << order << ", n = " << n << ": error " << err << ", rate " << rate
                  << "\n";
        EXPECT_NEAR(rate, order, 0.35) << "order " << order << " n " << n;
      }
      previous = err;
    }
  }
}

// A smooth input sampled every h: the hold's error dominates a map of order 4 with 4 substeps.
// Over a fixed horizon the first-order hold's error falls as h², the zero-order hold's as h.
TEST(DrivenMapOrder, TheHoldCostsOrderTwoOrOneForASmoothInput) {
  const auto u = [](double t) {
    return Vector((Vector(2) << std::sin(3.0 * t), std::cos(1.7 * t + 0.4)).finished());
  };
  const Vector z0 = (Vector(2) << 0.7, -0.2).finished();
  const double horizon = 2.0;
  const Vector exact = reference_flow(z0, 0.0, horizon, u, 20000);
  for (InputHold hold : {InputHold::kFirst, InputHold::kZero}) {
    double previous = 0.0;
    for (int steps : {20, 40, 80}) {
      Vector theta;
      const HamiltonianLibraryMap map = duffing_map(4, 4, hold, theta);
      const double h = horizon / steps;
      Vector z = z0, ucol(4);
      for (int k = 0; k < steps; ++k) {
        ucol << u(k * h), u((k + 1) * h);
        z = map.forward_driven(theta, z, Vector::Constant(1, h), ucol, nullptr).col(0);
      }
      const double err = (z - exact).norm();
      if (steps > 20) {
        const double rate = std::log2(previous / err);
        const double expected = hold == InputHold::kFirst ? 2.0 : 1.0;
        std::cout << "  " << hold_name(hold) << ", h = " << h << ": error " << err << ", rate "
                  << rate << "\n";
        EXPECT_NEAR(rate, expected, 0.2) << hold_name(hold) << " steps " << steps;
      }
      previous = err;
    }
  }
}

TEST(DrivenMapSpec, ModelFilesCarryTheInputsAndBadOnesAreRefused) {
  Vector theta;
  const HamiltonianLibraryMap map = duffing_map(4, 2, InputHold::kZero, theta);
  const nlohmann::json spec = map.hyperparams();
  EXPECT_EQ(spec["core"]["inputs"],
            nlohmann::json({{"m", 2}, {"hold", "zoh"}, {"B", "row-major"}}));
  const auto rebuilt = make_one_step_map(spec);
  EXPECT_EQ(rebuilt->hyperparams(), spec);
  EXPECT_EQ(rebuilt->n_inputs(), 2);
  EXPECT_EQ(rebuilt->n_params(), map.n_params());
  const Matrix z = (Matrix(2, 1) << 0.3, 0.1).finished();
  const Matrix u = (Matrix(4, 1) << 0.5, -1.0, 0.2, 0.3).finished();
  EXPECT_EQ(rebuilt->forward_driven(theta, z, Vector::Constant(1, 0.2), u, nullptr),
            map.forward_driven(theta, z, Vector::Constant(1, 0.2), u, nullptr));
  // The default hold is first order; a free map's spec has no "inputs" key.
  nlohmann::json foh = spec;
  foh["core"]["inputs"].erase("hold");
  const auto* lib = dynamic_cast<const HamiltonianLibraryMap*>(make_one_step_map(foh).get());
  ASSERT_NE(lib, nullptr);
  const HamiltonianLibraryMap free_map(1, {parse_term("q1^2", 1, "t")}, 4, 1, true, 0.1);
  EXPECT_FALSE(free_map.hyperparams()["core"].contains("inputs"));
  const auto refused = [&](const nlohmann::json& inputs, const std::string& words) {
    nlohmann::json bad = spec;
    bad["core"]["inputs"] = inputs;
    try {
      make_one_step_map(bad);
      ADD_FAILURE() << "accepted " << inputs.dump();
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  refused({{"m", 0}}, "key 'm' must be an integer from 1");
  refused({{"m", 1}, {"hold", "cubic"}}, "hold 'cubic', expected \"foh\"");
  refused({{"m", 1}, {"B", "column-major"}}, "expected \"row-major\"");
  refused({{"m", 1}, {"gain", 2}}, "unknown key 'gain'");
  refused(3, "expected an object");
  // Inputs of the wrong shape, and inputs to a free map.
  EXPECT_THROW(map.forward_driven(theta, z, Vector::Constant(1, 0.2), Matrix::Zero(2, 1), nullptr),
               Error);
  EXPECT_THROW(map.jacobian_driven(theta, z.col(0), 0.2, Vector::Zero(3)), Error);
  Vector free_theta(free_map.n_params());
  Rng r(1, "x");
  free_map.init_params(r, free_theta);
  try {
    free_map.forward_driven(free_theta, z, Vector::Constant(1, 0.2), u, nullptr);
    ADD_FAILURE() << "a free map took inputs";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("this map takes no inputs"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace csympnet::testing
