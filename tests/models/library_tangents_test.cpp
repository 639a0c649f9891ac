// Forward-mode step sensitivities of the Hamiltonian-library map (step_tangents; docs/
// derivations.md, "Forward-mode sensitivities"), at random parameters, states, steps and inputs,
// with every term of the library (powers, sin, cos, exp, differences under unequal coordinate
// scales), d = 1, 2, 3, orders 2, 4, 6, one or two substeps, full and diagonal masses, free and
// driven (both holds):
//   - the state ends with the bits of forward_driven();
//   - the state columns are jacobian_driven() (to rounding), and the θ columns are the reverse
//     mode's rows of ∂Φ̂/∂θ (to rounding) and central differences;
//   - the map on t is linear: t ← DΦ̂ t + [∂Φ̂/∂θ | 0] for any t, and θ's columns beyond n_theta
//     are only carried;
//   - with dissipation terms (Coulomb friction inside the kicks or beside them, drag), the same,
//     away from the stick set (where the flow is not differentiable);
//   - maps without them (the neural cores) refuse, as do wrong shapes.
#include <algorithm>
#include <cmath>
#include <ostream>
#include <string>

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "support/gradient_check.hpp"

namespace csympnet::testing {
namespace {

struct TangentCase {
  Index d;
  int order;
  Index substeps;
  bool full_mass;
  Index m;
  InputHold hold;
  // "": none; else the dissipation terms, e.g. "coulomb(p1),drag(p2)".
  const char* dissipation = "";
  bool coulomb_in_kicks = true;
};

void PrintTo(const TangentCase& c, std::ostream* os) {
  *os << "d=" << c.d << " order=" << c.order << " substeps=" << c.substeps
      << (c.full_mass ? " full" : " diagonal") << " m=" << c.m
      << (c.hold == InputHold::kZero ? " zoh" : " foh") << " dissipation=[" << c.dissipation
      << (c.coulomb_in_kicks ? "]" : "] split");
}

std::vector<DissipationTerm> dissipation_of(const TangentCase& c) {
  std::vector<DissipationTerm> out;
  std::string names = c.dissipation;
  while (!names.empty()) {
    const auto comma = names.find(',');
    out.push_back(parse_dissipation(names.substr(0, comma), c.d, "test"));
    names = comma == std::string::npos ? "" : names.substr(comma + 1);
  }
  return out;
}

HamiltonianLibraryMap tangent_map(const TangentCase& c, Rng& rng) {
  const Vector scales = rng.uniform_vector(c.d, 0.5, 2.0);
  return HamiltonianLibraryMap(c.d, full_library(c.d), c.order, c.substeps, c.full_mass, 0.1,
                               scales, dissipation_of(c), InputSpec{c.m, c.hold},
                               c.coulomb_in_kicks);
}

// Small random coefficients (every term's slope enters), wavenumbers of either size, a mass
// near I, β of either sign, B ~ N(0, 1).
Vector random_tangent_theta(const HamiltonianLibraryMap& map, Rng& rng, double beta) {
  Vector theta(map.n_params());
  Rng unused(1, "unused");
  map.init_params(unused, theta);
  for (Index k = 0; k < static_cast<Index>(map.terms().size()); ++k) {
    theta(map.coefficient_index(k)) += rng.uniform(-0.1, 0.1);
    if (map.wavenumber_index(k) >= 0)
      theta(map.wavenumber_index(k)) = map.terms()[k].kappa_sign * rng.uniform(0.3, 1.2);
  }
  for (Index k = 0; k < map.mass_size(); ++k) theta(k) += 0.05 * rng.normal();
  theta(*map.damping_param_index()) = beta;
  for (Index r = 0; r < map.d(); ++r)
    for (Index j = 0; j < map.n_inputs(); ++j) theta(map.input_index(r, j)) = rng.normal();
  // Rates of either sign (the rate is |θ|), small enough that no momentum below reaches 0.
  for (Index k = 0; k < static_cast<Index>(map.dissipation().size()); ++k)
    theta(map.dissipation_index(k)) = (k % 2 == 0 ? 1.0 : -1.0) * rng.uniform(0.005, 0.05);
  return theta;
}

// One random draw of everything a step takes.
struct Draw {
  Vector theta, z, u;
  double h = 0.0;
};
Draw draw(const HamiltonianLibraryMap& map, Rng& rng, int rep) {
  Draw x;
  x.theta = random_tangent_theta(map, rng, (rep % 2 == 0 ? 1.0 : -1.0) * rng.uniform(0.05, 1.0));
  x.z = rng.normal_matrix(map.dim(), 1, 0.5);
  // With dissipation terms, momenta of 0.5 to 1 in size: over a step the kicks and the friction
  // move them by less than that, so no flow reaches the stick set or its kink.
  if (!map.dissipation().empty())
    for (Index r = 0; r < map.d(); ++r)
      x.z(map.d() + r) = (rng.uniform(0.0, 1.0) < 0.5 ? -1.0 : 1.0) * rng.uniform(0.5, 1.0);
  x.u = map.n_inputs() > 0 ? Vector(rng.normal_matrix(2 * map.n_inputs(), 1, 1.0)) : Vector();
  x.h = rng.uniform(0.05, 0.3);
  return x;
}

const double* input_of(const Draw& x) {
  return x.u.size() > 0 ? x.u.data() : nullptr;
}

Matrix step_of(const HamiltonianLibraryMap& map, const Vector& theta, const Draw& x) {
  Vector h(1);
  h(0) = x.h;
  if (x.u.size() == 0) return map.forward(theta, x.z, h, nullptr);
  return map.forward_driven(theta, x.z, h, x.u, nullptr);
}

// ∂Φ̂/∂θ (2d × P) by reverse mode: one backward pass per output component.
Matrix reverse_rows(const HamiltonianLibraryMap& map, const Draw& x) {
  Vector h(1);
  h(0) = x.h;
  ForwardCache cache;
  const Matrix u = x.u.size() > 0 ? Matrix(x.u) : Matrix();
  map.forward_driven(x.theta, x.z, h, u, &cache);
  Matrix rows(map.dim(), map.n_params());
  for (Index i = 0; i < map.dim(); ++i) {
    Matrix bar = Matrix::Zero(map.dim(), 1);
    bar(i, 0) = 1.0;
    Vector grad = Vector::Zero(map.n_params());
    map.backward(x.theta, cache, bar, grad, nullptr);
    rows.row(i) = grad.transpose();
  }
  return rows;
}

double relative(const Matrix& a, const Matrix& b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(1.0, b.cwiseAbs().maxCoeff());
}

class LibraryTangentTest : public ::testing::TestWithParam<TangentCase> {};

TEST_P(LibraryTangentTest, TheStateHasForwardsBitsAndTheColumnsAreTheStepsDerivatives) {
  const TangentCase c = GetParam();
  Rng rng(300 + 17 * c.d + c.order + 3 * c.substeps + 5 * c.m, "library-tangents");
  const HamiltonianLibraryMap map = tangent_map(c, rng);
  const Index dim = map.dim(), p = map.n_params();
  ASSERT_TRUE(map.has_step_tangents());
  double worst_state = 0.0, worst_theta = 0.0;
  for (int rep = 0; rep < 6; ++rep) {
    const Draw x = draw(map, rng, rep);
    Matrix t = Matrix::Zero(dim, p + dim);
    t.rightCols(dim).setIdentity();
    Vector z = x.z;
    map.step_tangents(x.theta, x.h, input_of(x), z.data(), t, p);
    const Vector ref = step_of(map, x.theta, x).col(0);
    for (Index i = 0; i < dim; ++i) EXPECT_EQ(z(i), ref(i)) << "component " << i;
    const Matrix jac = x.u.size() > 0 ? map.jacobian_driven(x.theta, x.z, x.h, x.u)
                                      : map.jacobian(x.theta, x.z, x.h);
    worst_state = std::max(worst_state, relative(t.rightCols(dim), jac));
    worst_theta = std::max(worst_theta, relative(t.leftCols(p), reverse_rows(map, x)));
    // And against central differences of the step in θ.
    FdOptions o;
    const auto step = [&](const Vector& th) { return Vector(step_of(map, th, x).col(0)); };
    const CheckResult fd = compare(t.leftCols(p), fd_jacobian(step, x.theta, o), 1e-6);
    EXPECT_TRUE(fd.ok()) << fd.report("d step / d theta");
  }
  EXPECT_LE(worst_state, 1e-12);
  EXPECT_LE(worst_theta, 1e-12);
}

// t ← DΦ̂ t + [∂Φ̂/∂θ_0 … ∂Φ̂/∂θ_{n−1} | 0] for any t and any n_theta ≤ P.
TEST_P(LibraryTangentTest, TheMapOnTheTangentsIsLinearAndAddsOnlyTheFirstColumns) {
  const TangentCase c = GetParam();
  Rng rng(400 + 17 * c.d + c.order + 3 * c.substeps + 5 * c.m, "library-tangents-linear");
  const HamiltonianLibraryMap map = tangent_map(c, rng);
  const Index dim = map.dim(), p = map.n_params();
  for (int rep = 0; rep < 4; ++rep) {
    const Draw x = draw(map, rng, rep);
    const Index n_theta = rep * p / 3;  // 0, a third, two thirds, all
    const Index cols = n_theta + 3;
    const Matrix t0 = rng.normal_matrix(dim, cols, 1.0);
    Matrix t = t0;
    Vector z = x.z;
    map.step_tangents(x.theta, x.h, input_of(x), z.data(), t, n_theta);
    const Matrix jac = x.u.size() > 0 ? map.jacobian_driven(x.theta, x.z, x.h, x.u)
                                      : map.jacobian(x.theta, x.z, x.h);
    Matrix expected = jac * t0;
    expected.leftCols(n_theta) += reverse_rows(map, x).leftCols(n_theta);
    EXPECT_LE(relative(t, expected), 1e-12) << "n_theta = " << n_theta;
  }
}

// Every shape of the library at d = 1, 2, 3 (the difference terms from d = 2), each order, one
// and two substeps, both masses, free and driven under both holds; dissipation terms inside the
// kicks and beside them.
INSTANTIATE_TEST_SUITE_P(
    Cases, LibraryTangentTest,
    ::testing::Values(TangentCase{1, 2, 1, true, 0, InputHold::kFirst},
                      TangentCase{1, 4, 2, true, 0, InputHold::kFirst},
                      TangentCase{1, 6, 2, true, 1, InputHold::kFirst},
                      TangentCase{1, 6, 1, false, 2, InputHold::kZero},
                      TangentCase{2, 4, 1, true, 0, InputHold::kFirst},
                      TangentCase{2, 6, 2, false, 0, InputHold::kFirst},
                      TangentCase{2, 4, 1, true, 2, InputHold::kZero},
                      TangentCase{3, 2, 2, true, 1, InputHold::kFirst},
                      TangentCase{3, 6, 1, false, 0, InputHold::kFirst},
                      TangentCase{1, 4, 1, true, 0, InputHold::kFirst, "coulomb(p1)"},
                      TangentCase{1, 6, 2, true, 1, InputHold::kFirst, "coulomb(p1),drag(p1)"},
                      TangentCase{1, 4, 1, true, 0, InputHold::kFirst, "coulomb(p1)", false},
                      TangentCase{2, 4, 2, true, 0, InputHold::kFirst, "drag(p2),coulomb(p1)"},
                      TangentCase{2, 6, 1, false, 2, InputHold::kZero,
                                  "coulomb(p1),coulomb(p2),drag(p1)", false}));

TEST(LibraryTangents, MapsWithoutThemRefuseAndShapesAreChecked) {
  const std::vector<LibraryTerm> terms = {parse_term("q1^2", 1, "test")};
  Rng rng(5, "refuse");
  Vector z = Vector::Ones(2);
  Matrix t = Matrix::Identity(2, 2);
  const HamiltonianLibraryMap free_map(1, terms, 4, 1, true, 0.1);
  Vector th(free_map.n_params());
  free_map.init_params(rng, th);
  Matrix wrong_rows = Matrix::Zero(3, 2);
  EXPECT_THROW(free_map.step_tangents(th, 0.1, nullptr, z.data(), wrong_rows, 0), Error);
  Matrix few_cols = Matrix::Zero(2, 1);
  EXPECT_THROW(free_map.step_tangents(th, 0.1, nullptr, z.data(), few_cols, 2), Error);
  const double u[2] = {1.0, 1.0};
  EXPECT_THROW(free_map.step_tangents(th, 0.1, u, z.data(), t, 0), Error);
  Vector short_theta = Vector::Zero(free_map.n_params() - 1);
  EXPECT_THROW(free_map.step_tangents(short_theta, 0.1, nullptr, z.data(), t, 0), Error);

  const auto g_core = make_one_step_map(
      {{"type", "csympnet"}, {"d", 1}, {"core", {{"type", "g"}, {"layers", 2}, {"width", 4}}}});
  EXPECT_FALSE(g_core->has_step_tangents());
  Vector gt(g_core->n_params());
  g_core->init_params(rng, gt);
  EXPECT_THROW(g_core->step_tangents(gt, 0.1, nullptr, z.data(), t, 0), Error);
}

}  // namespace
}  // namespace csympnet::testing
