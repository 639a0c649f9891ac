// The SIMD kernels of the SympNet cores (src/kernels/product*.cpp, sigmoid_avx512.cpp) must
// give Eigen's own results to the bit, so that optimised training reproduces earlier reports.
// Compared here on random operands of many shapes, every operand layout and every epilogue,
// including the shapes the presets use; on machines or builds where the kernels decline, the
// same assertions hold trivially (Eigen computes both sides).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <utility>

#include "../src/kernels/registry.hpp"
#include "../src/kernels/targets.hpp"
#include "../src/models/activation.hpp"
#include "../src/models/core_product.hpp"
#include "support/random_data.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

struct Shape {
  Index m, k, n;
};

std::vector<Shape> shapes() {
  // The presets' products (d = 10, 100; G-SympNet width 50; 400 and 100 pairs) ...
  std::vector<Shape> out = {{10, 10, 400}, {10, 400, 10}, {100, 100, 400}, {100, 400, 100},
                            {50, 10, 400}, {50, 400, 10}, {10, 50, 400},   {10, 10, 100},
                            {100, 100, 1}, {8, 8, 3},     {2, 30, 30},     {6, 9, 17}};
  // ... and random ones, half of them with m ≡ 2 (mod 4) (Eigen's two-row remainder).
  std::mt19937_64 gen(2024);
  for (int t = 0; t < 400; ++t) {
    const Index m =
        t % 2 == 0 ? 2 + 4 * static_cast<Index>(gen() % 30) : 1 + static_cast<Index>(gen() % 130);
    out.push_back({m, 1 + static_cast<Index>(gen() % 300), 1 + static_cast<Index>(gen() % 200)});
  }
  return out;
}

TEST(ExactProduct, MatchesEigenToTheBit) {
  std::mt19937_64 gen(7);
  for (const Shape& s : shapes()) {
    SCOPED_TRACE(::testing::Message() << s.m << " x " << s.k << " x " << s.n);
    const Matrix a = random_matrix(gen, s.m, s.k);
    const Matrix b = random_matrix(gen, s.k, s.n);
    const Matrix at = a.transpose();
    const Matrix bt = b.transpose();
    Matrix ref, mine;
    product_into(a, b, ref);
    detail::core_product(a, b, mine);
    EXPECT_TRUE(same_bits(ref, mine)) << "A B";
    product_into(a, bt.transpose(), ref);
    detail::core_product(a, bt.transpose(), mine);
    EXPECT_TRUE(same_bits(ref, mine)) << "A (Bᵀ)ᵀ";
    product_into(at.transpose(), b, ref);
    detail::core_product(at.transpose(), b, mine);
    EXPECT_TRUE(same_bits(ref, mine)) << "(Aᵀ)ᵀ B";
  }
}

TEST(ExactProduct, EpiloguesMatchEigenToTheBit) {
  std::mt19937_64 gen(8);
  std::uniform_real_distribution<double> step(0.05, 0.15);
  for (const Shape& s : shapes()) {
    SCOPED_TRACE(::testing::Message() << s.m << " x " << s.k << " x " << s.n);
    const Matrix a = random_matrix(gen, s.m, s.k);
    const Matrix b = random_matrix(gen, s.k, s.n);
    const Matrix d0 = random_matrix(gen, s.m, s.n);
    Vector h(s.n);
    for (Index j = 0; j < s.n; ++j) h(j) = step(gen);
    Matrix t, scratch;
    product_into(a, b, t);

    Matrix ref = d0, mine = d0;
    ref += t;
    detail::core_product_add(a, b, mine, scratch);
    EXPECT_TRUE(same_bits(ref, mine)) << "dst += A B";

    ref = d0;
    mine = d0;
    ref.array() += t.array().rowwise() * h.transpose().array();
    detail::core_product_add_scaled(a, b, h.data(), mine, scratch);
    EXPECT_TRUE(same_bits(ref, mine)) << "dst += (A B) H";

    ref = d0;
    mine = d0;
    ref += t;
    Eigen::Map<Matrix> view(mine.data(), s.m, s.n);
    detail::core_product_add(a, b, view, scratch);
    EXPECT_TRUE(same_bits(ref, mine)) << "map += A B";
  }
}

TEST(ExactProduct, ReportsWhatRuns) {
  const std::string isa = kernels::product_kernel_isa();
  EXPECT_TRUE(isa == "avx512" || isa == "avx" || isa == "portable") << isa;
  if (isa != "portable" && kernels::cpu().avx512f) {
    // Where the kernels are built, AVX-512 passes its self-check (and is declined only when the
    // instruction set is capped at AVX2).
    EXPECT_EQ(isa, kernels::avx2_capped() ? "avx" : "avx512");
  }
}

