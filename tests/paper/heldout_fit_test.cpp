// fit_pairs on a damped system that is not a preset: the pendulum H = p²/2 − cos q with
// γ = 0.1, sampled at irregular steps along trajectories from a fine RK4 solve (not the
// presets' splitting). Small budgets; the full-budget numbers are in docs/identification.md.
#include <gtest/gtest.h>

#include <cmath>

#include "csympnet/paper/fit.hpp"

namespace csympnet {
namespace {

constexpr double kGamma = 0.1;

Vector pendulum_field(const Vector& z) {
  Vector f(2);
  f << z(1), -std::sin(z(0)) - kGamma * z(1);
  return f;
}

// Classical RK4 over time h in substeps of at most 1e-3 (global error ~1e-14 here).
Vector rk4_flow(Vector z, double h) {
  const int n = static_cast<int>(std::ceil(h / 1e-3));
  const double dt = h / n;
  for (int i = 0; i < n; ++i) {
    const Vector k1 = pendulum_field(z);
    const Vector k2 = pendulum_field(z + 0.5 * dt * k1);
    const Vector k3 = pendulum_field(z + 0.5 * dt * k2);
    const Vector k4 = pendulum_field(z + dt * k3);
    z += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  }
  return z;
}

// 32 trajectories of 12 steps with h ~ U[0.05, 0.2]; relative noise sigma on every state.
std::pair<PairSet, std::vector<Index>> pendulum_data(double sigma, std::uint64_t seed) {
  Rng rng(seed, "pendulum");
  std::vector<Trajectory> trajs;
  for (int m = 0; m < 32; ++m) {
    Trajectory t;
    t.t.resize(13);
    t.z.resize(2, 13);
    t.t(0) = 0.0;
    t.z(0, 0) = rng.uniform(-1.0, 1.0);  // libration only: H < 1 - cos 1 + 1/2 < 1
    t.z(1, 0) = rng.uniform(-1.0, 1.0);
    for (int k = 1; k <= 12; ++k) {
      const double h = rng.uniform(0.05, 0.2);
      t.t(k) = t.t(k - 1) + h;
      // Element-wise: GCC 12 flags Eigen's packet store into a 2-row column as an overread
      // (-Wstringop-overread, a false positive).
      const Vector next = rk4_flow(t.z.col(k - 1), h);
      t.z(0, k) = next(0);
      t.z(1, k) = next(1);
    }
    trajs.push_back(t);
  }
  if (sigma > 0.0)
    for (auto& t : trajs)
      for (Index k = 0; k < t.z.cols(); ++k) {
        t.z(0, k) += sigma * rng.normal();  // the states' std is about 1 in q and p
        t.z(1, k) += sigma * rng.normal();
      }
  std::vector<Index> groups;
  for (std::size_t m = 0; m < trajs.size(); ++m)
    groups.insert(groups.end(), 12, static_cast<Index>(m));
  return {pairs_from_trajectories(trajs), groups};
}

FitConfig small_budget() {
  FitConfig c;
  // The default core for d = 1, LA(5, 20).
  c.train.epochs = 20000;
  c.train.adamw.lr = 1e-2;
  c.train.lr_schedule = LrSchedule::kCosine;
  c.warm_start = true;      // the recommended identification settings (identification.md)
  c.refine_method.reset();  // chosen by size
  c.refine.iterations = 200;
  return c;
}

TEST(HeldOutSystem, PendulumGammaToRelativeErrorOneInAThousand) {
  const auto [pairs, groups] = pendulum_data(0.0, 1);
  FitConfig c = small_budget();
  c.bootstrap_replicates = 0;
  const FitResult r = fit_pairs(pairs, std::nullopt, c, {}, groups);
  EXPECT_EQ(r.config.refine.method, RefineMethod::kLm);  // the default for a model this size
  ASSERT_TRUE(r.warm_start.has_value());
  EXPECT_EQ(r.warm_start->method, WarmStartMethod::kMidpoint);  // irregular steps
  const double gamma = *r.model.damping_rate(r.theta);
  EXPECT_LT(std::abs(gamma - kGamma) / kGamma, 1e-3) << "gamma_hat " << gamma;
}

TEST(HeldOutSystem, NoisyPendulumIntervalCoversTheTruth) {
  const auto [pairs, groups] = pendulum_data(1e-2, 2);
  FitConfig c = small_budget();
  c.bootstrap_replicates = 20;
  const FitResult r = fit_pairs(pairs, std::nullopt, c, {}, groups);
  ASSERT_TRUE(r.interval.has_value());
  EXPECT_EQ(r.interval->resample, "trajectories");
  EXPECT_EQ(r.interval->gammas.size(), 20u);
  EXPECT_LT(r.interval->low, r.interval->high);
  EXPECT_LE(r.interval->low, kGamma);
  EXPECT_GE(r.interval->high, kGamma);
}

TEST(HeldOutSystem, BootstrapIsDeterministic) {
  const auto [pairs, groups] = pendulum_data(1e-2, 3);
  FitConfig c = small_budget();
  c.train.epochs = 300;
  c.refine.iterations = 10;
  c.bootstrap_replicates = 10;
  const FitResult a = fit_pairs(pairs, std::nullopt, c, {}, groups);
  const FitResult b = fit_pairs(pairs, std::nullopt, c, {}, groups);
  EXPECT_EQ(a.interval->gammas, b.interval->gammas);
  EXPECT_EQ(a.theta, b.theta);
}

}  // namespace
}  // namespace csympnet
