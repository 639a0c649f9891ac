// Checks every hand-written derivative of System against central finite differences, at random
// points, for all kinds, several d and random constants.
#include "csympnet/systems/system.hpp"

#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"

namespace csympnet {
namespace {

// Central differences: truncation O(ε² f''') ~ 1e-11 and rounding O(u |f| / ε) ~ 1e-11 at
// ε = 1e-5 for the O(1) values used here, so 1e-8 has margin yet catches any real mistake.
constexpr double kFdStep = 1e-5;
constexpr double kFdTol = 1e-8;

template <class F>
Vector system_fd_gradient(F f, const Vector& x) {
  Vector g(x.size());
  for (Index i = 0; i < x.size(); ++i) {
    Vector xp = x, xm = x;
    xp(i) += kFdStep;
    xm(i) -= kFdStep;
    g(i) = (f(xp) - f(xm)) / (2.0 * kFdStep);
  }
  return g;
}

template <class F>
Matrix system_fd_jacobian(F f, const Vector& x) {
  const Index m = f(x).size();
  Matrix jac(m, x.size());
  for (Index i = 0; i < x.size(); ++i) {
    Vector xp = x, xm = x;
    xp(i) += kFdStep;
    xm(i) -= kFdStep;
    jac.col(i) = (f(xp) - f(xm)) / (2.0 * kFdStep);
  }
  return jac;
}

// Every kind with d ∈ {1, 3, 10} and random constants (α of both signs).
std::vector<System> random_systems(Rng& rng) {
  std::vector<System> out;
  for (const char* kind : {"oscillator", "chain", "cubic"}) {
    for (int d : {1, 3, 10}) {
      SystemSpec s;
      s.kind = kind;
      s.d = d;
      s.gamma = rng.uniform(0.0, 0.5);
      s.omega = rng.uniform(0.5, 2.0);
      s.k = rng.uniform(0.5, 2.0);
      s.alpha = rng.uniform(-0.1, 0.1);
      out.emplace_back(s);
    }
  }
  return out;
}

std::string label(const System& sys) {
  return sys.spec().kind + " d=" + std::to_string(sys.d());
}

TEST(System, GradientsMatchFiniteDifferences) {
  Rng rng(1, "system-test");
  for (const System& sys : random_systems(rng)) {
    for (int rep = 0; rep < 3; ++rep) {
      const Vector z = rng.uniform_vector(sys.dim(), -1.5, 1.5);
      const Vector q = z.head(sys.d());
      const Vector gv = system_fd_gradient([&](const Vector& x) { return sys.potential(x); }, q);
      EXPECT_LT((sys.grad_potential(q) - gv).lpNorm<Eigen::Infinity>(), kFdTol) << label(sys);
      const Vector gh = system_fd_gradient([&](const Vector& x) { return sys.energy(x); }, z);
      EXPECT_LT((sys.grad_energy(z) - gh).lpNorm<Eigen::Infinity>(), kFdTol) << label(sys);
    }
  }
}

TEST(System, HessiansMatchFiniteDifferencesOfGradients) {
  Rng rng(2, "system-test");
  for (const System& sys : random_systems(rng)) {
    const Vector z = rng.uniform_vector(sys.dim(), -1.5, 1.5);
    const Vector q = z.head(sys.d());
    const Matrix hv = system_fd_jacobian([&](const Vector& x) { return sys.grad_potential(x); }, q);
    EXPECT_LT((sys.hess_potential(q) - hv).lpNorm<Eigen::Infinity>(), kFdTol) << label(sys);
    const Matrix hh = system_fd_jacobian([&](const Vector& x) { return sys.grad_energy(x); }, z);
    EXPECT_LT((sys.hess_energy(z) - hh).lpNorm<Eigen::Infinity>(), kFdTol) << label(sys);
    // The matrix-free product agrees with the assembled Hessian.
    const Matrix X = rng.uniform_matrix(sys.d(), 4, -1.0, 1.0);
    EXPECT_LT((sys.hess_potential_times(q, X) - sys.hess_potential(q) * X).norm(), 1e-13)
        << label(sys);
  }
}

TEST(System, VectorFieldAndJacobian) {
  Rng rng(3, "system-test");
  for (const System& sys : random_systems(rng)) {
    const Index d = sys.d();
    const Vector z = rng.uniform_vector(sys.dim(), -1.5, 1.5);
    // f = J ∇H − diag(0, γI) z.
    Vector expected = canonical_j(d) * sys.grad_energy(z);
    expected.tail(d) -= sys.gamma() * z.tail(d);
    EXPECT_LT((sys.vector_field(z) - expected).norm(), 1e-14) << label(sys);
    const Matrix jf = system_fd_jacobian([&](const Vector& x) { return sys.vector_field(x); }, z);
    EXPECT_LT((sys.vector_field_jacobian(z) - jf).lpNorm<Eigen::Infinity>(), kFdTol) << label(sys);
  }
}

TEST(System, FiniteDifferenceHarnessCatchesAWrongGradient) {
  // The harness must be able to fail: a gradient off by 1e-6 in one entry is flagged.
  SystemSpec s;
  s.kind = "cubic";
  s.d = 3;
  const System sys(s);
  const Vector q = Vector::LinSpaced(3, -0.5, 0.7);
  Vector wrong = sys.grad_potential(q);
  wrong(1) += 1e-6;
  const Vector gv = system_fd_gradient([&](const Vector& x) { return sys.potential(x); }, q);
  EXPECT_GT((wrong - gv).lpNorm<Eigen::Infinity>(), kFdTol);
}

TEST(System, BatchGradientEqualsPerColumnBitForBit) {
  Rng rng(4, "system-test");
  for (const System& sys : random_systems(rng)) {
    const Matrix Q = rng.uniform_matrix(sys.d(), 17, -2.0, 2.0);
    const Matrix G = sys.grad_potential_batch(Q);
    ASSERT_EQ(G.rows(), sys.d());
    ASSERT_EQ(G.cols(), 17);
    for (Index j = 0; j < Q.cols(); ++j)
      EXPECT_TRUE((G.col(j).array() == sys.grad_potential(Q.col(j)).array()).all()) << label(sys);
  }
}

TEST(System, KnownValues) {
  SystemSpec s;
  s.kind = "chain";
  s.d = 3;
  s.k = 2.0;
  const Vector q = (Vector(3) << 0.0, 1.0, 3.0).finished();
  EXPECT_DOUBLE_EQ(System(s).potential(q), 0.5 * 2.0 * (1.0 + 4.0));  // free ends: no walls
  s.kind = "cubic";
  s.omega = 2.0;
  s.alpha = 0.5;
  EXPECT_DOUBLE_EQ(System(s).potential(q), 0.5 * 4.0 * 10.0 + 0.5 * 64.0);
  s.kind = "oscillator";
  s.d = 1;
  const Vector z = (Vector(2) << 3.0, 4.0).finished();
  EXPECT_DOUBLE_EQ(System(s).energy(z), 0.5 * 16.0 + 0.5 * 4.0 * 9.0);
}

TEST(System, LinearGenerator) {
  Rng rng(5, "system-test");
  for (const System& sys : random_systems(rng)) {
    if (!sys.is_linear()) {
      EXPECT_THROW(sys.linear_generator(), Error);
      continue;
    }
    const Matrix A = sys.linear_generator();
    for (int rep = 0; rep < 3; ++rep) {
      const Vector z = rng.uniform_vector(sys.dim(), -2.0, 2.0);
      EXPECT_LT((A * z - sys.vector_field(z)).norm(), 1e-13) << label(sys);
    }
  }
}

// Expects spec.validate() to throw an Error whose message contains `field`.
void expect_rejected(const SystemSpec& spec, const std::string& field) {
  try {
    spec.validate();
    ADD_FAILURE() << "no error for bad " << field;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
}

TEST(System, ValidateRejectsEachBadField) {
  const double nan = std::nan("");
  const double inf = INFINITY;
  SystemSpec s;
  EXPECT_NO_THROW(s.validate());
  s.kind = "pendulum";
  expect_rejected(s, "system.kind");
  expect_rejected(s, "pendulum");
  s = {};
  for (int d : {0, -3}) {
    s.d = d;
    expect_rejected(s, "system.d");
  }
  s = {};
  for (double g : {-1.0, nan, inf}) {
    s.gamma = g;
    expect_rejected(s, "system.gamma");
  }
  s = {};
  for (double w : {0.0, -1.0, nan, inf}) {
    s.omega = w;
    expect_rejected(s, "system.omega");
    s.kind = "cubic";
    expect_rejected(s, "system.omega");
    s.kind = "oscillator";
  }
  s = {};
  s.kind = "chain";
  s.omega = 0.0;  // ω is unused by the chain
  EXPECT_NO_THROW(s.validate());
  for (double k : {-0.5, nan, inf}) {
    s.k = k;
    expect_rejected(s, "system.k");
  }
  s = {};
  for (double a : {nan, -inf}) {
    s.alpha = a;
    expect_rejected(s, "system.alpha");
  }
  SystemSpec bad;
  bad.gamma = -1.0;
  EXPECT_THROW(System{bad}, Error);
}

TEST(System, JsonRoundTripAndRejections) {
  SystemSpec s;
  s.kind = "cubic";
  s.d = 10;
  s.gamma = 0.07;
  s.alpha = 1e-4;
  const nlohmann::json j = s;
  const auto back = j.get<SystemSpec>();
  EXPECT_EQ(back.kind, "cubic");
  EXPECT_EQ(back.d, 10);
  EXPECT_EQ(back.gamma, 0.07);
  EXPECT_EQ(back.alpha, 1e-4);

  // Optional constants keep their defaults.
  const auto minimal = nlohmann::json{{"kind", "chain"}, {"d", 100}}.get<SystemSpec>();
  EXPECT_EQ(minimal.k, SystemSpec{}.k);
  EXPECT_EQ(minimal.gamma, SystemSpec{}.gamma);

  auto expect_json_error = [](const nlohmann::json& bad_json, const std::string& mention) {
    try {
      (void)bad_json.get<SystemSpec>();
      ADD_FAILURE() << "accepted " << bad_json.dump();
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(mention), std::string::npos) << e.what();
    }
  };
  expect_json_error(nlohmann::json{{"d", 3}}, "system.kind");
  expect_json_error(nlohmann::json{{"kind", "chain"}}, "system.d");
  expect_json_error(nlohmann::json{{"kind", "chain"}, {"d", 2.5}}, "system.d");
  expect_json_error(nlohmann::json{{"kind", "chain"}, {"d", "10"}}, "system.d");
  expect_json_error(nlohmann::json{{"kind", 3}, {"d", 1}}, "system.kind");
  expect_json_error(nlohmann::json{{"kind", "chain"}, {"d", 2}, {"gamma", "x"}}, "system.gamma");
  expect_json_error(nlohmann::json{{"kind", "chain"}, {"d", 2}, {"gama", 0.1}}, "gama");
  expect_json_error(nlohmann::json{{"kind", "chain"}, {"d", 2}, {"k", -1.0}}, "system.k");
  expect_json_error(nlohmann::json::array(), "object");
}

}  // namespace
}  // namespace csympnet
