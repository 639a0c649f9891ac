// Every kernel family against the portable code, bit for bit, through the entry points the
// models use: the same call once with the kernels and once under kernels::ForcePortable, at
// random inputs of many sizes (whole registers, masked tails, odd lengths, a single element).
// On an AVX-512 machine the first call must have run the kernel (checked through the
// registry), so that the comparison is never Eigen against Eigen there.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <string>

#include "../src/kernels/column_scaling.hpp"
#include "../src/kernels/registry.hpp"
#include "../src/kernels/scaled_exp.hpp"
#include "../src/kernels/targets.hpp"
#include "../src/models/activation.hpp"
#include "../src/models/core_product.hpp"
#include "../src/models/csympnet_id.hpp"
#include "../src/models/g_sympnet.hpp"
#include "../src/models/la_sympnet.hpp"
#include "csympnet/train/loss.hpp"
#include "support/random_data.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

using kernels::Family;

// Where the kernels must run: the portable build on an AVX-512 (F, VL) machine, not forced.
bool kernels_expected() {
  return kernels::kernels_built() && kernels::cpu().avx512f && kernels::cpu().avx512vl &&
         !kernels::portable_forced_by_environment();
}

void expect_runs(Family f) {
  if (kernels_expected()) {
    EXPECT_TRUE(kernels::use(f)) << static_cast<int>(f);
  }
}

Matrix random_values(std::mt19937_64& gen, Index rows, Index cols, double scale) {
  std::normal_distribution<double> normal;
  Matrix m(rows, cols);
  for (Index i = 0; i < m.size(); ++i) m.data()[i] = scale * normal(gen);
  return m;
}

TEST(PortableVsKernel, Sigmoid) {
  std::mt19937_64 gen(101);
  expect_runs(Family::kSigmoid);
  for (Index rows : {1, 2, 3, 10}) {
    for (Index cols = 1; cols <= 41; cols += 4) {
      // Some arguments beyond ±700, where the kernel hands element pairs to Eigen.
      Matrix x = random_values(gen, rows, cols, 4.0);
      for (Index i = 0; i < x.size(); i += 5) x.data()[i] *= 300.0;
      Matrix mine, ref;
      sigmoid_into(x, mine);
      {
        const kernels::ForcePortable portable;
        sigmoid_into(x, ref);
      }
      EXPECT_TRUE(same_bits(mine, ref)) << rows << " x " << cols;
    }
  }
}

TEST(PortableVsKernel, ScaledExp) {
  std::mt19937_64 gen(102);
  expect_runs(Family::kScaledExp);
  for (Index n = 1; n <= 67; ++n) {
    const Vector h = random_values(gen, n, 1, 30.0);
    for (const double c : {-0.37, 2.5, -25.0}) {
      Vector mine(n);
      const bool ran = kernels::scaled_exp_simd(c, h.data(), mine.data(), n);
      if (kernels_expected()) {
        EXPECT_TRUE(ran);
      }
      if (!ran) mine = (c * h.array()).exp().matrix();
      {
        const kernels::ForcePortable portable;
        Vector none(n);
        EXPECT_FALSE(kernels::scaled_exp_simd(c, h.data(), none.data(), n));
      }
      const Vector ref = (c * h.array()).exp().matrix();
      EXPECT_TRUE(same_bits(mine, ref)) << "n = " << n << ", c = " << c;
    }
  }
}

TEST(PortableVsKernel, ColumnScaling) {
  std::mt19937_64 gen(103);
  expect_runs(Family::kColumnScaling);
  for (Index m = 1; m <= 25; m += 2) {
    for (Index n : {1, 3, 8}) {
      const Matrix x = random_values(gen, m, n, 1.0), base = random_values(gen, m, n, 1.0);
      const Vector a = random_values(gen, m, 1, 1.0), h = random_values(gen, n, 1, 0.1);
      auto all = [&](Matrix(&out)[4]) {
        out[0].resize(m, n);
        kernels::columns_times(x, h.data(), out[0]);
        out[1].resize(m, n);
        kernels::columns_times_scaled(x, a.data(), h.data(), out[1]);
        out[2] = base;
        kernels::add_columns_times_scaled(x, a.data(), h.data(), out[2]);
        out[3] = base;
        kernels::add_outer(a.data(), h.data(), out[3]);
      };
      Matrix mine[4], ref[4];
      all(mine);
      {
        const kernels::ForcePortable portable;
        all(ref);
      }
      for (int i = 0; i < 4; ++i) EXPECT_TRUE(same_bits(mine[i], ref[i])) << m << " x " << n;
    }
  }
}

