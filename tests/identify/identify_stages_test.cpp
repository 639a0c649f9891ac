// The stages of identify() one by one (src/identify/identify_stages.hpp): each takes a
// typed state and returns what it found; identify_test.cpp runs them together.
#include "../../src/identify/identify_stages.hpp"

#include <gtest/gtest.h>

#include <set>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"

namespace csympnet::detail {
namespace {

std::vector<Trajectory> random_trajectories(int n, int points, Index d, std::uint64_t seed,
                                            bool irregular = false) {
  Rng rng(seed, "stages-test");
  std::vector<Trajectory> out;
  for (int k = 0; k < n; ++k) {
    Trajectory t;
    t.t.resize(points);
    t.t(0) = 0.0;
    for (int i = 1; i < points; ++i)
      t.t(i) = t.t(i - 1) + (irregular ? rng.uniform(0.05, 0.15) : 0.1);
    t.z = Matrix::Random(2 * d, points);
    out.push_back(t);
  }
  return out;
}

TEST(IdentifyStages, InspectDataSummarisesStepsAndRefusesSubnormalSteps) {
  const auto trajs = random_trajectories(3, 11, 2, 1, true);
  const DataFacts f = inspect_data(trajs, false);
  EXPECT_EQ(f.d, 2);
  EXPECT_TRUE(f.varying_steps);
  EXPECT_GE(f.h_min, 0.05);
  EXPECT_LE(f.h_max, 0.15);
  EXPECT_EQ(f.summary["samples"], 33);
  EXPECT_EQ(f.summary["steps"], 30);
  EXPECT_FALSE(inspect_data(random_trajectories(2, 5, 1, 2), false).varying_steps);
  auto tiny = random_trajectories(1, 3, 1, 3);
  tiny[0].t << 0.0, 1e-310, 2e-310;
  EXPECT_THROW(inspect_data(tiny, false), Error);
}

TEST(IdentifyStages, SplitBlocksCutsALongTrajectoryAndHoldsOutWholeBlocksBySeed) {
  const auto one = random_trajectories(1, 401, 1, 4);
  IdentifyConfig c;
  const BlockSplit s = split_blocks(one, false, c);
  EXPECT_EQ(static_cast<long>(s.blocks.size()), c.target_blocks);
  EXPECT_EQ(s.train_blocks.size() + s.val_blocks.size(), s.blocks.size());
  EXPECT_EQ(static_cast<long>(s.val_blocks.size()),
            std::lround(c.val_fraction * static_cast<double>(s.blocks.size())));
  EXPECT_EQ(s.summary["kind"], "segments of trajectories");
  // An automatic window starts at one step and may grow to 4 (adapt_windows).
  EXPECT_TRUE(s.adaptive);
  EXPECT_EQ(s.m, 1);
  EXPECT_EQ(s.m_long, 4);
  // Held-out blocks are whole: no held-out start time is a training start time.
  std::set<double> train_starts;
  for (const Trajectory& b : s.train_blocks) train_starts.insert(b.t(0));
  for (const Trajectory& b : s.val_blocks) EXPECT_EQ(train_starts.count(b.t(0)), 0u);
  // Same seed, same split; another seed, another.
  const BlockSplit s2 = split_blocks(one, false, c);
  ASSERT_EQ(s2.val_blocks.size(), s.val_blocks.size());
  for (std::size_t i = 0; i < s.val_blocks.size(); ++i)
    EXPECT_EQ(s2.val_blocks[i].t(0), s.val_blocks[i].t(0));
  IdentifyConfig other = c;
  other.seed = 7;
  const BlockSplit s3 = split_blocks(one, false, other);
  bool differs = false;
  for (std::size_t i = 0; i < s.val_blocks.size(); ++i)
    differs = differs || s3.val_blocks[i].t(0) != s.val_blocks[i].t(0);
  EXPECT_TRUE(differs);
}

TEST(IdentifyStages, SplitBlocksTakesPairsAsOneStepBlocksAndRefusesLongerWindows) {
  const auto pairs = random_trajectories(30, 2, 1, 5);
  IdentifyConfig c;
  const BlockSplit s = split_blocks(pairs, true, c);
  EXPECT_EQ(s.blocks.size(), 30u);
  EXPECT_FALSE(s.adaptive);
  EXPECT_EQ(s.m, 1);
  EXPECT_EQ(s.summary["kind"], "pairs");
  c.window = 3;
  EXPECT_THROW(split_blocks(pairs, true, c), OptionError);
  EXPECT_THROW(split_blocks(random_trajectories(1, 8, 1, 6), false, IdentifyConfig{}),
               Error);  // fewer than 3 blocks
}

TEST(IdentifyStages, WarmStartChoosesDofScalesByDimensionAndStartsBetaAtGammaZero) {
  for (Index d : {1, 3}) {
    const auto trajs = random_trajectories(25, 12, d, 8);
    IdentifyConfig c;
    const BlockSplit s = split_blocks(trajs, false, c);
    const WarmStart w = warm_start(s, d, c);
    const double beta = w.beta_init;
    EXPECT_EQ(w.dof_scales, d > 1 ? DofScales::kLearned : DofScales::kFixed);
    EXPECT_EQ(w.choices["dof_scales"], d > 1 ? "learned" : "fixed");
    if (w.gamma)
      EXPECT_EQ(beta, std::max(std::abs(w.gamma->gamma), 1e-6));
    else
      EXPECT_EQ(beta, 0.1);
    EXPECT_GT(beta, 0.0);
  }
}

TEST(IdentifyStages, DefaultCoresShrinkWithDimensionAndGainStepPolynomialsWhenStepsVary) {
  const auto one = default_cores(1, false);
  ASSERT_EQ(one.size(), 2u);
  EXPECT_EQ(core_name(one[0]), "la:5:20");
  EXPECT_EQ(core_name(one[1]), "g:6:32");
  EXPECT_EQ(core_name(default_cores(1, true)[0]), "la:5:20:h2");
  EXPECT_EQ(core_name(default_cores(10, false)[0]), "la:4:5");
  EXPECT_EQ(core_name(default_cores(16, false)[0]), "la:4:2");
  EXPECT_EQ(core_name(default_cores(16, false)[1]), "g:6:11");
}

Evidence interval_result(double low, double high) {
  Evidence r;
  r.gamma = 0.5 * (low + high);
  SandwichInterval s;
  s.low = low;
  s.high = high;
  s.stable = true;
  r.interval = s;
  r.quality.val_relative_residual = 0.01;
  r.quality.train_loss = r.quality.val_loss = 1e-4;
  return r;
}

BlockSplit moving_split() {
  BlockSplit s;
  s.train.z0 = Matrix::Zero(2, 3);
  s.train.zm = Matrix::Ones(2, 3);
  return s;
}

TEST(IdentifyStages, VerdictPutsFailedChecksFirstAndNamesGrowthInsteadOfNoDamping) {
  Evidence ok_in = interval_result(0.09, 0.11);
  const Verdict ok = verdict(moving_split(), 0.1, true, ok_in);
  EXPECT_TRUE(ok.identified);
  EXPECT_EQ(ok.text, "identified");

  Evidence zero_in = interval_result(-0.01, 0.02);
  const Verdict zero = verdict(moving_split(), 0.1, true, zero_in);
  EXPECT_FALSE(zero.identified);
  EXPECT_EQ(zero.text, "not identified");
  ASSERT_EQ(zero.reasons.size(), 1u);
  EXPECT_NE(zero.reasons[0].find("no damping"), std::string::npos);
  EXPECT_EQ(zero.reasons[0].find("growth"), std::string::npos);

  // A signed rate that leans below 0 without the check's 99% confidence: the reason names
  // a slow growth as possible too, with the signed rate.
  Evidence leans_in = interval_result(-0.01, 0.02);
  ModelCheck lean;
  lean.name = "dissipation";
  lean.details = {{"signed_rate", -0.003}, {"interval", {-0.006, -0.0002}}};
  leans_in.checks = {lean};
  const Verdict leans = verdict(moving_split(), 0.1, true, leans_in);
  EXPECT_EQ(leans.text, "not identified");
  ASSERT_EQ(leans.reasons.size(), 1u);
  EXPECT_NE(leans.reasons[0].find("or from a slow growth (signed rate -0.003"), std::string::npos)
      << leans.reasons[0];

  Evidence grows_in = interval_result(-0.01, 0.02);
  ModelCheck g;
  g.name = "dissipation";
  g.assumption = "dissipation";
  g.passed = false;
  g.sentence = "the motion grows";
  grows_in.checks = {g};
  const Verdict grows = verdict(moving_split(), 0.1, true, grows_in);
  EXPECT_FALSE(grows.identified);
  EXPECT_TRUE(grows.rejected);
  EXPECT_EQ(grows.text, "model rejected");
  ASSERT_EQ(grows.reasons.size(), 1u);  // no "cannot tell from no damping" beside it
  EXPECT_NE(grows.reasons[0].find("the motion grows"), std::string::npos);

  Evidence modes_in = interval_result(0.09, 0.11);
  ModelCheck m;
  m.name = "one_rate";
  m.assumption = "one damping rate for every mode";
  m.passed = false;
  m.sentence = "the modes damp at different rates";
  ModelCheck untestable;
  untestable.name = "linear_damping";
  untestable.applicable = false;
  modes_in.checks = {untestable, m};
  const Verdict modes = verdict(moving_split(), 0.1, true, modes_in);
  EXPECT_EQ(modes.text, "model rejected");
  EXPECT_EQ(modes.reasons.size(), 1u);
}

// A model that explains too little cannot test its assumptions: the check is kept, undecided,
// and the verdict is "not identified" with the quality reason.
TEST(IdentifyStages, VerdictLeavesChecksUndecidedWhenTheModelExplainsTooLittle) {
  Evidence poor_in = interval_result(0.09, 0.11);
  poor_in.quality.val_relative_residual = 0.95;
  ModelCheck m;
  m.name = "one_rate";
  m.assumption = "one damping rate for every mode";
  m.passed = false;
  m.sentence = "the modes damp at different rates";
  poor_in.checks = {m};
  const Verdict poor = verdict(moving_split(), 0.1, true, poor_in);
  EXPECT_EQ(poor.text, "not identified");
  EXPECT_FALSE(poor.rejected);
  EXPECT_TRUE(poor.checks[0].passed);
  EXPECT_FALSE(poor.checks[0].applicable);
  EXPECT_NE(poor.checks[0].sentence.find("not decided"), std::string::npos);
  ASSERT_EQ(poor.reasons.size(), 1u);
  EXPECT_NE(poor.reasons[0].find("less than 10% of the motion"), std::string::npos);
}

// The neural candidates by dimension: LA with step polynomials when the steps vary, then G.
TEST(IdentifyStages, VaryingStepsGiveTheLaCandidateStepPolynomials) {
  for (Index d : {1, 3}) {
    const auto regular = default_cores(d, false), varying = default_cores(d, true);
    ASSERT_EQ(varying.size(), 2u);
    EXPECT_EQ(varying[0]["type"], "la");
    EXPECT_EQ(varying[0]["step_terms"], 2);
    EXPECT_FALSE(regular[0].contains("step_terms"));
    EXPECT_EQ(varying[1]["type"], "g");
  }
}

}  // namespace
}  // namespace csympnet::detail