// C = A B and the three epilogues through one kernel, raw operands: B stored by columns
// (bl = 1, bj = k) or by rows (bt: B(l, j) = bt[l*n + j]).
struct RawProduct {
  const Matrix& a;
  const Matrix& b;
  const Matrix& bt;
  const Vector& h;
};

bool run_raw(const char* isa, const RawProduct& p, bool by_rows, Index j0, Index n,
             kernels::Epilogue mode, Matrix& c) {
  const Index m = p.a.rows(), k = p.a.cols(), ldb = p.bt.rows();
  const double* b = by_rows ? p.bt.data() + j0 : p.b.data() + j0 * k;
  double* cj = c.data() + j0 * m;
  const Index bl = by_rows ? ldb : 1, bj = by_rows ? 1 : k;
  if (isa == nullptr) {
    return kernels::sse2_order_product(m, n, k, p.a.data(), m, b, bl, bj, cj, mode,
                                       p.h.data() + j0);
  }
  return kernels::product_kernel_using(isa, m, n, k, p.a.data(), m, b, bl, bj, cj, mode,
                                       p.h.data() + j0);
}

// Every kernel the machine can run, forced (not only the one chosen), on shapes that reach each
// of its tile kinds: 8- and 4-row blocks (m mod 8 = 0, 4), the two tail rows (m ≡ 2 mod 4, and
// m = 2 alone), every column remainder of the 16-column panels, inner dimensions below 8, at
// multiples of 8 and beyond the copy limit of the tail rows (128), both layouts of B.
TEST(ExactProduct, EveryKernelAndTileMatchesEigenToTheBit) {
  std::mt19937_64 gen(11);
  std::uniform_real_distribution<double> step(0.05, 0.15);
  int ran_avx512 = 0;
  for (const char* isa : {"avx512", "avx"}) {
    for (const Index m : {2, 6, 8, 10, 12, 14, 20, 26, 50, 100}) {
      for (const Index k : {1, 5, 8, 10, 17, 130}) {
        for (Index n = 2; n <= 36; n += (n < 20 ? 1 : 7)) {
          SCOPED_TRACE(::testing::Message() << isa << " " << m << " x " << k << " x " << n);
          const Matrix a = random_matrix(gen, m, k);
          const Matrix b = random_matrix(gen, k, n);
          const Matrix bt = b.transpose();
          const Matrix d0 = random_matrix(gen, m, n);
          Vector h(n);
          for (Index j = 0; j < n; ++j) h(j) = step(gen);
          const RawProduct p{a, b, bt, h};
          for (int e = 0; e < 3; ++e) {
            for (const bool by_rows : {false, true}) {
              Matrix mine = d0;
              if (!run_raw(isa, p, by_rows, 0, n, static_cast<kernels::Epilogue>(e), mine)) break;
              ran_avx512 += std::string(isa) == "avx512";
              // The raw products claim Eigen's own `P = A * B` order (no lazy product here).
              Matrix eigen_t(m, n);
              eigen_t.noalias() = a * b;
              Matrix want[3] = {eigen_t, d0 + eigen_t, d0};
              want[2].array() += eigen_t.array().rowwise() * h.transpose().array();
              EXPECT_TRUE(same_bits(want[e], mine)) << "epilogue " << e << (by_rows ? " Bᵀ" : "");
            }
          }
        }
      }
    }
  }
  if (std::string(kernels::product_kernel_isa()) == "avx512") {
    EXPECT_GT(ran_avx512, 0);
  }
}

// A product split into column ranges at a multiple of 4 (as a caller running ranges on
// separate threads does) gives the bits of the whole: an entry's arithmetic depends only on
// its row and on whether its column lies before 4⌊n/4⌋.
TEST(ExactProduct, ColumnRangesGiveTheBitsOfTheWhole) {
  std::mt19937_64 gen(12);
  std::uniform_real_distribution<double> step(0.05, 0.15);
  const Shape cases[] = {{10, 10, 400}, {10, 400, 10},   {50, 10, 400},   {10, 50, 400},
                         {50, 400, 10}, {100, 100, 400}, {100, 400, 100}, {14, 9, 39},
                         {22, 130, 27}, {2, 30, 31}};
  for (const Shape& s : cases) {
    const Matrix a = random_matrix(gen, s.m, s.k);
    const Matrix b = random_matrix(gen, s.k, s.n);
    const Matrix bt = b.transpose();
    const Matrix d0 = random_matrix(gen, s.m, s.n);
    Vector h(s.n);
    for (Index j = 0; j < s.n; ++j) h(j) = step(gen);
    const RawProduct p{a, b, bt, h};
    for (Index split = 4; split + 2 <= s.n; split += (s.n > 40 ? 36 : 4)) {
      for (int e = 0; e < 3; ++e) {
        for (const bool by_rows : {false, true}) {
          SCOPED_TRACE(::testing::Message() << s.m << " x " << s.k << " x " << s.n << " split at "
                                            << split << " epilogue " << e << " Bᵀ " << by_rows);
          const auto mode = static_cast<kernels::Epilogue>(e);
          Matrix whole = d0, parts = d0;
          const bool ran = run_raw(nullptr, p, by_rows, 0, s.n, mode, whole);
          const bool ran1 = run_raw(nullptr, p, by_rows, 0, split, mode, parts);
          const bool ran2 = run_raw(nullptr, p, by_rows, split, s.n - split, mode, parts);
          EXPECT_EQ(ran, ran1);
          EXPECT_EQ(ran, ran2);
          if (ran && ran1 && ran2) {
            EXPECT_TRUE(same_bits(whole, parts));
          }
        }
      }
    }
  }
}

