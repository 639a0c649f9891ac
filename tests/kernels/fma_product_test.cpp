// The fma arithmetic of the cores' products (src/kernels/fma_product.hpp): both kernels, forced
// one at a time, give the std::fma reference's bits at random shapes (odd m, n, k, inner
// dimensions of thousands, every epilogue, B stored by columns and by rows, any inner block);
// a product split into column ranges anywhere gives one call's bits; the reference is the
// fused chain (exact where every partial sum is representable, within the rounding bound of a
// k-term sum elsewhere); and the arithmetic switch parses, refuses and restores as documented.
// On a CPU with AVX-512F (or AVX2 + FMA) the kernel must run: the comparison is never the
// reference against itself there.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "../src/kernels/fma_product.hpp"
#include "../src/kernels/registry.hpp"
#include "../src/kernels/targets.hpp"
#include "../src/models/core_product.hpp"
#include "csympnet/core/error.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

using kernels::Epilogue;

constexpr Epilogue kEpilogues[] = {Epilogue::kStore, Epilogue::kAdd, Epilogue::kAddScaled};

void expect_same_bits(const Matrix& mine, const Matrix& ref, const std::string& what) {
  EXPECT_TRUE(same_bits(mine, ref))
      << what << ": largest difference " << (mine - ref).cwiseAbs().maxCoeff();
}

Matrix random_fma_matrix(std::mt19937_64& gen, Index rows, Index cols) {
  std::normal_distribution<double> normal;
  Matrix m(rows, cols);
  for (Index i = 0; i < m.size(); ++i) m.data()[i] = normal(gen);
  return m;
}

// The kernels this machine must run (built, CPU support, not forced).
std::vector<const char*> expected_kernels() {
  std::vector<const char*> out;
  if (kernels::portable_forced_by_environment()) return out;
#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__) && !defined(__clang__)
  if (kernels::cpu().avx512f) out.push_back("avx512");
  if (kernels::cpu().avx2 && kernels::cpu().fma) out.push_back("avx2");
#endif
  return out;
}

// One product's operands with B stored by columns (bt = false) or as the transpose of a stored
// n x k matrix (bt = true), C's leading dimension ldc >= m.
struct Operands {
  Index m, n, k, ldc;
  bool bt;
  Matrix a, b_store, c0;
  Vector h;
  const double* b() const { return b_store.data(); }
  Index bl() const { return bt ? n : 1; }
  Index bj() const { return bt ? 1 : k; }
};

Operands random_operands(std::mt19937_64& gen, Index m, Index n, Index k, bool bt, Index pad) {
  Operands o{m,
             n,
             k,
             m + pad,
             bt,
             random_fma_matrix(gen, m, k),
             bt ? random_fma_matrix(gen, n, k) : random_fma_matrix(gen, k, n),
             random_fma_matrix(gen, m + pad, n),
             random_fma_matrix(gen, n, 1).col(0)};
  return o;
}

Matrix reference(const Operands& o, Epilogue e) {
  Matrix c = o.c0;
  kernels::fma_order_reference(o.m, o.n, o.k, o.a.data(), o.m, o.b(), o.bl(), o.bj(), c.data(),
                               o.ldc, e, o.h.data());
  return c;
}

TEST(FmaProduct, EveryKernelGivesTheReferenceBits) {
  std::mt19937_64 gen(7);
  std::uniform_int_distribution<Index> small(1, 37);
  const auto isas = expected_kernels();
  for (const char* isa : isas) {
    EXPECT_TRUE(kernels::available(std::string(isa) == "avx512" ? kernels::Family::kFmaProductAvx512
                                                                : kernels::Family::kFmaProductAvx2))
        << isa;
  }
  for (int trial = 0; trial < 60; ++trial) {
    // Inner dimensions beyond the kernels' inner block in a fifth of the trials.
    const Index m = small(gen), n = small(gen);
    const Index k = trial % 5 == 4 ? 300 + 97 * (trial % 7) : small(gen);
    const bool bt = trial % 2 == 1;
    const Operands o = random_operands(gen, m, n, k, bt, trial % 3);
    for (const Epilogue e : kEpilogues) {
      const Matrix ref = reference(o, e);
      for (const char* isa : isas) {
        SCOPED_TRACE(std::string(isa) + " m=" + std::to_string(m) + " n=" + std::to_string(n) +
                     " k=" + std::to_string(k) + " epilogue=" + std::to_string(int(e)) +
                     (bt ? " bt" : ""));
        // The kernels' own inner block, and small ones that split every chain many times.
        for (const Index kc : {Index{0}, Index{1}, Index{5}, Index{64}}) {
          Matrix mine = o.c0;
          ASSERT_TRUE(kernels::fma_kernel_using(isa, kc, m, n, k, o.a.data(), m, o.b(), o.bl(),
                                                o.bj(), mine.data(), o.ldc, e, o.h.data()));
          expect_same_bits(mine, ref, "kernel vs reference");
        }
      }
      // The dispatching entry point: a kernel, or the reference where none runs.
      Matrix mine = o.c0;
      kernels::fma_order_product(m, n, k, o.a.data(), m, o.b(), o.bl(), o.bj(), mine.data(), o.ldc,
                                 e, o.h.data());
      expect_same_bits(mine, ref, "fma_order_product vs reference");
    }
  }
}

