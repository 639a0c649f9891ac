// AdamW::step()'s AVX-512 and AVX2 kernels (src/kernels/adamw_update.cpp) must give the portable
// update's results (the Eigen expressions, forced by kernels::ForcePortable) to the bit: θ, and the
// moments through later steps. Each test runs with the widest form and capped at AVX2
// (kernels::CapAtAvx2). Compared over every length 1 … 250 (whole registers and tails), with
// the damping parameter excluded from the decay at positions across lane boundaries, and on edge
// values: zeros of both signs, denormals, huge and tiny gradients, and a zero gradient history (√v
// = 0, the eps guard).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <string>

#include "../src/kernels/product.hpp"
#include "../src/kernels/registry.hpp"
#include "csympnet/train/adamw.hpp"
#include "support/kernel_caps.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

// Steps a kernel-driven and a portable optimiser side by side from the same θ with the same
// gradients, and compares θ after every step (the moments feed the next steps' θ).
void expect_same_steps(Index n, const AdamWOptions& o, std::optional<Index> damping,
                       std::mt19937_64& gen, int steps, bool edge_values) {
  SCOPED_TRACE("n = " + std::to_string(n) + ", decay_damping = " + std::to_string(o.decay_damping) +
               ", damping index = " + std::to_string(damping.value_or(-1)));
  std::normal_distribution<double> normal;
  std::uniform_int_distribution<int> exponent(-12, 6);
  AdamW kernel(n, o, damping), portable(n, o, damping);
  Vector theta_k(n), g(n);
  for (Index i = 0; i < n; ++i) theta_k(i) = normal(gen);
  Vector theta_p = theta_k;
  for (int step = 0; step < steps; ++step) {
    for (Index i = 0; i < n; ++i) g(i) = normal(gen) * std::pow(10.0, exponent(gen));
    if (edge_values) {
      const double edge[] = {0.0,   -0.0,    std::numeric_limits<double>::denorm_min(),
                             1e300, -1e-300, std::numeric_limits<double>::min()};
      for (Index i = 0; i < n; i += 3) g(i) = edge[(i / 3 + step) % 6];
      if (step == 0) theta_k(n - 1) = theta_p(n - 1) = -0.0;
    }
    kernel.step(theta_k, g);
    {
      const kernels::ForcePortable force;  // Eigen's expressions
      portable.step(theta_p, g);
    }
    ASSERT_TRUE(same_bits(theta_k, theta_p)) << "step " << step;
  }
  EXPECT_EQ(kernel.steps_taken(), portable.steps_taken());
}

class AdamWKernel : public KernelCapTest {};

INSTANTIATE_TEST_SUITE_P(Caps, AdamWKernel, ::testing::Values(KernelCap::kNone, KernelCap::kAvx2),
                         kernel_cap_name);

TEST_P(AdamWKernel, RunsOnAvx512Machines) {
  // The kernel needs AVX-512F (or, capped, AVX2) and the portable (SSE2, no FMA) build, as the
  // product kernels do; there it must also have passed its own check, or step() would silently
  // fall back.
  if (kernels_expected_here()) {
    EXPECT_TRUE(
        kernels::use(expected_form(kernels::Family::kAdamW, kernels::Family::kAdamWAvx2, cap())));
  }
}

TEST_P(AdamWKernel, EqualsThePortableStepToTheBitAtEveryLength) {
  std::mt19937_64 gen(20261124);
  AdamWOptions o;
  o.lr = 2e-3;
  o.weight_decay = 1e-2;
  for (Index n = 1; n <= 250; ++n) {
    o.decay_damping = n % 2 == 0;
    expect_same_steps(n, o, Index{(n * 7) / 3 % n}, gen, 4, n % 3 == 0);
  }
}

TEST_P(AdamWKernel, EqualsThePortableStepWithTheDampingParameterAnywhere) {
  std::mt19937_64 gen(5);
  AdamWOptions o;
  o.decay_damping = false;
  for (const Index n : {Index{1}, Index{8}, Index{9}, Index{115}, Index{117}}) {
    for (Index k = 0; k < n; ++k) expect_same_steps(n, o, k, gen, 2, true);
  }
  expect_same_steps(115, o, std::nullopt, gen, 3, true);  // no damping parameter at all
}

TEST_P(AdamWKernel, EqualsThePortableStepOverManySteps) {
  // The bias corrections 1 − βᵗ approach 1; the moments carry every earlier step.
  std::mt19937_64 gen(99);
  AdamWOptions o;
  o.lr = 1e-2;
  o.beta1 = 0.5;
  o.beta2 = 0.9;
  expect_same_steps(115, o, Index{114}, gen, 300, false);
  expect_same_steps(37, o, Index{3}, gen, 300, true);
}

TEST_P(AdamWKernel, ZeroGradientsKeepTheEpsGuard) {
  // v = 0: √v / √(1 − β2ᵗ) + eps = eps, and m = 0 gives a zero update of either sign.
  AdamWOptions o;
  AdamW kernel(19, o, Index{0}), portable(19, o, Index{0});
  Vector theta_k = Vector::LinSpaced(19, -1.0, 1.0), theta_p = theta_k;
  const Vector g = Vector::Zero(19);
  for (int step = 0; step < 3; ++step) {
    kernel.step(theta_k, g);
    {
      const kernels::ForcePortable force;  // Eigen's expressions
      portable.step(theta_p, g);
    }
    ASSERT_TRUE(same_bits(theta_k, theta_p));
  }
}

}  // namespace
}  // namespace csympnet::testing
