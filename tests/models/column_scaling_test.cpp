// The per-column scalings (src/models/column_scaling.{hpp,cpp}) against the Eigen broadcast
// expressions they replace, bit for bit, on every column count and row count around the
// kernels' registers (8 rows), for whole matrices and for blocks of columns; and the kernels
// must run where AVX-512 does, or the comparisons say nothing about them.
#include "../src/kernels/column_scaling.hpp"

#include <gtest/gtest.h>

#include <random>

#include "../src/kernels/product.hpp"
#include "support/random_data.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

TEST(ColumnScaling, EqualsTheBroadcastExpressions) {
  std::mt19937_64 gen(4);
  for (Index m : {1, 2, 3, 7, 8, 9, 10, 15, 16, 17, 50, 100}) {
    for (Index n : {1, 2, 5, 16, 33}) {
      SCOPED_TRACE("m=" + std::to_string(m) + " n=" + std::to_string(n));
      const Matrix x = random_matrix(gen, m, n + 4);
      const Vector a = random_matrix(gen, m, 1).col(0);
      const Vector h = random_matrix(gen, n + 4, 1).col(0);
      const Matrix start = random_matrix(gen, m, n + 4);
      // Whole matrices.
      Matrix mine(m, n + 4);
      kernels::columns_times(x, h.data(), mine);
      EXPECT_TRUE(same_bits(Matrix((x.array().rowwise() * h.transpose().array()).matrix()), mine));
      mine = x;
      kernels::scale_columns(mine, h.data());
      EXPECT_TRUE(same_bits(Matrix((x.array().rowwise() * h.transpose().array()).matrix()), mine));
      kernels::columns_times_scaled(x, a.data(), h.data(), mine);
      Matrix ref = ((x.array().colwise() * a.array()).rowwise() * h.transpose().array()).matrix();
      EXPECT_TRUE(same_bits(ref, mine));
      mine = start;
      kernels::add_columns_times_scaled(x, a.data(), h.data(), mine);
      ref = start;
      ref.array() += (x.array().colwise() * a.array()).rowwise() * h.transpose().array();
      EXPECT_TRUE(same_bits(ref, mine));
      mine = start;
      kernels::add_outer(a.data(), h.data(), mine);
      ref = start;
      ref.noalias() += a * h.transpose();
      EXPECT_TRUE(same_bits(ref, mine));
      mine = start;
      kernels::add_outer(a.data(), h.data() + 3, mine.middleCols(3, n));
      ref = start;
      ref.middleCols(3, n).noalias() += a * h.segment(3, n).transpose();
      EXPECT_TRUE(same_bits(ref, mine));
      mine = start;
      kernels::copy_columns(x.middleCols(1, n), mine.middleCols(2, n));
      ref = start;
      ref.middleCols(2, n) = x.middleCols(1, n);
      EXPECT_TRUE(same_bits(ref, mine));
      // Blocks of columns, as the column-split passes use them; the columns around stay.
      mine = start;
      kernels::add_columns_times_scaled(x.middleCols(2, n), a.data(), h.data() + 2,
                                        mine.middleCols(2, n));
      ref = start;
      ref.middleCols(2, n).array() += (x.middleCols(2, n).array().colwise() * a.array()).rowwise() *
                                      h.segment(2, n).transpose().array();
      EXPECT_TRUE(same_bits(ref, mine));
      mine = start;
      kernels::columns_times(x.middleCols(1, n), h.data() + 1, mine.middleCols(1, n));
      ref = start;
      ref.middleCols(1, n) =
          (x.middleCols(1, n).array().rowwise() * h.segment(1, n).transpose().array()).matrix();
      EXPECT_TRUE(same_bits(ref, mine));
    }
  }
}

TEST(ColumnScaling, KernelsRunWhereTheProductKernelsRunAvx512) {
  if (std::string(kernels::product_kernel_isa()) != "avx512") GTEST_SKIP() << "no AVX-512 here";
  const double x[3] = {1.0, 2.0, 3.0}, h[1] = {0.5};
  double out[3];
  EXPECT_TRUE(kernels::columns_times_simd(3, 1, x, h, out));
  EXPECT_TRUE(kernels::columns_times_scaled_simd(3, 1, x, x, h, out, true));
  EXPECT_TRUE(kernels::add_outer_simd(3, 1, x, h, out));
}

}  // namespace
}  // namespace csympnet::testing
