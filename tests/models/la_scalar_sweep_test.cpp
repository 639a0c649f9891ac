// The AVX-512 and AVX2 d = 1 LA-SympNet sweeps (src/kernels/d1_*_avx512.cpp, d1_*_avx2.cpp) must
// give the portable d = 1 code's results to the bit (q, p, everything recorded in the cache, the
// input gradients and dL/dθ), so that training with them reproduces earlier reports. Each test
// runs with the widest form and capped at AVX2 (kernels::CapAtAvx2). Compared at random
// parameters and batch sizes on both sides of the kernels' blocks (80 and 40 samples, 16 and 40
// in the AVX2 form), with and without step polynomials; on machines or builds where the kernels
// do not run, the dispatching assertions hold trivially and the direct calls are skipped.
#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <random>

#include "../src/kernels/d1_sweeps.hpp"
#include "../src/kernels/product.hpp"
#include "../src/kernels/registry.hpp"
#include "../src/kernels/targets.hpp"
#include "../src/models/la_sympnet.hpp"
#include "support/kernel_caps.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

struct Case {
  Index layers, sublayers, step_terms, n;
};

// A random problem: θ (step coefficients included), states, steps and upstream gradients.
struct SweepProblem {
  Vector theta, h;
  Matrix q, p, gq, gp;
  Vector grad0;
};

// specials: some samples of q and p are ±0, denormal, ±∞ or huge (σ's Eigen fallback lanes).
SweepProblem random_sweep_problem(const LaSympNet& net, Index n, std::mt19937_64& gen,
                                  double wide = 0.0, bool specials = false) {
  std::normal_distribution<double> normal;
  auto fill = [&](auto& x, double scale) {
    for (Index i = 0; i < x.size(); ++i) x.data()[i] = scale * normal(gen);
  };
  SweepProblem pr;
  pr.theta.resize(net.n_params());
  fill(pr.theta, 0.6);
  pr.h.resize(n);
  for (Index j = 0; j < n; ++j) pr.h(j) = 0.02 + 0.4 * std::abs(normal(gen));
  pr.q.resize(1, n);
  pr.p.resize(1, n);
  pr.gq.resize(1, n);
  pr.gp.resize(1, n);
  fill(pr.q, 1.5);
  fill(pr.p, 1.5);
  // Every third sample far out, so that some σ arguments fall below −700, where the σ kernel
  // hands element pairs to Eigen's own routine.
  for (Index j = 0; j < n; j += 3) {
    pr.q(0, j) *= 1.0 + wide;
    pr.p(0, j) *= 1.0 + wide;
  }
  if (specials) {
    // No NaN among the inputs: where two NaNs meet, which one an add passes on depends on the
    // order the compiler gives its commutative operands, in the portable code as here. The NaNs
    // that ∞ − ∞ and 0 · ∞ make are all the same default NaN.
    const double special[] = {0.0,
                              -0.0,
                              std::numeric_limits<double>::denorm_min(),
                              std::numeric_limits<double>::infinity(),
                              -std::numeric_limits<double>::infinity(),
                              1e300};
    for (Index j = 1; j < n; j += 7) pr.q(0, j) = special[(j / 7) % 6];
    for (Index j = 4; j < n; j += 11) pr.p(0, j) = special[(j / 11 + 3) % 6];
  }
  fill(pr.gq, 1.0);
  fill(pr.gp, 1.0);
  pr.grad0.resize(net.n_params());
  fill(pr.grad0, 0.1);
  return pr;
}