// The cores' large inner dimensions (the parameter gradients' sums over N samples): 100 x N
// times N x 100 with B stored by rows, at N = 4000; and a blocked inner dimension with more
// columns than one panel (each panel's columns, and their factors h_j, continue from their own
// partials), every epilogue.
TEST(FmaProduct, LargeInnerDimensions) {
  std::mt19937_64 gen(11);
  const Operands o = random_operands(gen, 100, 100, 4000, true, 0);
  const Matrix ref = reference(o, Epilogue::kAdd);
  const Operands wide = random_operands(gen, 5, 1100, 700, false, 1);
  for (const char* isa : expected_kernels()) {
    Matrix mine = o.c0;
    ASSERT_TRUE(kernels::fma_kernel_using(isa, 0, o.m, o.n, o.k, o.a.data(), o.m, o.b(), o.bl(),
                                          o.bj(), mine.data(), o.ldc, Epilogue::kAdd, nullptr));
    expect_same_bits(mine, ref, isa);
    for (const Epilogue e : kEpilogues) {
      Matrix w = wide.c0;
      ASSERT_TRUE(kernels::fma_kernel_using(isa, 0, wide.m, wide.n, wide.k, wide.a.data(), wide.m,
                                            wide.b(), wide.bl(), wide.bj(), w.data(), wide.ldc, e,
                                            wide.h.data()));
      expect_same_bits(w, reference(wide, e), std::string(isa) + " wide");
    }
  }
}

// Columns computed as separate calls, split anywhere (not only at multiples of a tile), give
// one call's bits: the thread-count invariance of the column-split passes.
TEST(FmaProduct, ColumnRangesGiveOneCallsBits) {
  std::mt19937_64 gen(13);
  for (int trial = 0; trial < 12; ++trial) {
    const Index m = 3 + 7 * trial % 29, n = 40 + trial, k = 5 + 31 * trial % 300;
    const bool bt = trial % 2 == 0;
    const Operands o = random_operands(gen, m, n, k, bt, 0);
    for (const Epilogue e : kEpilogues) {
      Matrix whole = o.c0;
      kernels::fma_order_product(m, n, k, o.a.data(), m, o.b(), o.bl(), o.bj(), whole.data(), m, e,
                                 o.h.data());
      std::uniform_int_distribution<Index> cut(1, 9);
      Matrix split = o.c0;
      for (Index j0 = 0; j0 < n;) {
        const Index w = std::min<Index>(cut(gen), n - j0);
        kernels::fma_order_product(m, w, k, o.a.data(), m, o.b() + j0 * o.bj(), o.bl(), o.bj(),
                                   split.data() + j0 * m, m, e, o.h.data() + j0);
        j0 += w;
      }
      expect_same_bits(split, whole, "split columns vs one call");
    }
  }
}

