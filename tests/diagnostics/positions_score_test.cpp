// score_positions (diagnostics/positions_score.hpp): on positions the true model made, the score
// is at the state fit's precision; noise and a wrong γ raise it; the warm-up is left out; and
// every refusal names what was wrong.
#include "csympnet/diagnostics/positions_score.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/diagnostics/learned_map.hpp"
#include "support/refusal.hpp"

namespace csympnet {
namespace {

// The damped oscillator H = ½p² + ½q² with damping rate `gamma`: a Hamiltonian-library
// csympnet model (θ = W, c, β), order-4 steps.
struct Oscillator {
  Model model;
  Vector theta;
};

Oscillator positions_oscillator(double gamma) {
  Oscillator o{make_model({{"type", "csympnet"},
                           {"d", 1},
                           {"core", {{"type", "library"}, {"terms", {"q1^2"}}, {"order", 4}}}}),
               Vector()};
  o.theta.resize(o.model.n_params());
  Rng rng(1, "unused");  // the library draws nothing
  o.model.init_params(rng, o.theta);
  o.theta(o.theta.size() - 1) = gamma;
  return o;
}

// Positions of the model's own motion from (q, p) = (1, 0.5) at the times `t`, plus noise.
Trajectory positions_of(const Oscillator& o, const Vector& t, double sigma = 0.0,
                        std::uint64_t seed = 0) {
  const LearnedMap map = learned_map(o.model, o.theta);
  Vector z(2);
  z << 1.0, 0.5;
  Trajectory tr;
  tr.t = t;
  tr.z.resize(1, t.size());
  Rng rng(seed, "noise");
  for (Index k = 0; k < t.size(); ++k) {
    if (k > 0) z = map.step(z, t(k) - t(k - 1));
    tr.z(0, k) = z(0) + (sigma > 0.0 ? sigma * rng.normal() : 0.0);
  }
  return tr;
}

Vector regular_times(Index n, double h) {
  return Vector::LinSpaced(n, 0.0, h * static_cast<double>(n - 1));
}

using testing::refusal;

TEST(ScorePositions, TheTrueModelScoresAtTheStateFitsPrecision) {
  const Oscillator o = positions_oscillator(0.1);
  const Trajectory tr = positions_of(o, regular_times(200, 0.1));
  const PositionsScores s = score_positions(o.model, o.theta, {tr});
  EXPECT_LT(s.rmse, 1e-6);
  EXPECT_LT(s.nrmse, 1e-6);
  EXPECT_GT(s.spread, 0.1);
  EXPECT_TRUE(s.rollout_finite);
  EXPECT_FALSE(s.warmup.has_value());
  ASSERT_EQ(s.per_trajectory.size(), 1u);
  // The default: a tenth of 200 samples.
  EXPECT_EQ(s.per_trajectory[0].warmup, 20);
  EXPECT_EQ(s.per_trajectory[0].scored, 180);
  EXPECT_EQ(s.samples_scored, 180);
  EXPECT_EQ(s.per_trajectory[0].t_start, tr.t(19));
  EXPECT_LT(s.per_trajectory[0].state_fit_rms, 1e-6);
  ASSERT_EQ(s.rmse_per_coordinate.size(), 1);
  EXPECT_EQ(s.rmse_per_coordinate(0), s.rmse);  // d = 1
  ASSERT_EQ(s.rollouts.size(), 1u);
  EXPECT_EQ(s.rollouts[0].rows(), 2);
  EXPECT_EQ(s.rollouts[0].cols(), 181);  // the fitted state, then one per scored sample
}

TEST(ScorePositions, IrregularStepsAreOneMapStepEach) {
  const Oscillator o = positions_oscillator(0.1);
  Vector t(120);
  t(0) = 0.0;
  for (Index k = 1; k < t.size(); ++k) t(k) = t(k - 1) + (k % 3 == 0 ? 0.15 : 0.07);
  const PositionsScores s = score_positions(o.model, o.theta, {positions_of(o, t)});
  EXPECT_LT(s.rmse, 1e-6);
}

TEST(ScorePositions, NoiseAndAWrongDampingRateRaiseTheScore) {
  const Oscillator truth = positions_oscillator(0.1);
  const Vector t = regular_times(300, 0.1);
  const double clean = score_positions(truth.model, truth.theta, {positions_of(truth, t)}).rmse;
  const double noisy =
      score_positions(truth.model, truth.theta, {positions_of(truth, t, 0.01, 3)}).rmse;
  const double noisier =
      score_positions(truth.model, truth.theta, {positions_of(truth, t, 0.03, 3)}).rmse;
  // The score of a true forecast of noisy positions is about the noise itself.
  EXPECT_GT(noisy, 0.005);
  EXPECT_LT(noisy, 0.03);
  EXPECT_GT(noisier, noisy);
  EXPECT_GT(noisy, 100 * clean);
  // A damping rate twice the true one still explains a short warm-up, and its forecast drifts.
  const Oscillator wrong = positions_oscillator(0.2);
  const double off =
      score_positions(wrong.model, wrong.theta, {positions_of(truth, t)}, {10L, "p"}).rmse;
  EXPECT_GT(off, 100 * clean);
  EXPECT_GT(off, 0.01);
}

// The valid time: the true model's forecast stays within 10% of the spread over its whole
// span; one with twice the damping rate leaves it before the end, and the time it reports is
// the last sample time at which the running rms was still within.
TEST(ScorePositions, ValidTimeIsTheSpanForTheTruthAndShorterForAWrongRate) {
  const Oscillator truth = positions_oscillator(0.1);
  const Vector t = regular_times(400, 0.1);
  const Trajectory tr = positions_of(truth, t);
  const PositionsScores good = score_positions(truth.model, truth.theta, {tr}, {10L, "p"});
  EXPECT_DOUBLE_EQ(good.per_trajectory[0].span, t(399) - t(9));
  EXPECT_DOUBLE_EQ(good.per_trajectory[0].valid_time, good.per_trajectory[0].span);
  EXPECT_DOUBLE_EQ(good.valid_time_mean, good.per_trajectory[0].valid_time);
  const Oscillator wrong = positions_oscillator(0.3);
  const PositionsScores bad = score_positions(wrong.model, wrong.theta, {tr}, {10L, "p"});
  const double v = bad.per_trajectory[0].valid_time;
  EXPECT_LT(v, bad.per_trajectory[0].span);
  EXPECT_GT(v, 0.0);
  // By the definition: the running rms at the reported time is within, one sample later not.
  const Matrix& pred = bad.rollouts[0];
  double sq = 0.0;
  Index k = 0;
  for (; k < 390; ++k) {
    const double e = pred(0, k + 1) - tr.z(0, 10 + k);
    sq += e * e;
    if (std::sqrt(sq / static_cast<double>(k + 1)) > 0.1 * bad.per_trajectory[0].spread) break;
  }
  ASSERT_GT(k, 0);
  EXPECT_DOUBLE_EQ(v, t(10 + k - 1) - t(9));
}

TEST(ScorePositions, TheWarmUpIsLeftOutOfTheScore) {
  const Oscillator o = positions_oscillator(0.1);
  Trajectory a = positions_of(o, regular_times(100, 0.1));
  const Trajectory b = positions_of(o, regular_times(60, 0.2));
  PositionsScoreOptions opt;
  opt.warmup = 30;
  const PositionsScores s = score_positions(o.model, o.theta, {a, b}, opt);
  EXPECT_EQ(*s.warmup, 30);
  EXPECT_EQ(s.trajectories, 2);
  EXPECT_EQ(s.per_trajectory[0].scored, 70);
  EXPECT_EQ(s.per_trajectory[1].scored, 30);
  EXPECT_EQ(s.samples_scored, 100);
  EXPECT_EQ(s.rollouts[1].cols(), 31);
  // A sample after the warm-up counts in full; the score is over 100 samples.
  a.z(0, 99) += 1.0;
  const PositionsScores bumped = score_positions(o.model, o.theta, {a, b}, opt);
  EXPECT_NEAR(bumped.rmse, std::sqrt(1.0 / 100.0), 1e-6);
  EXPECT_NEAR(bumped.per_trajectory[0].rmse, std::sqrt(1.0 / 70.0), 1e-6);
  // The default, per trajectory: at least 10, at most 80.
  EXPECT_EQ(default_warmup(11), 10);
  EXPECT_EQ(default_warmup(101), 11);
  EXPECT_EQ(default_warmup(100000), 80);
}

TEST(ScorePositions, ShortTrajectoriesAndBadWarmUpsAreRefusedNamingTheWarmUp) {
  const Oscillator o = positions_oscillator(0.1);
  const Trajectory tr = positions_of(o, regular_times(8, 0.1));
  try {
    score_positions(o.model, o.theta, {tr}, {std::nullopt, "pos.csv"});
    FAIL() << "a trajectory of 8 samples has no sample after the default warm-up";
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "warmup");
    const std::string why = e.what();
    EXPECT_NE(why.find("pos.csv: trajectory 1 of 1 has 8 samples"), std::string::npos) << why;
    EXPECT_NE(why.find("default warm-up"), std::string::npos) << why;
    EXPECT_NE(why.find("a warm-up from 3 to 7"), std::string::npos) << why;
  }
  for (long w : {0L, 2L, -1L}) {
    try {
      score_positions(o.model, o.theta, {tr}, {w, "pos.csv"});
      FAIL() << "warm-up " << w;
    } catch (const OptionError& e) {
      EXPECT_EQ(e.key(), "warmup");
    }
  }
  for (long w : {8L, 9L}) {
    const std::string why = refusal([&] { score_positions(o.model, o.theta, {tr}, {w, "p"}); });
    EXPECT_NE(why.find("leaves none to score"), std::string::npos) << why;
  }
  EXPECT_EQ(score_positions(o.model, o.theta, {tr}, {7L, "p"}).samples_scored, 1);
}

TEST(ScorePositions, HostileDataAreRefused) {
  const Oscillator o = positions_oscillator(0.1);
  const Trajectory good = positions_of(o, regular_times(40, 0.1));
  Trajectory bad = good;
  bad.z(0, 25) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(refusal([&] {
              score_positions(o.model, o.theta, {good, bad}, {10L, "p.csv"});
            }).find("p.csv: trajectory 2 of 2: q1 at sample 25 is nan"),
            std::string::npos);
  bad = good;
  bad.z(0, 3) = 1e200;
  EXPECT_NE(refusal([&] { score_positions(o.model, o.theta, {bad}); }).find("1e150"),
            std::string::npos);
  bad = good;
  bad.t(5) = bad.t(4);
  EXPECT_NE(refusal([&] { score_positions(o.model, o.theta, {bad}); }).find("increasing"),
            std::string::npos);
  // A gap inside the warm-up: no state is fitted across it.
  bad = good;
  bad.t.tail(35).array() += 10.0;
  EXPECT_NE(refusal([&] {
              score_positions(o.model, o.theta, {bad}, {10L, "p"});
            }).find("gap"),
            std::string::npos);
  // Positions the model does not explain over the warm-up.
  bad = good;
  for (Index k = 0; k < 10; ++k) bad.z(0, k) = (k % 2 == 0 ? 1.0 : -1.0);
  EXPECT_NE(refusal([&] {
              score_positions(o.model, o.theta, {bad}, {10L, "p"});
            }).find("does not explain"),
            std::string::npos);
  // Another d, a state file's trajectories, another model type, no data.
  Trajectory two = good;
  two.z = Matrix::Zero(2, good.t.size());
  EXPECT_NE(refusal([&] { score_positions(o.model, o.theta, {two}); }).find("expected d = 1"),
            std::string::npos);
  const Model sympnet = make_model({{"type", "map"}, {"d", 1}, {"width", 3}});
  const Vector theta = Vector::Zero(sympnet.n_params());
  EXPECT_NE(refusal([&] { score_positions(sympnet, theta, {good}); }).find("csympnet model"),
            std::string::npos);
  EXPECT_NE(refusal([&] { score_positions(o.model, o.theta, {}); }).find("no trajectories"),
            std::string::npos);
}

}  // namespace
}  // namespace csympnet
