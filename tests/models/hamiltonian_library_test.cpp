// The Hamiltonian-library map (src/models/hamiltonian_library.hpp) and its terms
// (models/potential_library.hpp):
//   - every term's derivatives against central differences, at random arguments and κ;
//   - the map's three derivative paths against central differences, at random parameters
//     and coordinate scales, for d = 1, 2, 3, full and diagonal masses, orders 2, 4, 6, one and
//     several substeps;
//   - exact conformal symplecticity DΦᵀ J DΦ = e^{−γh} J at random parameters;
//   - the order of the composition: on a damped oscillator the error falls as (h/n)^order;
//   - names and specs round-trip, and bad ones are refused with the reason.
#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/models/potential_library.hpp"
#include "support/gradient_check.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet::testing {
namespace {

TEST(PotentialLibrary, EveryNameRoundTrips) {
  for (Index d = 1; d <= 6; ++d) {
    const std::vector<LibraryTerm> lib = full_library(d);
    for (const LibraryTerm& t : lib) {
      const std::string name = term_name(t);
      EXPECT_EQ(parse_term(name, d, "test"), t) << name;
    }
    // 8 per coordinate, 7 per pair (all pairs up to d = 4, neighbours beyond).
    const Index pairs = d <= 4 ? d * (d - 1) / 2 : d - 1;
    EXPECT_EQ(static_cast<Index>(lib.size()), 8 * d + 7 * pairs) << "d = " << d;
  }
  EXPECT_EQ(term_name(parse_term("exp(q2-q1)", 2, "t")), "exp(q2-q1)");
  EXPECT_EQ(term_name(parse_term("(q1-q3)^4", 3, "t")), "(q1-q3)^4");
}

TEST(PotentialLibrary, BadNamesAreRefusedWithTheReason) {
  const auto message = [](const std::string& name, Index d) {
    try {
      parse_term(name, d, "spec.terms");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message("q3^2", 2).find("out of range"), std::string::npos);
  EXPECT_NE(message("q1^5", 1).find("power"), std::string::npos);
  EXPECT_NE(message("(q1-q1)^2", 2).find("itself"), std::string::npos);
  EXPECT_NE(message("tan(q1)", 1).find("not a library term"), std::string::npos);
  EXPECT_NE(message("sin(q2-q1)", 2).find("write it as 'sin(q1-q2)'"), std::string::npos);
  EXPECT_NE(message("sin(-q1)", 1).find("minus sign"), std::string::npos);
  EXPECT_NE(message("(q1-q2)^1", 2).find("2..4"), std::string::npos);
}

TEST(PotentialLibrary, TermDerivativesMatchCentralDifferences) {
  Rng rng(3, "term-derivatives");
  for (const LibraryTerm& t : full_library(2)) {
    for (int rep = 0; rep < 20; ++rep) {
      const double u = rng.uniform(-1.5, 1.5), kappa = rng.uniform(-2.0, 2.0);
      const double du = 1e-6, dk = 1e-6;
      const TermValues v = term_values(t, u, kappa);
      const TermValues up = term_values(t, u + du, kappa), um = term_values(t, u - du, kappa);
      const TermValues kp = term_values(t, u, kappa + dk), km = term_values(t, u, kappa - dk);
      const auto close = [](double a, double b) {
        return std::abs(a - b) <= 1e-7 * std::max(1.0, std::abs(a));
      };
      EXPECT_TRUE(close(v.d1, (up.phi - um.phi) / (2 * du))) << term_name(t) << " d1";
      EXPECT_TRUE(close(v.d2, (up.d1 - um.d1) / (2 * du))) << term_name(t) << " d2";
      if (!t.has_wavenumber()) continue;
      EXPECT_TRUE(close(v.d1_kappa, (kp.d1 - km.d1) / (2 * dk))) << term_name(t) << " d1_kappa";
      EXPECT_TRUE(close(v.phi_kappa, (kp.phi - km.phi) / (2 * dk))) << term_name(t);
    }
  }
}

// A random library map: a random subset of the full library (every family represented for
// d ≤ 2), random parameters of moderate size.
struct MapCase {
  Index d;
  int order;
  Index substeps;
  bool full_mass;
};

HamiltonianLibraryMap random_map(const MapCase& c, Rng& rng) {
  std::vector<LibraryTerm> terms;
  for (const LibraryTerm& t : full_library(c.d))
    if (rng.uniform(0.0, 1.0) < 0.6) terms.push_back(t);
  if (terms.empty()) terms.push_back(full_library(c.d).front());
  Vector scales(c.d);  // weights of the coordinates in differences
  for (Index i = 0; i < c.d; ++i) scales(i) = rng.uniform(0.5, 2.0);
  return HamiltonianLibraryMap(c.d, terms, c.order, c.substeps, c.full_mass, 0.1, scales);
}

Vector random_library_theta(const HamiltonianLibraryMap& map, Rng& rng, double beta) {
  Vector theta(map.n_params());
  Rng init(1, "unused");
  map.init_params(init, theta);
  for (Index k = 0; k < static_cast<Index>(map.terms().size()); ++k) {
    theta(map.coefficient_index(k)) = rng.normal() * 0.3;
    if (map.wavenumber_index(k) >= 0)
      theta(map.wavenumber_index(k)) = map.terms()[k].kappa_sign * rng.uniform(0.3, 1.5);
  }
  for (Index k = 0; k < map.mass_size(); ++k) theta(k) += 0.2 * rng.normal();
  theta(*map.damping_param_index()) = beta;
  return theta;
}

class LibraryMapTest : public ::testing::TestWithParam<MapCase> {};

TEST_P(LibraryMapTest, DerivativesMatchCentralDifferences) {
  Rng rng(11 + GetParam().d * 7 + GetParam().order, "library-fd");
  for (int rep = 0; rep < 4; ++rep) {
    const HamiltonianLibraryMap map = random_map(GetParam(), rng);
    Vector theta;
    Matrix z;
    Vector h(3);
    // Redrawn until the map is finite there (an exp or a negative quartic can blow up).
    for (int draw = 0; draw == 0 || !map.apply(theta, z, h).allFinite(); ++draw) {
      ASSERT_LT(draw, 20) << "no finite draw";
      theta = random_library_theta(map, rng, rep % 2 == 0 ? 0.4 : -0.3);
      z = rng.normal_matrix(map.dim(), 3, 0.6);
      for (Index j = 0; j < 3; ++j) h(j) = rng.uniform(0.05, 0.3);
    }
    FdOptions o;
    o.tolerance = 1e-6;
    const ModelCheck check = check_one_step_map(map, theta, z, h, rng, o);
    EXPECT_TRUE(check.ok()) << check.report();
  }
}

TEST_P(LibraryMapTest, ConformallySymplecticAtRandomParameters) {
  Rng rng(21 + GetParam().d, "library-structure");
  double worst = 0.0;
  for (int rep = 0; rep < 50; ++rep) {
    const HamiltonianLibraryMap map = random_map(GetParam(), rng);
    const double beta = (rep % 2 == 0 ? 1.0 : -1.0) * rng.uniform(0.05, 3.0);
    const Vector theta = random_library_theta(map, rng, beta);
    const Vector z = rng.normal_matrix(map.dim(), 1, 0.6);
    const double h = rng.uniform(0.05, 0.4);
    const Matrix jac = map.jacobian(theta, z, h);
    const double lambda = std::exp(-std::abs(beta) * h);
    worst = std::max(worst, conformal_residual(jac, lambda) / std::max(1.0, jac.squaredNorm()));
  }
  std::cout << "  worst ||DPhi^T J DPhi - exp(-gamma h) J||_F / ||DPhi||^2 = " << worst << "\n";
  EXPECT_LE(worst, 1e-13);
}

INSTANTIATE_TEST_SUITE_P(Cases, LibraryMapTest,
                         ::testing::Values(MapCase{1, 2, 1, true}, MapCase{1, 4, 3, true},
                                           MapCase{1, 6, 1, false}, MapCase{2, 4, 2, true},
                                           MapCase{2, 4, 1, false}, MapCase{3, 6, 2, true}));

// The damped oscillator q̈ + γq̇ + ω²q = 0 (H = ½p² + ½ω²q²) has the exact one-step map
// e^{Ah}; the composed conformal Strang steps approach it as (h/n)^order.
TEST(LibraryMapOrder, ErrorFallsAsTheOrderSays) {
  const double omega = 2.0, gamma = 0.3, h = 0.5;
  Matrix a(2, 2);
  a << 0.0, 1.0, -omega * omega, -gamma;
  // e^{Ah} by a long Taylor series on h/64, squared six times.
  Matrix e = Matrix::Identity(2, 2), term = Matrix::Identity(2, 2);
  for (int k = 1; k < 30; ++k) {
    term = term * a * (h / 64.0) / static_cast<double>(k);
    e += term;
  }
  for (int k = 0; k < 6; ++k) e = e * e;
  const Vector z0 = (Vector(2) << 0.7, -0.2).finished();
  const Vector exact = e * z0;
  for (int order : {2, 4, 6}) {
    double previous = 0.0;
    for (Index n : {2, 4, 8}) {
      HamiltonianLibraryMap map(1, {parse_term("q1^2", 1, "t")}, order, n, true, gamma);
      Vector theta(map.n_params());
      Rng r(1, "x");
      map.init_params(r, theta);
      theta(map.coefficient_index(0)) = 0.5 * omega * omega;
      const Vector out = map.apply(theta, z0, Vector::Constant(1, h));
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

TEST(LibraryMapSpec, HyperparamsRebuildTheSameMap) {
  HamiltonianLibraryMap map(2, {parse_term("q1^2", 2, "t"), parse_term("cos(q1-q2)", 2, "t")}, 4, 3,
                            false, 0.2, (Vector(2) << 1.5, 0.7).finished());
  const auto rebuilt = make_one_step_map(map.hyperparams());
  EXPECT_EQ(rebuilt->hyperparams(), map.hyperparams());
  Rng rng(4, "spec");
  const Vector theta = random_library_theta(map, rng, 0.2);
  const Matrix z = rng.normal_matrix(4, 5, 0.5);
  const Vector h = Vector::Constant(5, 0.1);
  EXPECT_EQ(rebuilt->apply(theta, z, h), map.apply(theta, z, h));
  nlohmann::json bad = map.hyperparams();
  bad["core"]["order"] = 3;
  EXPECT_THROW(make_one_step_map(bad), Error);
  bad = map.hyperparams();
  bad["core"]["terms"] = nlohmann::json::array();
  EXPECT_THROW(make_one_step_map(bad), Error);
  bad = map.hyperparams();
  bad["core"]["wavenumbers"] = 1;
  EXPECT_THROW(make_one_step_map(bad), Error);
  bad = map.hyperparams();
  bad["core"]["coordinate_scales"] = {1.0, -1.0};
  EXPECT_THROW(make_one_step_map(bad), Error);
}

}  // namespace
}  // namespace csympnet::testing