// The reference is the fused chain: with small integers every product and partial sum is exact,
// so it equals the exact product; with random values it lies within the rounding bound of a
// k-term sum, |ŝ − s| <= γ_k Σ|a||b| (γ_k = k u / (1 − k u)), and differs from Eigen's
// separate multiplies and adds in some entries (one rounding per step instead of two).
TEST(FmaProduct, ReferenceIsTheFusedChain) {
  std::mt19937_64 gen(17);
  std::uniform_int_distribution<int> small_int(-50, 50);
  const Index m = 9, n = 11, k = 123;
  Matrix a(m, k), b(k, n);
  for (Index i = 0; i < a.size(); ++i) a.data()[i] = small_int(gen);
  for (Index i = 0; i < b.size(); ++i) b.data()[i] = small_int(gen);
  Matrix c(m, n);
  kernels::fma_order_reference(m, n, k, a.data(), m, b.data(), 1, k, c.data(), m, Epilogue::kStore);
  const Matrix exact = a * b;
  expect_same_bits(c, exact, "integers: exact");

  a = random_fma_matrix(gen, m, k);
  b = random_fma_matrix(gen, k, n);
  kernels::fma_order_reference(m, n, k, a.data(), m, b.data(), 1, k, c.data(), m, Epilogue::kStore);
  const Matrix eigen = a * b;
  const Matrix bound_terms = a.cwiseAbs() * b.cwiseAbs();
  const double u = std::numeric_limits<double>::epsilon() / 2;
  const double gamma = static_cast<double>(k) * u / (1 - static_cast<double>(k) * u);
  Index differ = 0;
  for (Index j = 0; j < n; ++j) {
    for (Index i = 0; i < m; ++i) {
      // The sum in extended precision (64-bit significands), far closer than the bound.
      long double s = 0;
      for (Index l = 0; l < k; ++l) s += static_cast<long double>(a(i, l)) * b(l, j);
      EXPECT_LE(std::abs(static_cast<long double>(c(i, j)) - s), gamma * bound_terms(i, j));
      differ += c(i, j) != eigen(i, j);
    }
  }
  EXPECT_GT(differ, 0) << "no entry differs from mul-then-add: not a fused chain";

  // The scaled epilogue is one more fused step: C = fma(s, h_j, C).
  Matrix d = random_fma_matrix(gen, m, n);
  const Vector h = random_fma_matrix(gen, n, 1).col(0);
  Matrix scaled = d;
  kernels::fma_order_reference(m, n, k, a.data(), m, b.data(), 1, k, scaled.data(), m,
                               Epilogue::kAddScaled, h.data());
  for (Index j = 0; j < n; ++j) {
    for (Index i = 0; i < m; ++i) EXPECT_EQ(scaled(i, j), std::fma(c(i, j), h(j), d(i, j)));
  }
}

// The cores' entry points follow the process's arithmetic: fma gives the fma-order bits, sse2
// Eigen's (the guard restores the previous arithmetic).
TEST(FmaProduct, CoreProductsFollowTheArithmetic) {
  std::mt19937_64 gen(19);
  const Matrix s = random_fma_matrix(gen, 10, 10);
  const Matrix x = random_fma_matrix(gen, 10, 64);
  Matrix fma_out, sse2_out, scratch;
  const kernels::Arithmetic before = kernels::arithmetic();
  {
    const kernels::UseArithmetic use(kernels::Arithmetic::kFma);
    EXPECT_TRUE(kernels::product_kernel_covers(3, 7, 1));  // every shape splits
    detail::core_product(s, x, fma_out);
  }
  EXPECT_EQ(kernels::arithmetic(), before);
  {
    const kernels::UseArithmetic use(kernels::Arithmetic::kSse2);
    detail::core_product(s, x, sse2_out);
  }
  Matrix ref(10, 64);
  kernels::fma_order_reference(10, 64, 10, s.data(), 10, x.data(), 1, 10, ref.data(), 10,
                               Epilogue::kStore);
  expect_same_bits(fma_out, ref, "fma arithmetic");
  Matrix eigen;
  eigen.noalias() = s * x;
  expect_same_bits(sse2_out, eigen, "sse2 arithmetic");
}

TEST(FmaProduct, ArithmeticNamesParseAndOthersAreRefused) {
  EXPECT_EQ(kernels::parse_arithmetic("fma", "X"), kernels::Arithmetic::kFma);
  EXPECT_EQ(kernels::parse_arithmetic("sse2", "X"), kernels::Arithmetic::kSse2);
  EXPECT_STREQ(kernels::to_string(kernels::Arithmetic::kFma), "fma");
  EXPECT_STREQ(kernels::to_string(kernels::Arithmetic::kSse2), "sse2");
  for (const char* bad : {"FMA", "", "avx512", "sse2 "}) {
    try {
      (void)kernels::parse_arithmetic(bad, "CSYMPNET_ARITHMETIC");
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("CSYMPNET_ARITHMETIC"), std::string::npos) << what;
      EXPECT_NE(what.find("expected 'sse2'"), std::string::npos) << what;
    }
  }
}

}  // namespace
}  // namespace csympnet::testing
