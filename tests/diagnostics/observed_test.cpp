// score_observed (diagnostics/observed.hpp): every score against hand-computed values, the
// limits (the exact map, no change at all), and the refusals.
#include "csympnet/diagnostics/observed.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "csympnet/core/error.hpp"

namespace csympnet {
namespace {

// The flow of a damped rotation over a step h: z ↦ e^{−γh/2} R(h) z with γ = 0.05, a
// conformally symplectic linear map in closed form.
Vector spiral_step(const Vector& z, double h) {
  const double a = std::exp(-0.025 * h), c = std::cos(h), s = std::sin(h);
  Vector out(2);
  out << a * (c * z(0) + s * z(1)), a * (-s * z(0) + c * z(1));
  return out;
}

// One trajectory of it from (1, 0), sampled every h, shifted like a measurement whose zero is
// elsewhere.
Trajectory oscillator(Index n, double h, double offset = 0.0) {
  Trajectory tr;
  tr.t = Vector::LinSpaced(n + 1, 0.0, h * static_cast<double>(n));
  tr.z.resize(2, n + 1);
  Vector z(2);
  z << 1.0, 0.0;
  for (Index k = 0; k <= n; ++k) {
    tr.z.col(k) = z;
    z = spiral_step(z, h);
  }
  tr.z.array() += offset;
  return tr;
}

LearnedMap true_flow(double offset = 0.0) {
  LearnedMap m;
  m.step = [offset](const Vector& z, double h) -> Vector {
    return spiral_step(z.array() - offset, h).array() + offset;
  };
  m.gamma_hat = 0.05;
  return m;
}

TEST(ScoreObserved, TheExactMapScoresPerfectly) {
  const Trajectory tr = oscillator(60, 0.1, 3.0);
  const ObservedScores s = score_observed(true_flow(3.0), {tr});
  EXPECT_LT(s.one_step_rmse, 1e-13);
  EXPECT_LT(s.one_step_relative, 1e-12);
  EXPECT_NEAR(s.one_step_r2, 1.0, 1e-12);
  EXPECT_LT(s.rollout_nrmse, 1e-12);
  EXPECT_EQ(s.valid_fraction_mean, 1.0);
  EXPECT_EQ(s.valid_time_mean, tr.t(60));
  EXPECT_TRUE(s.rollout_finite);
  EXPECT_EQ(s.pairs, 60);
  EXPECT_TRUE(std::isnan(s.structure_residual_mean));  // this map has no Jacobian
  EXPECT_EQ(*s.gamma_hat, 0.05);
}

TEST(ScoreObserved, PredictingNoChangeHasRelativeErrorOne) {
  LearnedMap still;
  still.step = [](const Vector& z, double) { return z; };
  const ObservedScores s = score_observed(still, {oscillator(40, 0.1), oscillator(30, 0.2)});
  EXPECT_NEAR(s.one_step_relative, 1.0, 1e-15);  // the error is the increment itself
  EXPECT_LE(s.one_step_r2, 0.0);
  EXPECT_FALSE(s.gamma_hat.has_value());
  EXPECT_EQ(s.per_trajectory.size(), 2u);
  EXPECT_EQ(s.pairs, 70);
}

// A three-point trajectory and the map z ↦ 2z, worked by hand.
TEST(ScoreObserved, MatchesAHandComputedCase) {
  Trajectory tr;
  tr.t = Vector(3);
  tr.t << 0.0, 0.5, 1.5;
  tr.z.resize(2, 3);
  tr.z << 1.0, 2.0, 2.0,  //
      0.0, 1.0, 3.0;
  LearnedMap twice;
  twice.step = [](const Vector& z, double) { return Vector(2.0 * z); };
  twice.jacobian = [](const Vector&, double) { return Matrix(2.0 * Matrix::Identity(2, 2)); };
  const ObservedScores s = score_observed(twice, {tr});
  // One step: Φ(z0) = (2, 0) vs (2, 1): error² 1; Φ(z1) = (4, 2) vs (2, 3): error² 5.
  EXPECT_DOUBLE_EQ(s.one_step_rmse, std::sqrt(6.0 / 4.0));
  // Increments (1, 1) and (0, 2): Σ‖Δ‖² = 6; mean (0.5, 1.5), Σ‖Δ − mean‖² = 0.5 + 0.5 = 1.
  EXPECT_DOUBLE_EQ(s.one_step_relative, 1.0);
  EXPECT_DOUBLE_EQ(s.one_step_r2, 1.0 - 6.0 / 1.0);
  // Rollout: (1,0) → (2,0) → (4,0); errors² 1 and 4 + 9 = 13.
  EXPECT_DOUBLE_EQ(s.rollout_rmse, std::sqrt(14.0 / 4.0));
  // Mean state (5/3, 4/3); spread of z1, z2: (1/9 + 1/9) + (1/9 + 25/9) = 28/9.
  EXPECT_DOUBLE_EQ(s.rollout_nrmse, std::sqrt(14.0 / (28.0 / 9.0)));
  EXPECT_DOUBLE_EQ(s.l2_error, std::sqrt(1.0 * 0.5 + 13.0 * 1.0));
  // RMS spread over all three states: (4/9+16/9 + 1/9+1/9 + 1/9+25/9)/3 = 48/27; 10% of its root
  // is 0.133, and the first rollout error (1) exceeds it: valid only at t_0.
  EXPECT_EQ(s.valid_time_mean, 0.0);
  EXPECT_EQ(s.valid_fraction_mean, 0.0);
  // 2·I: MᵀJM = 4J, so λ̂ = 4 and S = 0 without a γ̂ (λ_own = λ̂).
  EXPECT_DOUBLE_EQ(s.structure_residual_max, 0.0);
}

TEST(ScoreObserved, ValidTimeIsTheLastTimeWithinTolerance) {
  const Trajectory tr = oscillator(80, 0.1);
  // The true flow plus a drift of 0.01 per step in q, so the rollout's error grows steadily.
  LearnedMap drift = true_flow();
  const auto exact = drift.step;
  drift.step = [exact](const Vector& z, double h) {
    Vector next = exact(z, h);
    next(0) += 0.01;
    return next;
  };
  const ObservedScores s = score_observed(drift, {tr});
  // The same rollout, stepped here, and the first state at which its RMS error so far passes
  // 10% of the RMS spread.
  const Vector mean = tr.z.rowwise().mean();
  const double spread = std::sqrt((tr.z.colwise() - mean).colwise().squaredNorm().mean());
  Vector z = tr.z.col(0);
  Index first_bad = 0;
  double sum_sq = 0.0;
  for (Index n = 1; n <= 80 && first_bad == 0; ++n) {
    z = drift.step(z, 0.1);
    sum_sq += (z - tr.z.col(n)).squaredNorm();
    if (std::sqrt(sum_sq / static_cast<double>(n)) > kValidTimeTolerance * spread) first_bad = n;
  }
  ASSERT_GT(first_bad, 3);   // the case is not degenerate: valid for a while,
  ASSERT_LT(first_bad, 80);  // and not to the end
  EXPECT_EQ(s.valid_time_mean, tr.t(first_bad - 1));
  EXPECT_EQ(s.valid_fraction_mean, tr.t(first_bad - 1) / tr.t(80));
}

TEST(ScoreObserved, OneNoisySampleDoesNotEndTheValidTime) {
  Trajectory tr = oscillator(80, 0.1);
  const Vector mean = tr.z.rowwise().mean();
  const double spread = std::sqrt((tr.z.colwise() - mean).colwise().squaredNorm().mean());
  tr.z(1, 5) += 0.5 * spread;  // one outlier, far past 10% of the spread on its own
  const ObservedScores s = score_observed(true_flow(), {tr});
  // RMS so far at n = 5 is 0.5 spread / √5 = 0.22 spread: past the tolerance, so valid until
  // t_4; with 20 clean samples before it, the outlier would be diluted below it.
  EXPECT_EQ(s.valid_time_mean, tr.t(4));
  Trajectory late = oscillator(80, 0.1);
  late.z(1, 60) += 0.5 * spread;  // 0.5 / √60 = 0.065 spread: within
  EXPECT_EQ(score_observed(true_flow(), {late}).valid_time_mean, late.t(80));
}

TEST(ScoreObserved, AMapThatFailsIsInfinitelyWrongNotACrash) {
  LearnedMap breaks = true_flow();
  const auto exact = breaks.step;
  breaks.step = [exact](const Vector& z, double h) {
    if (z(0) < 0.0) throw Error("left the domain");
    return exact(z, h);
  };
  const ObservedScores s = score_observed(breaks, {oscillator(60, 0.1)});
  EXPECT_FALSE(s.rollout_finite);
  EXPECT_TRUE(std::isinf(s.one_step_rmse));
}

TEST(ScoreObserved, RefusesWhatItCannotScoreNamingWhy) {
  Trajectory single;
  single.t = Vector::Zero(1);
  single.z = Matrix::Zero(2, 1);
  EXPECT_THROW(
      {
        try {
          score_observed(true_flow(), {oscillator(5, 0.1), single});
        } catch (const Error& e) {
          EXPECT_NE(std::string(e.what()).find("trajectory 2 has a single point"),
                    std::string::npos);
          throw;
        }
      },
      Error);
  Trajectory wide = oscillator(5, 0.1);
  wide.z = Matrix::Ones(4, 6);
  EXPECT_THROW(score_observed(true_flow(), {oscillator(5, 0.1), wide}), Error);
  Trajectory line;  // constant increments: R² undefined
  line.t = Vector::LinSpaced(4, 0.0, 3.0);
  line.z = Matrix(2, 4);
  line.z << 0, 1, 2, 3, 0, 1, 2, 3;
  EXPECT_THROW(score_observed(true_flow(), {line}), Error);
  EXPECT_THROW(score_observed(true_flow(), {}), Error);
}

}  // namespace
}  // namespace csympnet
