// Internal to src/models: the matrix products of the SympNet cores through SIMD kernels that
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

#include "csympnet/models/activation.hpp"

namespace csympnet::detail {

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
bool exact_product(Index m, Index n, Index k, const double* a, Index lda, const double* b, Index bl,
                   Index bj, double* c, Epilogue mode = Epilogue::kStore,
                   const double* h = nullptr);

// What the kernels run on this machine: "avx512", "avx" or "eigen" (Eigen itself).
const char* exact_product_isa();

// For tests: exact_product() through the named kernel ("avx512" or "avx") even where the other
// would be chosen, without the once-per-process check. False when that kernel cannot run on
// this machine or build, or the shape is not covered.
bool exact_product_using(const char* isa, Index m, Index n, Index k, const double* a, Index lda,
                         const double* b, Index bl, Index bj, double* c,
                         Epilogue mode = Epilogue::kStore, const double* h = nullptr);

// exact_product() on Eigen operands: A a plain column-major matrix or map, or the transpose
// of one; B likewise; c the m x n destination. False when not covered.
template <typename ADerived, typename BDerived>
bool exact_product(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
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
    return exact_product(m, n, k, a_col.data(), m, bd.data(), bl, bj, c, mode, h);
  } else {
    return exact_product(m, n, k, a.derived().data(), a.derived().outerStride(), bd.data(), bl, bj,
                         c, mode, h);
  }
}

// The cores' products: through the kernels where they cover the shape, else Eigen's product
// (product_into), to the bit as the Eigen expression in each comment. A destination may be a
// matrix, a map, or a block of whole columns of a matrix (the column-split passes write their
// range of a batch in place).

// out = a b into a matrix resized to fit, as product_into(a, b, out).
template <typename ADerived, typename BDerived>
void core_product(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                  Matrix& out) {
  out.resize(a.rows(), b.cols());
  if (!exact_product(a, b, out.data(), Epilogue::kStore, nullptr)) product_into(a, b, out);
}

// out = a b into a destination of that shape, as `product_into(a, b, t); out = t;`.
template <typename ADerived, typename BDerived, typename Dst>
void core_product_to(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                     Dst&& out, Matrix& scratch) {
  if (out.outerStride() == a.rows() && exact_product(a, b, out.data(), Epilogue::kStore, nullptr)) {
    return;
  }
  product_into(a, b, scratch);
  out = scratch;
}

// dst += a b, as `product_into(a, b, t); dst += t;`.
template <typename ADerived, typename BDerived, typename Dst>
void core_product_add(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                      Dst&& dst, Matrix& scratch) {
  if (dst.outerStride() == a.rows() && exact_product(a, b, dst.data(), Epilogue::kAdd, nullptr)) {
    return;
  }
  product_into(a, b, scratch);
  dst += scratch;
}

// dst += (a b) h per column (h: b.cols() contiguous steps), as
// `product_into(a, b, t); dst.array() += t.array().rowwise() * hᵀ;`.
template <typename ADerived, typename BDerived, typename Dst>
void core_product_add_scaled(const Eigen::MatrixBase<ADerived>& a,
                             const Eigen::MatrixBase<BDerived>& b, const double* h, Dst&& dst,
                             Matrix& scratch) {
  if (dst.outerStride() == a.rows() && exact_product(a, b, dst.data(), Epilogue::kAddScaled, h)) {
    return;
  }
  product_into(a, b, scratch);
  dst.array() += scratch.array().rowwise() * Eigen::Map<const RowVector>(h, scratch.cols()).array();
}

// Whether the kernels compute a b for A m x k and B k x n, both column-major: then the
// product's entries do not depend on how its columns are split into calls (at multiples of 4).
bool exact_product_covers(Index m, Index k, Index n);

}  // namespace csympnet::detail