// Portable forward and backward against the dispatching flow()/flow_backward() and, where the
// kernels run, against the kernels called directly.
void expect_same_as_portable(const Case& c, std::mt19937_64& gen, double wide = 0.0,
                             bool specials = false) {
  SCOPED_TRACE("L = " + std::to_string(c.layers) + ", m = " + std::to_string(c.sublayers) +
               ", step_terms = " + std::to_string(c.step_terms) + ", N = " + std::to_string(c.n));
  const LaSympNet net(1, c.layers, c.sublayers, c.step_terms);
  const SweepProblem pr = random_sweep_problem(net, c.n, gen, wide, specials);

  Matrix q_ref = pr.q, p_ref = pr.p;
  ForwardCache cache_ref;
  Matrix gq_ref = pr.gq, gp_ref = pr.gp;
  Vector grad_ref = pr.grad0;
  {
    const kernels::ForcePortable portable;  // the d = 1 loops in Eigen expressions
    net.flow(pr.theta, q_ref, p_ref, pr.h, &cache_ref);
    net.flow_backward(pr.theta, cache_ref, pr.h, gq_ref, gp_ref, grad_ref);
  }
  if (!specials) {
    ASSERT_TRUE(q_ref.allFinite() && p_ref.allFinite() && grad_ref.allFinite());
  }

  const auto& steps_ref = cache_ref.context<LaSympNet::FlowContext>("test").steps;
  auto expect_steps = [&](const std::vector<Matrix>& steps) {
    ASSERT_EQ(steps.size(), steps_ref.size());
    for (std::size_t s = 0; s < steps.size(); ++s) {
      EXPECT_TRUE(same_bits(steps[s], steps_ref[s])) << "step " << s;
    }
  };

  {  // What training runs.
    Matrix q = pr.q, p = pr.p, gq = pr.gq, gp = pr.gp;
    Vector grad = pr.grad0;
    ForwardCache cache;
    net.flow(pr.theta, q, p, pr.h, &cache);
    EXPECT_TRUE(same_bits(q, q_ref));
    EXPECT_TRUE(same_bits(p, p_ref));
    expect_steps(cache.context<LaSympNet::FlowContext>("test").steps);
    net.flow_backward(pr.theta, cache, pr.h, gq, gp, grad);
    EXPECT_TRUE(same_bits(gq, gq_ref));
    EXPECT_TRUE(same_bits(gp, gp_ref));
    EXPECT_TRUE(same_bits(grad, grad_ref));
    // Without a cache (validation, rollouts).
    Matrix q2 = pr.q, p2 = pr.p;
    net.flow(pr.theta, q2, p2, pr.h, nullptr);
    EXPECT_TRUE(same_bits(q2, q_ref));
    EXPECT_TRUE(same_bits(p2, p_ref));
  }

  if (!kernels::use(kernels::Family::kD1Sweeps) && !kernels::use(kernels::Family::kD1SweepsAvx2)) {
    return;
  }
  const kernels::D1Core core{c.layers, c.sublayers, c.step_terms == 2,
                             c.layers * (c.sublayers + 3) - 1};
  Matrix q = pr.q, p = pr.p, gq = pr.gq, gp = pr.gp;
  Vector grad = pr.grad0;
  std::vector<Matrix> steps(net.recorded_steps());
  ASSERT_TRUE(kernels::d1_flow_simd(core, pr.theta.data(), q.data(), p.data(), pr.h.data(), c.n,
                                    steps.data()));
  EXPECT_TRUE(same_bits(q, q_ref));
  EXPECT_TRUE(same_bits(p, p_ref));
  expect_steps(steps);
  ASSERT_TRUE(kernels::d1_backward_simd(core, pr.theta.data(), steps.data(), pr.h.data(), c.n,
                                        gq.data(), gp.data(), grad.data()));
  EXPECT_TRUE(same_bits(gq, gq_ref));
  EXPECT_TRUE(same_bits(gp, gp_ref));
  EXPECT_TRUE(same_bits(grad, grad_ref));
}

class LaScalarSweep : public KernelCapTest {};

INSTANTIATE_TEST_SUITE_P(Caps, LaScalarSweep, ::testing::Values(KernelCap::kNone, KernelCap::kAvx2),
                         kernel_cap_name);

TEST_P(LaScalarSweep, RunsWhereTheProductKernelsRun) {
  // Both need AVX-512F (or, capped, AVX2) and the portable (SSE2, no FMA) build; the sweeps
  // (AVX-512VL too) must also have passed their own check, or flow() would silently fall back to
  // the portable code.
  if (kernels_expected_here()) {
    EXPECT_TRUE(kernels::use(
        expected_form(kernels::Family::kD1Sweeps, kernels::Family::kD1SweepsAvx2, cap())));
  }
}

TEST_P(LaScalarSweep, EqualsThePortableSweepsToTheBit) {
  std::mt19937_64 gen(42);
  for (const Index terms : {Index{1}, Index{2}}) {
    for (const Index n : {1, 2, 7, 8, 13, 64, 79, 80, 81, 95, 160, 173}) {
      expect_same_as_portable({5, 20, terms, n}, gen);  // s1's core
      expect_same_as_portable({3, 5, terms, n}, gen);   // odd sublayer count
    }
    expect_same_as_portable({1, 1, terms, 13}, gen);  // one shear, no activation
    expect_same_as_portable({2, 2, terms, 80}, gen);
    expect_same_as_portable({4, 7, terms, 37}, gen);
  }
}

TEST_P(LaScalarSweep, EqualsThePortableSweepsAtEveryBatchSize) {
  // Every N: the forward's blocks of 80 and the backward's of 40 (with its column sums'
  // partial last block), odd and even, with and without step polynomials.
  std::mt19937_64 gen(3);
  for (Index n = 1; n <= 250; ++n) expect_same_as_portable({5, 20, 1 + n % 2, n}, gen);
}

TEST_P(LaScalarSweep, EqualsThePortableSweepsWithSpecialValues) {
  // ±0, denormals, ±∞ and huge values among the states: the forward's σ in registers must hand
  // the groups the σ kernel does not treat itself to it, and ∞ and the NaNs it makes must travel
  // as in the portable code.
  std::mt19937_64 gen(13);
  for (const Index terms : {Index{1}, Index{2}}) {
    for (const Index n : {8, 41, 80, 81, 160, 203}) {
      expect_same_as_portable({5, 20, terms, n}, gen, 0.0, true);
      expect_same_as_portable({3, 4, terms, n}, gen, 0.0, true);
    }
  }
}

TEST_P(LaScalarSweep, EqualsThePortableSweepsAtRandomShapes) {
  std::mt19937_64 gen(7);
  std::uniform_int_distribution<int> layers(1, 6), sublayers(1, 24), samples(1, 250);
  for (int rep = 0; rep < 60; ++rep) {
    expect_same_as_portable({layers(gen), sublayers(gen), 1 + rep % 2, samples(gen)}, gen);
  }
}

TEST_P(LaScalarSweep, EqualsThePortableSweepsWithSaturatedSigmoids) {
  std::mt19937_64 gen(11);
  for (const Index terms : {Index{1}, Index{2}}) {
    for (const Index n : {3, 80, 99}) expect_same_as_portable({5, 20, terms, n}, gen, 2000.0);
  }
}

}  // namespace
}  // namespace csympnet::testing
