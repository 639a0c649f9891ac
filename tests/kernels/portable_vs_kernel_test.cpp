// Every kernel family against the portable code, bit for bit, through the entry points the
// models use: the same call once with the kernels and once under kernels::ForcePortable, at
// random inputs of many sizes (whole registers, masked tails, odd lengths, a single element) and
// special values. Each test runs twice: with the widest forms and capped at AVX2
// (kernels::CapAtAvx2), so that an AVX-512 machine checks the forms a machine without AVX-512
// runs too. On an AVX-512 machine the first call must have run the form of the cap (checked
// through the registry), so that the comparison is never Eigen against Eigen there.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <string>

#include "../src/kernels/column_scaling.hpp"
#include "../src/kernels/conformal_rows.hpp"
#include "../src/kernels/registry.hpp"
#include "../src/kernels/scaled_exp.hpp"
#include "../src/kernels/targets.hpp"
#include "../src/models/activation.hpp"
#include "../src/models/core_product.hpp"
#include "../src/models/csympnet_id.hpp"
#include "../src/models/g_sympnet.hpp"
#include "../src/models/la_sympnet.hpp"
#include "csympnet/train/loss.hpp"
#include "support/kernel_caps.hpp"
#include "support/random_data.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

using kernels::Family;

// Where the kernels must run: the portable build on an AVX-512 (F, VL) machine, not forced.
bool kernels_expected() {
  return kernels_expected_here();
}

class PortableVsKernel : public KernelCapTest {
 protected:
  // The cap's form of the family runs (and, capped, the AVX-512 form does not).
  void expect_runs(Family avx512, Family avx2) const {
    if (!kernels_expected()) return;
    EXPECT_TRUE(kernels::use(expected_form(avx512, avx2, cap()))) << static_cast<int>(avx512);
    if (cap() == KernelCap::kAvx2) {
      EXPECT_FALSE(kernels::use(avx512)) << static_cast<int>(avx512);
    }
  }
};

INSTANTIATE_TEST_SUITE_P(Caps, PortableVsKernel,
                         ::testing::Values(KernelCap::kNone, KernelCap::kAvx2), kernel_cap_name);

// Values the portable code treats by cases: signed zeros, denormals, the smallest normal, ±∞,
// NaN, and arguments on both sides of the kernels' ±700 bounds.
constexpr double kSpecials[] = {0.0,
                                -0.0,
                                std::numeric_limits<double>::denorm_min(),
                                -std::numeric_limits<double>::denorm_min(),
                                std::numeric_limits<double>::min(),
                                std::numeric_limits<double>::infinity(),
                                -std::numeric_limits<double>::infinity(),
                                std::numeric_limits<double>::quiet_NaN(),
                                699.999,
                                -699.999,
                                700.0,
                                -700.0,
                                700.001,
                                -700.001,
                                745.2,
                                -745.2,
                                1e308,
                                -1e308};

// Puts a special value at every stride-th element, from `first` on.
void plant_specials(double* x, Index n, Index first, Index stride) {
  Index k = first;
  for (Index i = first; i < n; i += stride, ++k) {
    x[i] = kSpecials[static_cast<std::size_t>(k) % std::size(kSpecials)];
  }
}

Matrix random_values(std::mt19937_64& gen, Index rows, Index cols, double scale) {
  std::normal_distribution<double> normal;
  Matrix m(rows, cols);
  for (Index i = 0; i < m.size(); ++i) m.data()[i] = scale * normal(gen);
  return m;
}

