// Data generation per docs/protocol.md ("Data generation", "Noise", "Test trajectories"):
// draw order, determinism, noise, bounded test sets.
#include "csympnet/data/generate.hpp"

#include <cmath>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "support/same_bits.hpp"

namespace csympnet {
namespace {

System make(const std::string& kind, int d, double alpha = 0.005) {
  SystemSpec s;
  s.kind = kind;
  s.d = d;
  s.alpha = alpha;
  return System(s);
}

TEST(Generate, PairsAreDeterministicAndFollowTheDrawOrder) {
  const System sys = make("cubic", 3);
  const StepSpec steps{0.05, 0.15};
  Rng a(42, "train"), b(42, "train");
  const PairSet p = generate_pairs(sys, 20, steps, a);
  const PairSet q = generate_pairs(sys, 20, steps, b);
  EXPECT_TRUE(testing::same_bits(p.z0, q.z0));
  EXPECT_TRUE(testing::same_bits(p.z1, q.z1));
  EXPECT_TRUE(testing::same_bits(p.h, q.h));
  // Replay the documented order: per pair, 2d components of z0 (q then p), then h.
  Rng replay(42, "train");
  for (Index j = 0; j < 20; ++j) {
    for (Index i = 0; i < sys.dim(); ++i) EXPECT_EQ(p.z0(i, j), replay.uniform(-1.0, 1.0));
    EXPECT_EQ(p.h(j), replay.uniform(0.05, 0.15));
  }
  EXPECT_EQ(a.next_u64(), replay.next_u64());  // nothing else was drawn
  Rng other(43, "train");
  EXPECT_FALSE(testing::same_bits(generate_pairs(sys, 20, steps, other).z0, p.z0));
}

TEST(Generate, PerPairStepsLikeS1) {
  const System sys = make("oscillator", 1);
  Rng rng(42, "train");
  const PairSet p = generate_pairs(sys, 80, StepSpec{0.05, 0.15}, rng);
  ASSERT_EQ(p.size(), 80);
  ASSERT_EQ(p.dim(), 2);
  std::set<double> distinct;
  for (Index j = 0; j < p.size(); ++j) {
    EXPECT_GE(p.h(j), 0.05);
    EXPECT_LE(p.h(j), 0.15);
    distinct.insert(p.h(j));
    // z1 is that pair's own reference flow.
    const Matrix one = reference_flow(sys, p.z0.col(j), p.h.segment(j, 1));
    EXPECT_TRUE(testing::same_bits(p.z1.col(j), one)) << j;
  }
  EXPECT_EQ(distinct.size(), 80u);
  EXPECT_LE(p.z0.cwiseAbs().maxCoeff(), 1.0);
}

TEST(Generate, FixedStepIsExactAndStartsDoNotDependOnTheStepSpec) {
  const System sys = make("chain", 10);
  Rng a(5, "train"), b(5, "train");
  const PairSet fixed = generate_pairs(sys, 30, StepSpec{0.1, 0.1}, a);
  const PairSet varied = generate_pairs(sys, 30, StepSpec{0.05, 0.15}, b);
  EXPECT_TRUE((fixed.h.array() == 0.1).all());
  EXPECT_TRUE(testing::same_bits(fixed.z0, varied.z0));
  // The whole batch shares h = 0.1: each column still equals its own single-column flow.
  EXPECT_TRUE(testing::same_bits(fixed.z1.col(7),
                                 reference_flow(sys, fixed.z0.col(7), fixed.h.segment(7, 1))));
}

TEST(Generate, NoiseScales) {
  const System sys = make("cubic", 10);
  Rng rng(0, "noise-scales");
  const NoiseScales s = noise_scales(sys, StepSpec{}, rng);
  ASSERT_EQ(s.s0.size(), sys.dim());
  ASSERT_EQ(s.s1.size(), sys.dim());
  EXPECT_TRUE((s.s0.array() > 0.0).all());
  EXPECT_TRUE((s.s1.array() > 0.0).all());
  // Starts are U[−1, 1]: std 1/√3 ≈ 0.577; with m = 1000 the estimate is within ~0.03.
  for (Index i = 0; i < sys.dim(); ++i) EXPECT_NEAR(s.s0(i), 1.0 / std::sqrt(3.0), 0.05) << i;
  // After h = 0.1 the ends are a slightly mixed version of the starts: same scale.
  for (Index i = 0; i < sys.dim(); ++i) EXPECT_NEAR(s.s1(i), 0.577, 0.1) << i;
  // Population std of exactly the pairs generate_pairs would make from the same stream.
  Rng again(0, "noise-scales");
  const PairSet p = generate_pairs(sys, 1000, StepSpec{}, again);
  const double mean = p.z1.row(3).mean();
  const double var = (p.z1.row(3).array() - mean).square().sum() / 1000.0;
  EXPECT_NEAR(s.s1(3), std::sqrt(var), 1e-14);
}

TEST(Generate, ZeroNoiseIsANoOpAndKeepsTheStreamAligned) {
  const System sys = make("chain", 3);
  Rng rng(1, "train");
  const PairSet clean = generate_pairs(sys, 25, StepSpec{}, rng);
  NoiseScales s{Vector::Constant(6, 0.5), Vector::Constant(6, 0.7)};
  PairSet a = clean, b = clean;
  a.z0(0, 0) = -0.0;  // +0.0 added to −0.0 would flip the sign bit
  PairSet a_before = a;
  Rng ra(9, "noise"), rb(9, "noise");
  add_noise(a, 0.0, s, ra);
  EXPECT_TRUE(testing::same_bits(a.z0, a_before.z0));
  EXPECT_TRUE(testing::same_bits(a.z1, a_before.z1));
  EXPECT_TRUE(std::signbit(a.z0(0, 0)));
  add_noise(b, 1e-3, s, rb);
  EXPECT_EQ(ra.next_u64(), rb.next_u64());  // the same draws were consumed
  EXPECT_FALSE(testing::same_bits(b.z0, clean.z0));
}

TEST(Generate, NoiseHasTheRequestedScale) {
  const System sys = make("cubic", 10);
  Rng rng(2, "train");
  const PairSet clean = generate_pairs(sys, 400, StepSpec{}, rng);
  NoiseScales s{Vector::LinSpaced(20, 0.1, 2.0), Vector::LinSpaced(20, 3.0, 0.5)};
  PairSet noisy = clean;
  const double sigma = 1e-2;
  Rng nr(3, "noise");
  add_noise(noisy, sigma, s, nr);
  // ξ = (z̃ − z) / (σ s) must look standard normal: 8000 samples per side.
  const Matrix xi0 = ((noisy.z0 - clean.z0).array().colwise() / (sigma * s.s0.array())).matrix();
  const Matrix xi1 = ((noisy.z1 - clean.z1).array().colwise() / (sigma * s.s1.array())).matrix();
  for (const Matrix& xi : {xi0, xi1}) {
    const double n = static_cast<double>(xi.size());
    EXPECT_NEAR(xi.mean(), 0.0, 0.05);                        // 4.5 standard errors
    EXPECT_NEAR(std::sqrt(xi.squaredNorm() / n), 1.0, 0.04);  // 5 standard errors
  }
  // Replay the documented order: per pair, ξ0 then ξ1.
  Rng replay(3, "noise");
  for (Index i = 0; i < 20; ++i) EXPECT_NEAR(xi0(i, 0), replay.normal(), 1e-9);
  for (Index i = 0; i < 20; ++i) EXPECT_NEAR(xi1(i, 0), replay.normal(), 1e-9);
  NoiseScales wrong{Vector::Ones(19), Vector::Ones(20)};
  EXPECT_THROW(add_noise(noisy, sigma, wrong, nr), Error);
  EXPECT_THROW(add_noise(noisy, -1.0, s, nr), Error);
}

TEST(Generate, TestSetShapeAndNoRedrawsForLinearSystems) {
  for (const System& sys : {make("oscillator", 1), make("chain", 10)}) {
    Rng rng(0, "test");
    const TestSet ts = generate_test_set(sys, 10, 0.2, 10.0, rng);
    EXPECT_EQ(ts.redraws, 0);
    ASSERT_EQ(ts.trajectories.size(), 10u);
    for (const Trajectory& tr : ts.trajectories) {
      ASSERT_EQ(tr.t.size(), 51);
      ASSERT_EQ(tr.z.rows(), sys.dim());
      ASSERT_EQ(tr.z.cols(), 51);
      EXPECT_EQ(tr.t(0), 0.0);
      EXPECT_NEAR(tr.t(50), 10.0, 1e-12);
      EXPECT_LE(tr.z.col(0).cwiseAbs().maxCoeff(), 1.0);
      // Grid point to grid point with the reference flow, bit for bit.
      const Matrix step = reference_flow(sys, tr.z.col(24), Vector::Constant(1, 0.2));
      EXPECT_TRUE(testing::same_bits(tr.z.col(25), step));
    }
    // Starts are the stream's first draws, in order.
    Rng replay(0, "test");
    const Matrix starts = replay.uniform_matrix(sys.dim(), 10, -1.0, 1.0);
    for (Index m = 0; m < 10; ++m)
      EXPECT_TRUE(
          testing::same_bits(ts.trajectories[static_cast<std::size_t>(m)].z.col(0), starts.col(m)));
  }
}

TEST(Generate, CubicRedrawFractionMatchesProtocol) {
  // docs/protocol.md, "Test trajectories": about 6% of s3 starts (d = 10) leave ‖z‖_∞ ≤ 10
  // on [0, 10].
  // 500 kept trajectories give ~535 candidates, so the binomial std of the fraction is ~0.011;
  // [0.035, 0.10] is a ±2.5σ band around 6.5% (measured over 10690 candidates: 6.45%).
  const System sys = make("cubic", 10, 0.005);
  Rng rng(0, "test");
  const TestSet ts = generate_test_set(sys, 500, 0.2, 10.0, rng);
  ASSERT_EQ(ts.trajectories.size(), 500u);
  const double fraction = static_cast<double>(ts.redraws) / static_cast<double>(500 + ts.redraws);
  EXPECT_GE(fraction, 0.035);
  EXPECT_LE(fraction, 0.10);
  for (const Trajectory& tr : ts.trajectories) EXPECT_LE(tr.z.cwiseAbs().maxCoeff(), 10.0);
  // Rounds are invisible: asking for fewer trajectories gives a prefix of the same sequence.
  Rng small(0, "test");
  const TestSet first = generate_test_set(sys, 40, 0.2, 10.0, small);
  for (std::size_t m = 0; m < 40; ++m)
    EXPECT_TRUE(testing::same_bits(first.trajectories[m].z, ts.trajectories[m].z)) << m;
}

TEST(Generate, GivesUpAfterMaxRedraws) {
  const System sys = make("chain", 2);
  Rng rng(0, "test");
  // bound 0.1 < box: almost every start is already out of bounds.
  try {
    generate_test_set(sys, 5, 0.2, 1.0, rng, {}, 0.1, 1.0, 20);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    // Said in the user's terms: the options to check, not the library's parameter names.
    EXPECT_NE(std::string(e.what()).find("starts were drawn again"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--omega"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find("max_redraws"), std::string::npos) << e.what();
  }
  EXPECT_THROW(generate_test_set(sys, 0, 0.2, 1.0, rng), Error);
  EXPECT_THROW(generate_test_set(sys, 5, -0.2, 1.0, rng), Error);
}

TEST(Generate, StepSpecValidationAndJson) {
  EXPECT_NO_THROW((StepSpec{0.05, 0.15}.validate()));
  EXPECT_THROW((StepSpec{0.0, 0.1}.validate()), Error);
  EXPECT_THROW((StepSpec{0.2, 0.1}.validate()), Error);
  EXPECT_THROW((StepSpec{0.1, INFINITY}.validate()), Error);
  const nlohmann::json j = StepSpec{0.05, 0.15};
  const auto back = j.get<StepSpec>();
  EXPECT_EQ(back.h_min, 0.05);
  EXPECT_EQ(back.h_max, 0.15);
  EXPECT_THROW((nlohmann::json{{"h_min", 0.1}}.get<StepSpec>()), Error);
  EXPECT_THROW((nlohmann::json{{"h_min", 0.1}, {"h_max", "x"}}.get<StepSpec>()), Error);
  EXPECT_THROW((nlohmann::json{{"h_min", 0.1}, {"h_max", 0.1}, {"h", 1}}.get<StepSpec>()), Error);
  EXPECT_THROW((nlohmann::json{{"h_min", 0.3}, {"h_max", 0.1}}.get<StepSpec>()), Error);
}

}  // namespace
}  // namespace csympnet
