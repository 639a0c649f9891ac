// Internal to src: the matrix products of the SympNet cores through SIMD kernels that
// reproduce, to the bit, what Eigen's own product computes in the portable build.
//
// Why it can: in the portable build (SSE2, no FMA) Eigen 3.4's GEMM evaluates a product that
// fits in one cache block as, per entry, one running sum over the inner index k from 0, with
// separate multiplies and adds, except on a two-row remainder (rows ≡ 2 mod 4), where it adds
// even and odd k in two sums first (docs/benchmarks.md, "Exact products"). The kernels here
// follow the same order with wider registers (AVX-512 or AVX2, still without FMA), so every
// entry is the same IEEE computation. When a shape, a build or a machine falls outside what
// is covered, they decline and Eigen runs as before.
#pragma once

#include "csympnet/core/types.hpp"

namespace csympnet::kernels {

// What happens to an entry v = (A B)(i, j) of the product (v = 0 + s, Eigen's value):
enum class Epilogue {
  kStore,      // C(i, j) = v
  kAdd,        // C(i, j) = C(i, j) + v              (dst += A B)
  kAddScaled,  // C(i, j) = C(i, j) + v · h_j        (dst.array() += (A B).array().rowwise() * hᵀ)
};

// C = A B (or the epilogue's update of C), with A column-major m x k (leading dimension lda),
// B(l, j) = b[l*bl + j*bj] (k x n, stored by columns, bl = 1, or by rows, bj = 1) and C
// column-major m x n (leading dimension m); h (length n) is read by kAddScaled only. Returns
// false, leaving C untouched, unless every entry is bit-identical to Eigen's
// `P.noalias() = A * B` followed by the epilogue as an Eigen expression. The columns of one
// product may be computed as several calls on ranges split at multiples of 4 (b, c and h
// advanced to the range's first column): the entries come out as from one call, provided every
// call is taken (a range of one column, or one small enough for Eigen's lazy product, is not).
bool sse2_order_product(Index m, Index n, Index k, const double* a, Index lda, const double* b,
                        Index bl, Index bj, double* c, Epilogue mode = Epilogue::kStore,
                        const double* h = nullptr);

// Which product kernel runs now: "avx512", "avx" or "portable" (Eigen itself).
const char* product_kernel_isa();

// For tests: sse2_order_product() through the named kernel ("avx512" or "avx") even where the
// other would be chosen or the portable path is forced. False when that kernel is not
// available here (registry.hpp: built, supported, self-checked) or the shape is not covered.
bool product_kernel_using(const char* isa, Index m, Index n, Index k, const double* a, Index lda,
                          const double* b, Index bl, Index bj, double* c,
                          Epilogue mode = Epilogue::kStore, const double* h = nullptr);

// sse2_order_product() on Eigen operands: A a plain column-major matrix or map, or the transpose
// of one; B likewise; c the m x n destination. False when not covered.
template <typename ADerived, typename BDerived>
bool sse2_order_product(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                        double* c, Epilogue mode, const double* h) {
  constexpr Index kLazyBelow = 8;  // product_into's switch to the lazy product
  if (a.rows() < kLazyBelow || a.cols() < kLazyBelow) return false;
  const Index m = a.rows(), k = a.cols(), n = b.cols();
  // B's strides: column-major storage, or the transpose of column-major storage.
  constexpr bool kBTransposed = static_cast<int>(BDerived::Flags) & Eigen::RowMajorBit;
  const auto& bd = b.derived();
  const Index bl = kBTransposed ? bd.outerStride() : 1;
  const Index bj = kBTransposed ? 1 : bd.outerStride();
  if constexpr (static_cast<int>(ADerived::Flags) & Eigen::RowMajorBit) {
    // A transposed: packing it column-major first changes no arithmetic (Eigen packs too).
    const Matrix a_col = a;
    return sse2_order_product(m, n, k, a_col.data(), m, bd.data(), bl, bj, c, mode, h);
  } else {
    return sse2_order_product(m, n, k, a.derived().data(), a.derived().outerStride(), bd.data(), bl,
                              bj, c, mode, h);
  }
}

// Whether the kernels compute a b for A m x k and B k x n, both column-major: then the
// product's entries do not depend on how its columns are split into calls (at multiples of 4).
// In the fma arithmetic (registry.hpp) every shape is covered: its order never depends on them.
bool product_kernel_covers(Index m, Index k, Index n);

}  // namespace csympnet::kernels