// sigmoid_into before its kernels: both quotients formed, then selected. (Eigen picks its
// packet and scalar elements by the layout of x, so x keeps its own expression type.)
template <typename In>
Matrix reference_sigmoid(const Eigen::MatrixBase<In>& x) {
  Matrix e = (-x.array().abs()).exp().matrix();
  Matrix out(x.rows(), x.cols());
  out.array() = (x.array() >= 0.0).select(1.0 / (1.0 + e.array()), e.array() / (1.0 + e.array()));
  return out;
}

TEST(ExactSigmoid, MatchesEigenToTheBit) {
  std::mt19937_64 gen(9);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> wide(-800.0, 800.0);
  for (int t = 0; t < 600; ++t) {
    const Index rows = 1 + t % 13, cols = 1 + (7 * t) % 97;  // odd and even sizes
    Matrix x(rows, cols);
    for (Index i = 0; i < x.size(); ++i) {
      switch ((t + i) % 4) {
        case 0:
          x.data()[i] = wide(gen);
          break;  // beyond the kernel's range too
        case 1:
          x.data()[i] = 1e-3 * normal(gen);
          break;
        case 2:
          x.data()[i] = std::ldexp(normal(gen), -static_cast<int>(gen() % 1000));
          break;
        default:
          x.data()[i] = (1 + t % 40) * normal(gen);
          break;
      }
    }
    if (t % 50 == 0) {
      x(0, 0) = -0.0;
      x(rows - 1, cols - 1) = 0.0;
    }
    if (t % 97 == 1) x(0, 0) = std::numeric_limits<double>::quiet_NaN();
    if (t % 101 == 2) x(rows - 1, 0) = std::numeric_limits<double>::infinity();
    Matrix mine;
    sigmoid_into(x, mine);
    EXPECT_TRUE(same_bits(reference_sigmoid(x), mine)) << "case " << t;
  }
}

// The comparisons above pass vacuously if sigmoid_into() never reaches its kernel (it did not,
// from commit 7d33cec until the fix that added this test: its dispatch read the expression's
// Flags, which never carry LinearAccessBit). Contiguous operands must reach it.
TEST(ExactSigmoid, ContiguousOperandsReachTheKernel) {
  EXPECT_TRUE(detail::sigmoid_kernel_applies<Matrix>());
  EXPECT_TRUE(detail::sigmoid_kernel_applies<Eigen::Map<const Matrix>>());
  EXPECT_TRUE(detail::sigmoid_kernel_applies<decltype(std::declval<Matrix&>().middleCols(1, 2))>());
  EXPECT_FALSE(detail::sigmoid_kernel_applies<decltype(std::declval<Matrix&>().topRows(2))>());
  using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  EXPECT_FALSE(detail::sigmoid_kernel_applies<RowMajorMatrix>());
}

TEST(ExactSigmoid, BlocksMatchEigenToTheBit) {
  std::mt19937_64 gen(10);
  const Matrix big = random_matrix(gen, 9, 31);
  Matrix mine;
  sigmoid_into(big.topRows(5), mine);  // strided: the Eigen path
  EXPECT_TRUE(same_bits(reference_sigmoid(big.topRows(5)), mine));
  sigmoid_into(big.middleCols(3, 7), mine);  // whole columns: contiguous
  EXPECT_TRUE(same_bits(reference_sigmoid(big.middleCols(3, 7)), mine));
  sigmoid_into(big.topRows(9), mine);  // all rows, but a general block
  EXPECT_TRUE(same_bits(reference_sigmoid(big.topRows(9)), mine));
}

}  // namespace
}  // namespace csympnet::testing