TEST(PortableVsKernel, Products) {
  std::mt19937_64 gen(104);
  expect_runs(Family::kProductAvx512);
  const Index shapes[][3] = {{10, 10, 400}, {10, 10, 37}, {50, 10, 81},  {10, 50, 9},
                             {14, 17, 23},  {22, 9, 3},   {100, 100, 41}};
  for (const auto& s : shapes) {
    const Index m = s[0], k = s[1], n = s[2];
    const Matrix a = random_values(gen, m, k, 1.0), b = random_values(gen, k, n, 1.0);
    const Matrix d0 = random_values(gen, m, n, 1.0);
    const Vector h = random_values(gen, n, 1, 0.1);
    auto all = [&](Matrix(&out)[4]) {
      Matrix scratch;
      detail::core_product(a, b, out[0]);
      out[1] = d0;
      detail::core_product_add(a, b, out[1], scratch);
      out[2] = d0;
      detail::core_product_add_scaled(a, b, h.data(), out[2], scratch);
      out[3].resize(m, n);
      detail::core_product_to(a, b, out[3], scratch);
    };
    Matrix mine[4], ref[4];
    all(mine);
    {
      const kernels::ForcePortable portable;
      all(ref);
    }
    for (int i = 0; i < 4; ++i)
      EXPECT_TRUE(same_bits(mine[i], ref[i])) << m << "x" << k << "x" << n;
  }
}

// The models' loss and gradient, which run every family but AdamW's: the d = 1 sweeps, the
// conformal rows and factors and σ (d = 1 LA cores), the products and column scalings (d = 10).
TEST(PortableVsKernel, ModelLossAndGradient) {
  std::mt19937_64 gen(105);
  std::normal_distribution<double> normal;
  std::vector<std::unique_ptr<CSympNetId>> models;
  models.push_back(std::make_unique<CSympNetId>(std::make_unique<LaSympNet>(1, 3, 5)));
  models.push_back(std::make_unique<CSympNetId>(std::make_unique<LaSympNet>(1, 2, 4, 2)));
  models.push_back(std::make_unique<CSympNetId>(std::make_unique<LaSympNet>(10, 3, 4)));
  models.push_back(std::make_unique<CSympNetId>(std::make_unique<GSympNet>(10, 3, 50)));
  for (const Family f : {Family::kD1Sweeps, Family::kConformalRows, Family::kScaledExp,
                         Family::kSigmoid, Family::kColumnScaling, Family::kProductAvx512}) {
    expect_runs(f);
  }
  for (const auto& model : models) {
    for (const Index n : {1, 7, 37, 81, 400}) {
      SCOPED_TRACE(model->hyperparams().dump() + " N=" + std::to_string(n));
      const PairSet pairs = random_pairs(model->dim(), n, gen);
      Vector theta(model->n_params());
      for (Index i = 0; i < theta.size(); ++i) theta(i) = 0.3 * normal(gen);
      Vector g_kernel, g_portable;
      ForwardCache c_kernel, c_portable;
      const double l_kernel = one_step_loss(*model, theta, pairs, &g_kernel, &c_kernel);
      double l_portable = 0.0;
      {
        const kernels::ForcePortable portable;
        l_portable = one_step_loss(*model, theta, pairs, &g_portable, &c_portable);
      }
      EXPECT_TRUE(same_bits(l_kernel, l_portable));
      EXPECT_TRUE(same_bits(g_kernel, g_portable));
    }
  }
}

}  // namespace
}  // namespace csympnet::testing
