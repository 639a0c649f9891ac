// The AVX (256-bit) kernel of the SSE2-order products, for x86-64 machines without
// AVX-512, and the SSE2 tail rows (product_targets.hpp). Every entry in the order stated
// at the top of product.cpp.
#include "sse2_order.hpp"
//
#include "product_targets.hpp"

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace csympnet::kernels {

namespace {

#define CSYMPNET_AVX_INLINE __attribute__((target("avx"), always_inline)) inline
#define CSYMPNET_AVX_OUTLINE __attribute__((target("avx"), noinline))

// Rows [0, 4R) times NC columns, one running sum per entry.
template <int R, int NC>
CSYMPNET_AVX_INLINE void tile256(Index k, const double* a, Index lda, const double* b, Index bl,
                                 Index bj, double* c, Index ldc, Epilogue mode, const double* h) {
  __m256d acc[R][NC];
#pragma GCC unroll 4
  for (int s = 0; s < NC; ++s) {
#pragma GCC unroll 3
    for (int r = 0; r < R; ++r) acc[r][s] = _mm256_setzero_pd();
  }
  for (Index l = 0; l < k; ++l) {
    __m256d av[R];
#pragma GCC unroll 3
    for (int r = 0; r < R; ++r) av[r] = _mm256_loadu_pd(a + l * lda + 4 * r);
#pragma GCC unroll 4
    for (int s = 0; s < NC; ++s) {
      const __m256d bv = _mm256_set1_pd(b[l * bl + s * bj]);
#pragma GCC unroll 3
      for (int r = 0; r < R; ++r) acc[r][s] = _mm256_add_pd(acc[r][s], _mm256_mul_pd(av[r], bv));
    }
  }
  const __m256d zero = _mm256_setzero_pd();
#pragma GCC unroll 4
  for (int s = 0; s < NC; ++s) {
#pragma GCC unroll 3
    for (int r = 0; r < R; ++r) {
      put256(c + s * ldc + 4 * r, _mm256_add_pd(zero, acc[r][s]), mode, h + s);
    }
  }
}

// One row tile across all n columns: tiles of 4 columns, then 2 and 1.
template <int R>
CSYMPNET_AVX_OUTLINE void sweep256(Index n, Index k, const double* a, Index lda, const double* b,
                                   Index bl, Index bj, double* c, Index ldc, Epilogue mode,
                                   const double* h) {
  Index j = 0;
  for (; j + 4 <= n; j += 4) {
    tile256<R, 4>(k, a, lda, b + j * bj, bl, bj, c + j * ldc, ldc, mode, h + j);
  }
  if (j + 2 <= n) {
    tile256<R, 2>(k, a, lda, b + j * bj, bl, bj, c + j * ldc, ldc, mode, h + j);
    j += 2;
  }
  if (j < n) tile256<R, 1>(k, a, lda, b + j * bj, bl, bj, c + j * ldc, ldc, mode, h + j);
}

}  // namespace

// Rows m4, m4 + 1 in Eigen's 1-packet order with its registers: one SSE2 packet holds the
// two rows, four columns at a time.
void tail_rows_sse2(const ProductArgs& p) {
  const Index m4 = p.m - 2;
  const Index k8 = p.k & ~Index{7};
  const Index n4 = p.n & ~Index{3};
  const double* ar = p.a + m4;
  const Index lda = p.lda, bl = p.bl, k = p.k;
  const __m128d zero = _mm_setzero_pd();
  Index j = 0;
  for (; j < n4; j += 4) {
    const double* b0 = p.b + j * p.bj;
    const double* b1 = b0 + p.bj;
    const double* b2 = b1 + p.bj;
    const double* b3 = b2 + p.bj;
    __m128d c0 = zero, c1 = zero, c2 = zero, c3 = zero;
    __m128d d0 = zero, d1 = zero, d2 = zero, d3 = zero;
    Index l = 0;
    for (; l < k8; l += 2) {  // even l into c, odd l into d
      const __m128d ae = _mm_loadu_pd(ar + l * lda);
      c0 = _mm_add_pd(c0, _mm_mul_pd(ae, _mm_set1_pd(b0[l * bl])));
      c1 = _mm_add_pd(c1, _mm_mul_pd(ae, _mm_set1_pd(b1[l * bl])));
      c2 = _mm_add_pd(c2, _mm_mul_pd(ae, _mm_set1_pd(b2[l * bl])));
      c3 = _mm_add_pd(c3, _mm_mul_pd(ae, _mm_set1_pd(b3[l * bl])));
      const Index lo = l + 1;
      const __m128d ao = _mm_loadu_pd(ar + lo * lda);
      d0 = _mm_add_pd(d0, _mm_mul_pd(ao, _mm_set1_pd(b0[lo * bl])));
      d1 = _mm_add_pd(d1, _mm_mul_pd(ao, _mm_set1_pd(b1[lo * bl])));
      d2 = _mm_add_pd(d2, _mm_mul_pd(ao, _mm_set1_pd(b2[lo * bl])));
      d3 = _mm_add_pd(d3, _mm_mul_pd(ao, _mm_set1_pd(b3[lo * bl])));
    }
    c0 = _mm_add_pd(c0, d0);
    c1 = _mm_add_pd(c1, d1);
    c2 = _mm_add_pd(c2, d2);
    c3 = _mm_add_pd(c3, d3);
    for (; l < k; ++l) {
      const __m128d av = _mm_loadu_pd(ar + l * lda);
      c0 = _mm_add_pd(c0, _mm_mul_pd(av, _mm_set1_pd(b0[l * bl])));
      c1 = _mm_add_pd(c1, _mm_mul_pd(av, _mm_set1_pd(b1[l * bl])));
      c2 = _mm_add_pd(c2, _mm_mul_pd(av, _mm_set1_pd(b2[l * bl])));
      c3 = _mm_add_pd(c3, _mm_mul_pd(av, _mm_set1_pd(b3[l * bl])));
    }
    double* cj = p.c + m4 + j * p.ldc;
    put128(cj, _mm_add_pd(zero, c0), p.mode, p.h + j);
    put128(cj + p.ldc, _mm_add_pd(zero, c1), p.mode, p.h + j + 1);
    put128(cj + 2 * p.ldc, _mm_add_pd(zero, c2), p.mode, p.h + j + 2);
    put128(cj + 3 * p.ldc, _mm_add_pd(zero, c3), p.mode, p.h + j + 3);
  }
  for (; j < p.n; ++j) {  // the last n mod 4 columns: one running sum each
    const double* bc = p.b + j * p.bj;
    __m128d s = zero;
    for (Index l = 0; l < k; ++l) {
      s = _mm_add_pd(s, _mm_mul_pd(_mm_loadu_pd(ar + l * lda), _mm_set1_pd(bc[l * bl])));
    }
    put128(p.c + m4 + j * p.ldc, _mm_add_pd(zero, s), p.mode, p.h + j);
  }
}

// Row tiles of 12 and 4 rows, then the SSE2 tail.
__attribute__((target("avx"))) void product_avx(const ProductArgs& p) {
  const Index m4 = p.m & ~Index{3};
  Index i = 0;
  for (; i + 12 <= m4; i += 12) {
    sweep256<3>(p.n, p.k, p.a + i, p.lda, p.b, p.bl, p.bj, p.c + i, p.ldc, p.mode, p.h);
  }
  for (; i + 4 <= m4; i += 4) {
    sweep256<1>(p.n, p.k, p.a + i, p.lda, p.b, p.bl, p.bj, p.c + i, p.ldc, p.mode, p.h);
  }
  if (p.m - m4 == 2) tail_rows_sse2(p);
}

}  // namespace csympnet::kernels

#endif  // CSYMPNET_SSE2_ORDER_KERNELS
