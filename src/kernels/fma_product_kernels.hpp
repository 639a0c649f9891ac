// Internal to the fma-order products (fma_product.cpp): what the kernel files share.
// fma_product_avx512.cpp and fma_product_avx2.cpp hold the kernels; fma_product.cpp blocks the
// inner index, checks the kernels against the portable reference and picks one.
#pragma once

#include "fma_product.hpp"

// The kernels need GCC's target attributes on x86; elsewhere the reference runs.
#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__) && !defined(__clang__)
#define CSYMPNET_FMA_KERNELS 1
#endif

namespace csympnet::kernels {

// One product's operands, as fma_order_product() takes them.
struct FmaArgs {
  Index m, n, k;
  const double* a;
  Index lda;
  const double* b;
  Index bl, bj;
  double* c;
  Index ldc;
  Epilogue mode;
  const double* h;  // any array of n doubles when the epilogue reads no h
};

// One inner block l = k0..k1−1 of every entry's chain: s starts at `in` (s(i, j) =
// in[i + j*ldi]) or at +0 when `in` is null, takes the block's FMAs in order of l, and then goes
// to `out` (out[i + j*ldo], the partial for the next block) or, when `out` is null, through the
// epilogue into C. `in` and `out` may be the same array.
using FmaKernel = void (*)(const FmaArgs& p, Index k0, Index k1, const double* in, Index ldi,
                           double* out, Index ldo);

#ifdef CSYMPNET_FMA_KERNELS
void fma_product_avx512(const FmaArgs& p, Index k0, Index k1, const double* in, Index ldi,
                        double* out, Index ldo);
void fma_product_avx2(const FmaArgs& p, Index k0, Index k1, const double* in, Index ldi,
                      double* out, Index ldo);
#endif

}  // namespace csympnet::kernels
