// The window loss (train/window_loss.hpp): its gradient and Jacobian rows against central
// differences (the balancing's β term included), its reduction to the one-step loss, and the
// chunked normal equations against the explicit J; the chunks' shares add up to the loss.
#include "csympnet/train/window_loss.hpp"

#include <algorithm>

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/train/loss.hpp"
#include "support/gradient_check.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet {
namespace {

using testing::check_gradient;
using testing::check_jacobian;
using testing::random_theta;

// Random trajectories of random states at random steps: the loss's derivatives hold for any
// data, not only for data the map explains.
std::vector<Trajectory> random_trajectories(Index dim, int count, int points, Rng& rng) {
  std::vector<Trajectory> out;
  for (int k = 0; k < count; ++k) {
    Trajectory t;
    t.z = rng.normal_matrix(dim, points, 1.0);
    t.t.resize(points);
    t.t(0) = rng.uniform(-1.0, 1.0);
    for (int j = 1; j < points; ++j) t.t(j) = t.t(j - 1) + rng.uniform(0.05, 0.2);
    out.push_back(t);
  }
  return out;
}

struct Case {
  const char* spec;
  Index m;
  bool balanced;
};

class WindowLossTest : public ::testing::TestWithParam<Case> {};

TEST_P(WindowLossTest, GradientMatchesFiniteDifferences) {
  const Case c = GetParam();
  const auto map = make_one_step_map(nlohmann::json::parse(c.spec));
  Rng rng(21, c.spec);
  for (int rep = 0; rep < 3; ++rep) {
    // β of either sign: γ̂ = |β|, and the balancing's weight depends on it.
    const Vector theta = random_theta(*map, rng, 0.3, rep == 1 ? -0.4 : 0.7);
    const WindowSet w = windows_from_trajectories(random_trajectories(map->dim(), 2, 7, rng), c.m);
    const auto f = [&](const Vector& th) { return window_loss(*map, th, w, c.balanced); };
    const auto g = [&](const Vector& th) {
      Vector grad;
      window_loss(*map, th, w, c.balanced, &grad);
      return grad;
    };
    const auto check = check_gradient(f, g, theta);
    EXPECT_TRUE(check.ok()) << check.report("window loss gradient");
  }
}

TEST_P(WindowLossTest, JacobianRowsMatchFiniteDifferencesAndTheGradient) {
  const Case c = GetParam();
  const auto map = make_one_step_map(nlohmann::json::parse(c.spec));
  Rng rng(22, c.spec);
  const Vector theta = random_theta(*map, rng, 0.3, -0.6);
  const WindowSet w = windows_from_trajectories(random_trajectories(map->dim(), 2, 6, rng), c.m);
  const Index rows = w.size() * w.dim();
  const auto r = [&](const Vector& th) { return window_residuals(*map, th, w, c.balanced); };
  const auto jac = [&](const Vector& th) -> Matrix {
    RowMajorMatrix j(rows, map->n_params());
    Vector res(rows);
    window_jacobian_rows(*map, th, w, c.balanced, 0, w.size(), j, res);
    return j;
  };
  const auto check = check_jacobian(r, jac, theta);
  EXPECT_TRUE(check.ok()) << check.report("window residual Jacobian");
  // dL/dθ = (2/N) Jᵀ r, the batched reverse pass being an independent path.
  Vector grad;
  window_loss(*map, theta, w, c.balanced, &grad);
  const Vector from_jac = (2.0 / static_cast<double>(w.size())) * jac(theta).transpose() * r(theta);
  EXPECT_LE((grad - from_jac).norm(), 1e-12 * (1.0 + grad.norm()));
}

// The shares of the chunks of a partition add up to the loss and its gradient (what fit sums
// over ranks), and the share of the whole set is the loss to the bit.
TEST_P(WindowLossTest, ChunkSharesAddUpToTheLoss) {
  const Case c = GetParam();
  const auto map = make_one_step_map(nlohmann::json::parse(c.spec));
  Rng rng(25, c.spec);
  const Vector theta = random_theta(*map, rng, 0.3, 0.6);
  const WindowSet w = windows_from_trajectories(random_trajectories(map->dim(), 3, 12, rng), c.m);
  Vector grad;
  const double loss = window_loss(*map, theta, w, c.balanced, &grad);
  Vector whole_grad;
  EXPECT_EQ(window_loss_part(*map, theta, w, c.balanced, w.size(), &whole_grad), loss);
  EXPECT_EQ(whole_grad, grad);
  double sum = 0.0;
  Vector sum_grad = Vector::Zero(map->n_params());
  for (Index first = 0; first < w.size(); first += 7) {
    std::vector<Index> idx;
    for (Index i = first; i < std::min<Index>(first + 7, w.size()); ++i) idx.push_back(i);
    Vector g;
    sum += window_loss_part(*map, theta, select_windows(w, idx), c.balanced, w.size(), &g);
    sum_grad += g;
    // Without a gradient, the same share.
    EXPECT_EQ(window_loss_part(*map, theta, select_windows(w, idx), c.balanced, w.size()),
              window_loss_part(*map, theta, select_windows(w, idx), c.balanced, w.size(), &g));
  }
  EXPECT_NEAR(sum, loss, 1e-13 * loss);
  EXPECT_LE((sum_grad - grad).norm(), 1e-12 * (1.0 + grad.norm()));
  EXPECT_THROW(window_loss_part(*map, theta, w, c.balanced, w.size() - 1), Error);
}

TEST_P(WindowLossTest, ChunkedNormalEquationsMatchTheExplicitJacobian) {
  const Case c = GetParam();
  const auto map = make_one_step_map(nlohmann::json::parse(c.spec));
  Rng rng(23, c.spec);
  const Vector theta = random_theta(*map, rng, 0.3, 0.5);
  // Enough windows to need several chunks when P is small.
  const WindowSet w = windows_from_trajectories(random_trajectories(map->dim(), 5, 90, rng), c.m);
  const double scale = 0.37;
  const NormalEquations ne = window_normal_equations(*map, theta, w, c.balanced, scale, true);
  const Index rows = w.size() * w.dim();
  RowMajorMatrix j(rows, map->n_params());
  Vector res(rows);
  window_jacobian_rows(*map, theta, w, c.balanced, 0, w.size(), j, res);
  j *= scale;
  res *= scale;
  const Matrix a = j.transpose() * j;
  const Matrix lower_a = a.triangularView<Eigen::Lower>();
  const Matrix lower_ne = ne.a.triangularView<Eigen::Lower>();
  EXPECT_LE((lower_ne - lower_a).norm(), 1e-11 * a.norm());
  EXPECT_LE((ne.g - j.transpose() * res).norm(), 1e-11 * (1.0 + ne.g.norm()));
  EXPECT_NEAR(ne.cost, 0.5 * res.squaredNorm(), 1e-12 * ne.cost);
  // The block scores add up to g, and each is its own block's share.
  ASSERT_EQ(ne.scores.cols(), 5);
  EXPECT_LE((ne.scores.rowwise().sum() - ne.g).norm(), 1e-11 * (1.0 + ne.g.norm()));
  Vector first = Vector::Zero(map->n_params());
  for (Index i = 0; i < w.size(); ++i)
    if (w.block[static_cast<std::size_t>(i)] == 0)
      first += j.middleRows(i * w.dim(), w.dim()).transpose() * res.segment(i * w.dim(), w.dim());
  EXPECT_LE((ne.scores.col(0) - first).norm(), 1e-11 * (1.0 + first.norm()));
}

// An interrupt polled per chunk: the sums stop after the chunks already taken, marked
// stopped; never polled again once it fired; a poll that never fires changes nothing.
TEST_P(WindowLossTest, NormalEquationsStopBetweenChunksWhenAsked) {
  const Case c = GetParam();
  const auto map = make_one_step_map(nlohmann::json::parse(c.spec));
  Rng rng(29, c.spec);
  const Vector theta = random_theta(*map, rng, 0.3, 0.5);
  const WindowSet w = windows_from_trajectories(random_trajectories(map->dim(), 5, 90, rng), c.m);
  const NormalEquations full = window_normal_equations(*map, theta, w, c.balanced, 1.0);
  int polls = 0;
  const NormalEquations never =
      window_normal_equations(*map, theta, w, c.balanced, 1.0, false, [&] {
        ++polls;
        return false;
      });
  EXPECT_FALSE(never.stopped);
  EXPECT_GE(polls, 1);
  EXPECT_EQ(never.cost, full.cost);
  EXPECT_TRUE(never.g == full.g);
  int after = 0;
  const NormalEquations first_chunk =
      window_normal_equations(*map, theta, w, c.balanced, 1.0, false, [&] { return ++after > 1; });
  EXPECT_TRUE(first_chunk.stopped);
  EXPECT_EQ(after, 2);
  if (polls > 1) {
    EXPECT_LT(first_chunk.cost, full.cost);  // only the first chunk summed
  }
  const NormalEquations none =
      window_normal_equations(*map, theta, w, c.balanced, 1.0, false, [] { return true; });
  EXPECT_TRUE(none.stopped);
  EXPECT_EQ(none.cost, 0.0);
  EXPECT_EQ(none.g.norm(), 0.0);
}

INSTANTIATE_TEST_SUITE_P(
    Maps, WindowLossTest,
    ::testing::Values(
        Case{R"({"type":"csympnet","d":1,"core":{"type":"la","layers":3,"sublayers":4}})", 1, true},
        Case{
            R"({"type":"csympnet","d":1,"core":{"type":"la","layers":3,"sublayers":4,"step_terms":2}})",
            3, true},
        Case{R"({"type":"csympnet","d":2,"core":{"type":"g","layers":3,"width":5}})", 2, true},
        Case{R"({"type":"csympnet","d":2,"core":{"type":"la","layers":2,"sublayers":3}})", 4,
             false},
        Case{R"({"type":"sympnet","d":1,"core":{"type":"la","layers":2,"sublayers":3}})", 2,
             true}));

TEST(WindowLoss, OneStepUnbalancedIsTheOneStepLoss) {
  const auto map = make_one_step_map(nlohmann::json::parse(
      R"({"type":"csympnet","d":2,"core":{"type":"la","layers":2,"sublayers":3}})"));
  Rng rng(24, "one-step");
  const Vector theta = random_theta(*map, rng, 0.3, 0.2);
  PairSet p;
  p.z0 = rng.normal_matrix(4, 9, 1.0);
  p.z1 = rng.normal_matrix(4, 9, 1.0);
  p.h = rng.uniform_vector(9, 0.05, 0.2);
  Vector g1, g2;
  const double l1 = one_step_loss(*map, theta, p, &g1);
  const double l2 = window_loss(*map, theta, windows_from_pairs(p), false, &g2);
  // The same terms, summed in another order.
  EXPECT_NEAR(l1, l2, 1e-14 * l1);
  EXPECT_LE((g1 - g2).norm(), 1e-14 * g1.norm());
}

TEST(WindowLoss, BalancedResidualIsTheMismatchInTheMiddleOfTheMap) {
  // For one step of CSympNet-ID, W r = S_a⁻¹(Φ̂(z0) − z1) = Ψ(S_a z0) − S_a⁻¹ z1.
  const auto map = make_one_step_map(nlohmann::json::parse(
      R"({"type":"csympnet","d":1,"core":{"type":"la","layers":2,"sublayers":3}})"));
  const auto core =
      make_one_step_map(nlohmann::json::parse(R"({"type":"la","d":1,"layers":2,"sublayers":3})"));
  Rng rng(25, "middle");
  const Vector theta = random_theta(*map, rng, 0.3, -0.8);
  PairSet p;
  p.z0 = rng.normal_matrix(2, 5, 1.0);
  p.z1 = rng.normal_matrix(2, 5, 1.0);
  p.h = rng.uniform_vector(5, 0.05, 0.2);
  const Vector r = window_residuals(*map, theta, windows_from_pairs(p), true);
  for (Index j = 0; j < 5; ++j) {
    const double a = std::exp(-0.5 * 0.8 * p.h(j));
    Matrix s = p.z0.col(j);
    s(1, 0) *= a;
    Vector hj(1);
    hj(0) = p.h(j);
    const Matrix mid = core->apply(theta.head(core->n_params()), s, hj);
    EXPECT_NEAR(r(2 * j), mid(0, 0) - p.z1(0, j), 1e-13);
    EXPECT_NEAR(r(2 * j + 1), mid(1, 0) - p.z1(1, j) / a, 1e-13);
  }
}

TEST(WindowLoss, WindowsStayInsideTheirTrajectories) {
  Rng rng(26, "windows");
  std::vector<Trajectory> t = random_trajectories(2, 3, 6, rng);
  t[1] = random_trajectories(2, 1, 2, rng)[0];  // 1 step: no window of 3
  const WindowSet w = windows_from_trajectories(t, 3, {7, 8, 9});
  ASSERT_EQ(w.size(), 3 + 0 + 3);
  EXPECT_EQ(w.block, (std::vector<Index>{7, 7, 7, 9, 9, 9}));
  EXPECT_EQ(w.z0.col(0), t[0].z.col(0));
  EXPECT_EQ(w.zm.col(0), t[0].z.col(3));
  EXPECT_EQ(w.zm.col(5), t[2].z.col(5));
  EXPECT_DOUBLE_EQ(w.h(2, 5), t[2].t(5) - t[2].t(4));
}

// The Gauss–Newton step with parameters held at 0, at random normal equations: the held ones
// are exactly 0, the rest stationary for the quadratic model (its gradient on them vanishes to
// the ridge), and the model is no higher there than at θ with the held ones simply zeroed.
TEST(GaussNewtonWithZeros, ZeroesTheHeldAndMinimisesTheModelOverTheRest) {
  for (int draw = 0; draw < 20; ++draw) {
    SCOPED_TRACE(draw);
    Rng rng(draw, "gn-with-zeros");
    const Index n = 3 + draw % 6;
    const Matrix j = rng.normal_matrix(2 * n + 3, n, 1.0);
    NormalEquations ne;
    ne.a = j.transpose() * j;
    ne.g = rng.normal_matrix(n, 1, 0.3);
    const Vector theta = rng.normal_matrix(n, 1, 1.0);
    std::vector<Index> zeroed;
    for (Index k = 0; k < n; ++k)
      if (rng.uniform(0.0, 1.0) < 0.35 || k == draw % n) zeroed.push_back(k);
    if (static_cast<Index>(zeroed.size()) == n) zeroed.pop_back();
    const Vector out = gauss_newton_with_zeros(ne, theta, zeroed);
    ASSERT_EQ(out.size(), n);
    const Vector delta = out - theta;
    const auto model = [&](const Vector& d) { return 0.5 * d.dot(ne.a * d) + ne.g.dot(d); };
    const Vector grad = ne.a * delta + ne.g;
    Vector plain = Vector::Zero(n);
    for (Index k : zeroed) {
      EXPECT_EQ(out(k), 0.0);
      plain(k) = -theta(k);
    }
    for (Index k = 0; k < n; ++k) {
      if (std::find(zeroed.begin(), zeroed.end(), k) != zeroed.end()) continue;
      EXPECT_LE(std::abs(grad(k)), 1e-6 * (1.0 + ne.a.cwiseAbs().maxCoeff() * delta.norm()));
    }
    EXPECT_LE(model(delta), model(plain) + 1e-12 * std::abs(model(plain)));
  }
  NormalEquations ne;
  ne.a = Matrix::Identity(2, 2);
  ne.g = Vector::Zero(2);
  EXPECT_EQ(gauss_newton_with_zeros(ne, Vector::Ones(2), {}).size(), 0);
  EXPECT_EQ(gauss_newton_with_zeros(ne, Vector::Ones(2), {0, 1}).size(), 0);
  EXPECT_THROW(gauss_newton_with_zeros(ne, Vector::Ones(2), {2}), Error);
}

}  // namespace
}  // namespace csympnet
