// Internal to the SSE2-order products (product.cpp): what the kernel files share.
// product_avx512.cpp holds the AVX-512 kernel, product_avx.cpp the AVX one and
// the SSE2 tail rows; product.cpp checks and dispatches them. The order every kernel
// reproduces is stated at the top of product.cpp.
//
// Include sse2_order.hpp before this file: its pragma keeps multiplies and adds separate.
#pragma once

#include "product.hpp"

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace csympnet::kernels {

// One product's operands: A(i, l) = a[i + l*lda], B(l, j) = b[l*bl + j*bj], C(i, j) =
// c[i + j*ldc], h_j = h[j] (any array of n doubles when the epilogue reads no h).
struct ProductArgs {
  Index m, n, k;
  const double* a;
  Index lda;
  const double* b;
  Index bl, bj;
  double* c;
  Index ldc;
  Epilogue mode;
  const double* h;
};

// A kernel computes every entry of the product in the order of product.cpp's top.
using ProductKernel = void (*)(const ProductArgs&);

void product_avx512(const ProductArgs& p);
void product_avx(const ProductArgs& p);

// Rows m4, m4 + 1 (m4 = m − 2, m ≡ 2 mod 4) in SSE2 registers, one column per register
// (Eigen's own registers); the AVX kernel uses it for the tail, as both kernels do for m = 2.
void tail_rows_sse2(const ProductArgs& p);

// Writing a finished entry v = 0 + s (the product's value) to its destination p:
// kStore: p = v;  kAdd: p = p + v;  kAddScaled: p = p + v·h_j (hs points at h_j).
inline void put128(double* p, __m128d v, Epilogue mode, const double* hs) {
  if (mode == Epilogue::kStore) {
    _mm_storeu_pd(p, v);
  } else if (mode == Epilogue::kAdd) {
    _mm_storeu_pd(p, _mm_add_pd(_mm_loadu_pd(p), v));
  } else {
    _mm_storeu_pd(p, _mm_add_pd(_mm_loadu_pd(p), _mm_mul_pd(v, _mm_set1_pd(*hs))));
  }
}

// The same for four entries of a column, in a 256-bit register (AVX; the AVX-512 kernel's
// 4-row blocks call it too).
__attribute__((target("avx"), always_inline)) inline void put256(double* p, __m256d v,
                                                                 Epilogue mode, const double* hs) {
  if (mode == Epilogue::kStore) {
    _mm256_storeu_pd(p, v);
  } else if (mode == Epilogue::kAdd) {
    _mm256_storeu_pd(p, _mm256_add_pd(_mm256_loadu_pd(p), v));
  } else {
    _mm256_storeu_pd(p, _mm256_add_pd(_mm256_loadu_pd(p), _mm256_mul_pd(v, _mm256_set1_pd(*hs))));
  }
}

}  // namespace csympnet::kernels

#endif  // CSYMPNET_SSE2_ORDER_KERNELS