namespace csympnet::detail {
namespace {

// A library candidate given a linear term per coordinate: the same map at every θ (the new
// coefficients start at 0, the rest of θ carried over, wavenumbers and β moved past them),
// and nothing to add when the terms are there or the core is no library.
TEST(IdentifyStages, RestPositionTermsLeaveTheMapAsItWas) {
  Rng rng(12, "rest-terms");
  const nlohmann::json core = {{"type", "library"},
                               {"terms", {"q1^2", "sin(q1-q2)", "cos(q1-q2)", "q2^4", "q1"}},
                               {"mass", "full"}};
  Candidate lib;
  lib.core = core;
  lib.inner = make_model({{"type", "csympnet"}, {"d", 2}, {"core", core}, {"beta_init", 0.1}});
  for (int draw = 0; draw < 5; ++draw) {
    lib.theta = Vector(lib.inner.n_params());
    lib.inner.map->init_params(rng, lib.theta);
    lib.theta += 0.2 * rng.normal_matrix(lib.theta.size(), 1, 1.0);
    const std::optional<Candidate> x = with_rest_position_terms(lib, 2);
    ASSERT_TRUE(x.has_value());
    const std::vector<std::string> terms = x->core.at("terms");
    ASSERT_EQ(terms.size(), 6u);
    EXPECT_EQ(terms.back(), "q2");
    EXPECT_EQ(x->theta.size(), lib.theta.size() + 1);
    EXPECT_EQ(x->inner.map->damping_rate(x->theta), lib.inner.map->damping_rate(lib.theta));
    const Matrix z = rng.normal_matrix(4, 6, 0.7);
    Vector h(6);
    for (Index k = 0; k < 6; ++k) h(k) = rng.uniform(0.05, 0.2);
    const Matrix before = lib.inner.map->forward(lib.theta, z, h, nullptr);
    const Matrix after = x->inner.map->forward(x->theta, z, h, nullptr);
    EXPECT_LE((after - before).cwiseAbs().maxCoeff(), 1e-14 * (1.0 + before.norm()));
  }
  Candidate whole;
  whole.core = {{"type", "library"}, {"terms", {"q1", "q2", "q1^2", "q2^2"}}};
  whole.inner = make_model({{"type", "csympnet"}, {"d", 2}, {"core", whole.core}});
  EXPECT_FALSE(with_rest_position_terms(whole, 2).has_value());
  Candidate neural;
  neural.core = {{"type", "la"}, {"layers", 2}, {"sublayers", 2}};
  neural.inner = make_model({{"type", "csympnet"}, {"d", 2}, {"core", neural.core}});
  EXPECT_FALSE(with_rest_position_terms(neural, 2).has_value());
}

}  // namespace
}  // namespace csympnet::detail
