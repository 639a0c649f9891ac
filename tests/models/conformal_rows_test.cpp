// The AVX-512 d = 1 row kernels of CSympNet-ID (src/models/conformal_rows.cpp) against the
// scalar formulas of the portable loops, bit for bit, on every batch size from 1 to 100 (all
// tail lengths of the eight-sample blocks) and with values that make rounding visible. Where
// the kernels do not run they must say so and write nothing.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "../src/kernels/conformal_rows.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

Matrix random_rows_matrix(Index rows, Index cols, std::mt19937_64& gen) {
  std::normal_distribution<double> normal;
  Matrix m(rows, cols);
  for (Index i = 0; i < m.size(); ++i)
    m.data()[i] = normal(gen) * (1.0 + 1e-3 * static_cast<double>(i % 17));
  return m;
}

TEST(ConformalRows, KernelsMatchTheScalarFormulas) {
  std::mt19937_64 gen(17);
  for (Index n = 1; n <= 100; ++n) {
    SCOPED_TRACE("N = " + std::to_string(n));
    const Matrix z = random_rows_matrix(2, n, gen);
    const Matrix a = random_rows_matrix(1, n, gen);
    // Outputs start as a sentinel one past the batch, which the kernels must leave alone.
    const Matrix sentinel = Matrix::Constant(1, n + 1, -7.0);
    Matrix q = sentinel, p = sentinel, raw = sentinel;
    if (!kernels::split_scaled_rows_simd(z.data(), n, a.data(), q.data(), p.data(), raw.data())) {
      EXPECT_TRUE(same_bits(q, sentinel) && same_bits(p, sentinel) && same_bits(raw, sentinel));
      GTEST_SKIP() << "the AVX-512 row kernels do not run on this machine";
    }
    Matrix q_ref = sentinel, p_ref = sentinel, raw_ref = sentinel;
    for (Index j = 0; j < n; ++j) {
      q_ref(0, j) = z(0, j);
      p_ref(0, j) = z(1, j) * a(0, j);
      raw_ref(0, j) = z(1, j);
    }
    EXPECT_TRUE(same_bits(q, q_ref));
    EXPECT_TRUE(same_bits(p, p_ref));
    EXPECT_TRUE(same_bits(raw, raw_ref));
    Matrix p2 = sentinel, q2 = sentinel;
    ASSERT_TRUE(
        kernels::split_scaled_rows_simd(z.data(), n, a.data(), q2.data(), p2.data(), nullptr));
    EXPECT_TRUE(same_bits(q2, q_ref));
    EXPECT_TRUE(same_bits(p2, p_ref));

    Matrix out = Matrix::Constant(2, n + 1, -7.0);
    Matrix out_ref = out;
    ASSERT_TRUE(kernels::join_scaled_rows_simd(q.data(), raw.data(), a.data(), n, out.data()));
    for (Index j = 0; j < n; ++j) {
      out_ref(0, j) = q(0, j);
      out_ref(1, j) = raw(0, j) * a(0, j);
    }
    EXPECT_TRUE(same_bits(out, out_ref));

    const Matrix p_core = random_rows_matrix(1, n, gen), gp = random_rows_matrix(1, n, gen);
    const Matrix p_in = random_rows_matrix(1, n, gen), h = random_rows_matrix(1, n, gen);
    Matrix terms = sentinel, terms_ref = sentinel;
    ASSERT_TRUE(kernels::damping_terms_simd(z.data(), p_core.data(), gp.data(), p_in.data(),
                                            h.data(), a.data(), n, terms.data()));
    for (Index j = 0; j < n; ++j) {
      const double grad_a = z(1, j) * p_core(0, j) + gp(0, j) * p_in(0, j);
      terms_ref(0, j) = grad_a * h(0, j) * a(0, j);
    }
    EXPECT_TRUE(same_bits(terms, terms_ref));
  }
}

}  // namespace
}  // namespace csympnet::testing
