// Internal to src: the cores' matrix products in the "fma" arithmetic (registry.hpp's
// Arithmetic::kFma): every entry in one fixed order of fused multiply-adds, the same bits on
// every CPU, for every thread count and however the columns are split.
//
// The order, per entry C(i, j) of C = A B (k = inner dimension):
//   s = +0;  s = fma(A(i,l), B(l,j), s) for l = 0, 1, ..., k−1;  then the epilogue below.
// An FMA is correctly rounded (IEEE 754 fusedMultiplyAdd), so this chain has one result,
// whatever computes it: the AVX-512 kernel, the AVX2 + FMA kernel and the portable reference
// (std::fma, which glibc runs on the FMA instruction where the CPU has one and emulates
// exactly where not) agree bit for bit. The kernels tile rows, columns and the inner index
// freely: a tile of the inner index continues each chain from its stored partial, so no sum is
// ever split or reassociated.
#pragma once

#include "csympnet/core/types.hpp"
#include "product.hpp"  // Epilogue

namespace csympnet::kernels {

// The epilogue in this arithmetic, for the chain's value s (h_j = h[j]):
//   kStore:     C(i, j) = s
//   kAdd:       C(i, j) = C(i, j) + s
//   kAddScaled: C(i, j) = fma(s, h_j, C(i, j))     (one rounding, as every step of the chain)

// C = A B (then the epilogue), A column-major m x k (leading dimension lda), B(l, j) =
// b[l*bl + j*bj] (k x n), C(i, j) = c[i + j*ldc]; h (length n) is read by kAddScaled only.
// Every shape with m, n, k >= 1 is covered: a kernel where one runs (registry.hpp), the
// portable reference elsewhere; both give the same bits. C must not overlap A, B or h.
void fma_order_product(Index m, Index n, Index k, const double* a, Index lda, const double* b,
                       Index bl, Index bj, double* c, Index ldc, Epilogue mode,
                       const double* h = nullptr);

// The portable reference: the order above with std::fma, one entry at a time (slow; what the
// kernels' self-checks and tests compare with).
void fma_order_reference(Index m, Index n, Index k, const double* a, Index lda, const double* b,
                         Index bl, Index bj, double* c, Index ldc, Epilogue mode,
                         const double* h = nullptr);

// Which fma kernel fma_order_product() runs now: "avx512", "avx2" or "portable".
const char* fma_kernel_isa();

// For tests: fma_order_product() through the named kernel ("avx512" or "avx2") even where the
// other would be chosen or the portable path is forced, with a given inner block (kc >= 1;
// 0 keeps the kernels' own). False, leaving C untouched, when that kernel is not available here
// (built, supported by the CPU, self-checked).
bool fma_kernel_using(const char* isa, Index kc, Index m, Index n, Index k, const double* a,
                      Index lda, const double* b, Index bl, Index bj, double* c, Index ldc,
                      Epilogue mode, const double* h = nullptr);

// fma_order_product() on Eigen operands: A a plain column-major matrix or map, or the
// transpose of one; B likewise; C(i, j) = c[i + j*ldc].
template <typename ADerived, typename BDerived>
void fma_order_product(const Eigen::MatrixBase<ADerived>& a, const Eigen::MatrixBase<BDerived>& b,
                       double* c, Index ldc, Epilogue mode, const double* h) {
  const Index m = a.rows(), k = a.cols(), n = b.cols();
  if (m == 0 || n == 0) return;
  constexpr bool kBTransposed = static_cast<int>(BDerived::Flags) & Eigen::RowMajorBit;
  const auto& bd = b.derived();
  const Index bl = kBTransposed ? bd.outerStride() : 1;
  const Index bj = kBTransposed ? 1 : bd.outerStride();
  if constexpr (static_cast<int>(ADerived::Flags) & Eigen::RowMajorBit) {
    const Matrix a_col = a;  // a copy changes no value
    fma_order_product(m, n, k, a_col.data(), m, bd.data(), bl, bj, c, ldc, mode, h);
  } else {
    fma_order_product(m, n, k, a.derived().data(), a.derived().outerStride(), bd.data(), bl, bj, c,
                      ldc, mode, h);
  }
}

}  // namespace csympnet::kernels
