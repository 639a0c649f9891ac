#include "csympnet/train/gamma_warm_start.hpp"

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/core/options.hpp"
#include "csympnet/data/generate.hpp"

namespace csympnet {
namespace {

PairSet expm_pairs(const SystemSpec& spec, Index n, double h_min, double h_max,
                   std::uint64_t seed) {
  ReferenceOptions ref;
  ref.method = Reference::kExpm;
  Rng rng(seed, "warm-start-test");
  return generate_pairs(System(spec), n, StepSpec{h_min, h_max}, rng, ref);
}

TEST(GammaWarmStart, DetIsExactForALinearOscillatorAtOneStep) {
  SystemSpec s;  // ω = 1, γ = 0.05
  const PairSet p = expm_pairs(s, 40, 0.1, 0.1, 1);
  const GammaWarmStart w = gamma_warm_start(p);
  EXPECT_EQ(w.method, WarmStartMethod::kDet);
  EXPECT_EQ(w.groups, 1);
  EXPECT_NEAR(w.gamma, 0.05, 1e-11);
}

TEST(GammaWarmStart, DetIsExactForALinearChainAtSeveralSteps) {
  SystemSpec s;
  s.kind = "chain";
  s.d = 3;
  s.gamma = 0.2;
  // Two step groups: the fit combines them by least squares in h.
  const PairSet p = concat_pairs({expm_pairs(s, 30, 0.1, 0.1, 2), expm_pairs(s, 30, 0.3, 0.3, 3)});
  const GammaWarmStart w = gamma_warm_start(p);
  EXPECT_EQ(w.method, WarmStartMethod::kDet);
  EXPECT_EQ(w.groups, 2);
  EXPECT_NEAR(w.gamma, 0.2, 1e-10);
}

TEST(GammaWarmStart, MidpointHasItsPredictedBiasAtIrregularSteps) {
  // Each pair has its own h, so no step group exists. For the oscillator the midpoint rule
  // sees (2/h) tanh(hμ/2) = μ − h²μ³/12 + … instead of each eigenvalue μ = −γ/2 ± iω, so
  // γ₀ − γ ≈ (h²/6) Re μ³ = (h²/6)(3γω²/2 − γ³/8) > 0, below its value at h_max = 0.15.
  SystemSpec s;
  const PairSet p = expm_pairs(s, 80, 0.05, 0.15, 4);
  const GammaWarmStart w = gamma_warm_start(p);
  EXPECT_EQ(w.method, WarmStartMethod::kMidpoint);
  const double bound = 0.15 * 0.15 / 6.0 * (1.5 * 0.05 - 0.05 * 0.05 * 0.05 / 8.0);
  EXPECT_GT(w.gamma - 0.05, 0.0);
  EXPECT_LT(w.gamma - 0.05, bound);
}

TEST(GammaWarmStart, NamesTheMethodWhenItCannotApply) {
  SystemSpec s;
  const PairSet p = expm_pairs(s, 40, 0.05, 0.15, 5);  // all steps differ
  try {
    gamma_warm_start(p, WarmStartMethod::kDet);
    FAIL() << "det accepted data without step groups";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("det"), std::string::npos) << e.what();
  }
  EXPECT_THROW(gamma_warm_start(expm_pairs(s, 3, 0.1, 0.1, 6)), Error);  // too few pairs
}

// The one spelling of each estimator, as reports write it; others refused by name.
TEST(GammaWarmStart, MethodSpellingsRoundTripAndOthersAreRefused) {
  for (const std::string& name : warm_start_method_names())
    EXPECT_EQ(to_string(parse_warm_start_method(name)), name);
  EXPECT_EQ(to_string(WarmStartMethod::kMidpoint), "midpoint");
  try {
    parse_warm_start_method("svd");
    FAIL() << "'svd' was accepted";
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "warm_start_method");
    EXPECT_STREQ(e.what(),
                 "warm_start_method: 'svd' is not a choice; expected one of auto, det, midpoint");
  }
}

}  // namespace
}  // namespace csympnet
