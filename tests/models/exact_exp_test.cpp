// scaled_exp_simd (src/kernels/scaled_exp_avx512.cpp) must give, bit for bit, what the portable
// build's Eigen expression `(c * h.array()).exp()` gives: on every batch size from 1 to 100 (the
// packet pairs and the odd last element), at arguments of both signs, up to and past the
// ±700 bounds where lanes are handed to Eigen's routine, at ±0, ±∞ and NaN. On machines or
// builds where the kernel does not run, it must say so and write nothing.
#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <random>

#include "../src/kernels/product.hpp"
#include "../src/kernels/scaled_exp.hpp"
#include "../src/models/activation.hpp"

namespace csympnet::testing {
namespace {

Vector eigen_exp(double c, const Vector& h) {
  return (c * h.array()).exp().matrix();
}

void expect_same(double c, const Vector& h) {
  Vector out = Vector::Constant(h.size(), -1.0);
  if (!kernels::scaled_exp_simd(c, h.data(), out.data(), h.size())) {
    EXPECT_TRUE((out.array() == -1.0).all()) << "a declining kernel wrote output";
    return;
  }
  const Vector ref = eigen_exp(c, h);
  for (Index j = 0; j < h.size(); ++j) {
    EXPECT_EQ(std::memcmp(&out(j), &ref(j), sizeof(double)), 0)
        << "c = " << c << ", h = " << h(j) << ", j = " << j << " of " << h.size() << ": " << out(j)
        << " vs " << ref(j);
  }
}

TEST(ExactExp, MatchesEigenOnRandomBatches) {
  std::mt19937_64 gen(3);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (Index n = 1; n <= 100; ++n) {
    for (const double scale : {0.3, 30.0, 600.0}) {
      Vector h(n);
      for (Index j = 0; j < n; ++j) h(j) = scale * uniform(gen);
      expect_same(-0.5 * std::abs(normal(gen)), h);
      expect_same(normal(gen), h);
    }
  }
}

TEST(ExactExp, MatchesEigenAtTheBoundsAndSpecialValues) {
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double denorm = std::numeric_limits<double>::denorm_min();
  Vector h(24);
  h << 700.0, -700.0, std::nextafter(700.0, 800.0), std::nextafter(-700.0, -800.0), 709.7, -709.7,
      745.2, -745.2, 800.0, -800.0, 0.0, -0.0, denorm, -denorm, inf, -inf, nan, 1e-300, -1e-300,
      1.0, -1.0, 0.5, -0.5, 1e6;
  // Every value in every lane position, and alone in its block of eight.
  for (Index shift = 0; shift < 8; ++shift) {
    Vector rotated(h.size());
    for (Index j = 0; j < h.size(); ++j) rotated(j) = h((j + shift) % h.size());
    expect_same(1.0, rotated);
    expect_same(-1.0, rotated);
  }
  for (Index j = 0; j < h.size(); ++j) {
    Vector block = Vector::Constant(9, 0.25);
    block(j % 9) = h(j);
    expect_same(1.0, block);
  }
}

// The comparisons above pass vacuously when a kernel declines. Where the product kernels run
// AVX-512 (so the build is the portable one and the CPU has it), the exp and σ kernels, which
// share their Cephes exp (src/kernels/sse2_order.hpp), must run too, and so pass their self-checks.
TEST(ExactExp, KernelsRunWhereTheProductKernelsDo) {
  if (std::string(kernels::product_kernel_isa()) != "avx512") GTEST_SKIP() << "no AVX-512 here";
  const double h[3] = {0.1, -2.0, 3.5};
  double out[3];
  EXPECT_TRUE(kernels::scaled_exp_simd(-0.5, h, out, 3));
  EXPECT_TRUE(kernels::sigmoid_simd(h, out, 3));
}

}  // namespace
}  // namespace csympnet::testing