TEST_P(PortableVsKernel, Sigmoid) {
  std::mt19937_64 gen(101);
  expect_runs(Family::kSigmoid, Family::kSigmoidAvx2);
  for (Index rows : {1, 2, 3, 10}) {
    for (Index cols = 1; cols <= 41; cols += 4) {
      // Some arguments beyond ±700, where the kernel hands element pairs to Eigen, and special
      // values (in some sizes only, so that others run every group in the kernel's own code).
      Matrix x = random_values(gen, rows, cols, 4.0);
      for (Index i = 0; i < x.size(); i += 5) x.data()[i] *= 300.0;
      if (cols % 8 == 1) plant_specials(x.data(), x.size(), cols % 3, 7);
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

TEST_P(PortableVsKernel, ScaledExp) {
  std::mt19937_64 gen(102);
  expect_runs(Family::kScaledExp, Family::kScaledExpAvx2);
  for (Index n = 1; n <= 67; ++n) {
    Vector h = random_values(gen, n, 1, 30.0);
    if (n % 4 == 3) plant_specials(h.data(), n, n % 5, 3);
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

TEST_P(PortableVsKernel, ColumnScaling) {
  std::mt19937_64 gen(103);
  expect_runs(Family::kColumnScaling, Family::kColumnScalingAvx2);
  for (Index m = 1; m <= 25; ++m) {
    for (Index n : {1, 3, 8}) {
      Matrix x = random_values(gen, m, n, 1.0), base = random_values(gen, m, n, 1.0);
      Vector a = random_values(gen, m, 1, 1.0), h = random_values(gen, n, 1, 0.1);
      if (m % 3 == 0) {
        plant_specials(x.data(), x.size(), m % 4, 5);
        plant_specials(a.data(), m, 1, 6);
        plant_specials(base.data(), base.size(), 2, 9);
      }
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

// The conformal rows' three passes against the portable loops' formulas (csympnet_id.cpp), at
// every length up to five registers (every tail) and with special values.
TEST_P(PortableVsKernel, ConformalRows) {
  std::mt19937_64 gen(106);
  expect_runs(Family::kConformalRows, Family::kConformalRowsAvx2);
  for (Index n = 1; n <= 41; ++n) {
    Matrix z = random_values(gen, 2, n, 1.0), dz = random_values(gen, 2, n, 1.0);
    Vector a = random_values(gen, n, 1, 1.0), h = random_values(gen, n, 1, 0.1);
    const Vector pc = random_values(gen, n, 1, 1.0), gp = random_values(gen, n, 1, 1.0),
                 pin = random_values(gen, n, 1, 1.0);
    if (n % 4 == 1) {
      plant_specials(z.data(), z.size(), n % 3, 5);
      plant_specials(dz.data(), dz.size(), 1, 4);
      plant_specials(a.data(), n, 2, 7);
    }
    Vector q(n), p(n), raw(n), terms(n);
    Matrix out(2, n);
    const bool ran =
        kernels::split_scaled_rows_simd(z.data(), n, a.data(), q.data(), p.data(), raw.data()) &&
        kernels::join_scaled_rows_simd(q.data(), raw.data(), a.data(), n, out.data()) &&
        kernels::damping_terms_simd(dz.data(), pc.data(), gp.data(), pin.data(), h.data(), a.data(),
                                    n, terms.data());
    if (kernels_expected()) {
      EXPECT_TRUE(ran);
    }
    if (!ran) continue;
    Vector q_ref(n), p_ref(n), raw_ref(n), terms_ref(n);
    Matrix out_ref(2, n);
    for (Index j = 0; j < n; ++j) {
      q_ref(j) = z(0, j);
      raw_ref(j) = z(1, j);
      p_ref(j) = z(1, j) * a(j);
      out_ref(0, j) = q_ref(j);
      out_ref(1, j) = raw_ref(j) * a(j);
      terms_ref(j) = ((dz(1, j) * pc(j) + gp(j) * pin(j)) * h(j)) * a(j);
    }
    EXPECT_TRUE(same_bits(q, q_ref)) << n;
    EXPECT_TRUE(same_bits(p, p_ref)) << n;
    EXPECT_TRUE(same_bits(raw, raw_ref)) << n;
    EXPECT_TRUE(same_bits(out, out_ref)) << n;
    EXPECT_TRUE(same_bits(terms, terms_ref)) << n;
  }
}

TEST_P(PortableVsKernel, Products) {
  std::mt19937_64 gen(104);
  expect_runs(Family::kProductAvx512, Family::kProductAvx);
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
TEST_P(PortableVsKernel, ModelLossAndGradient) {
  std::mt19937_64 gen(105);
  std::normal_distribution<double> normal;
  std::vector<std::unique_ptr<CSympNetId>> models;
  models.push_back(std::make_unique<CSympNetId>(std::make_unique<LaSympNet>(1, 3, 5)));
  models.push_back(std::make_unique<CSympNetId>(std::make_unique<LaSympNet>(1, 2, 4, 2)));
  models.push_back(std::make_unique<CSympNetId>(std::make_unique<LaSympNet>(10, 3, 4)));
  models.push_back(std::make_unique<CSympNetId>(std::make_unique<GSympNet>(10, 3, 50)));
  expect_runs(Family::kD1Sweeps, Family::kD1SweepsAvx2);
  expect_runs(Family::kConformalRows, Family::kConformalRowsAvx2);
  expect_runs(Family::kScaledExp, Family::kScaledExpAvx2);
  expect_runs(Family::kSigmoid, Family::kSigmoidAvx2);
  expect_runs(Family::kColumnScaling, Family::kColumnScalingAvx2);
  expect_runs(Family::kProductAvx512, Family::kProductAvx);
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
