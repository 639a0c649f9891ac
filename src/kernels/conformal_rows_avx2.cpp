// conformal_rows.hpp's AVX2 forms, for machines without AVX-512: four samples per instruction.
// Four interleaved samples (q_0, p_0, …, q_3, p_3) fill two registers; an unpack pairs the q (or
// p) of samples 0, 2 and 1, 3, and a lane permute puts them in order (joined back the other way
// round). Shuffles move values unchanged; the arithmetic is the portable loops' multiplies and
// adds, one instruction per operation, in their order (fp-contract is off in this file), and the
// last n mod 4 samples take the same operations one at a time.
#include "conformal_rows.hpp"

#include "sse2_order.hpp"  // first of this file's own code: fp-contract off, under gcc and clang

#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
#define CSYMPNET_CONFORMAL_ROWS_SIMD 1
#include <immintrin.h>
#endif

namespace csympnet::kernels {

#ifdef CSYMPNET_CONFORMAL_ROWS_SIMD

namespace {

// Rows 0 and 1 of four interleaved samples (lo: samples 0, 1; hi: samples 2, 3).
__attribute__((target("avx2"), always_inline)) inline void split(__m256d lo, __m256d hi,
                                                                 __m256d& top, __m256d& bottom) {
  top = _mm256_permute4x64_pd(_mm256_unpacklo_pd(lo, hi), 0xD8);  // lanes 0, 2, 1, 3
  bottom = _mm256_permute4x64_pd(_mm256_unpackhi_pd(lo, hi), 0xD8);
}

}  // namespace

__attribute__((target("avx2"))) void split_scaled_rows_avx2(const double* z, Index n,
                                                            const double* a, double* q, double* p,
                                                            double* p_raw) {
  Index j = 0;
  for (; j + 4 <= n; j += 4) {
    __m256d top, bottom;
    split(_mm256_loadu_pd(z + 2 * j), _mm256_loadu_pd(z + 2 * j + 4), top, bottom);
    _mm256_storeu_pd(q + j, top);
    if (p_raw != nullptr) _mm256_storeu_pd(p_raw + j, bottom);
    _mm256_storeu_pd(p + j, _mm256_mul_pd(bottom, _mm256_loadu_pd(a + j)));
  }
  for (; j < n; ++j) {
    q[j] = z[2 * j];
    if (p_raw != nullptr) p_raw[j] = z[2 * j + 1];
    p[j] = z[2 * j + 1] * a[j];
  }
}

__attribute__((target("avx2"))) void join_scaled_rows_avx2(const double* q, const double* p,
                                                           const double* a, Index n, double* out) {
  Index j = 0;
  for (; j + 4 <= n; j += 4) {
    const __m256d qv = _mm256_loadu_pd(q + j);
    const __m256d pa = _mm256_mul_pd(_mm256_loadu_pd(p + j), _mm256_loadu_pd(a + j));
    const __m256d even = _mm256_unpacklo_pd(qv, pa);  // q0 pa0 q2 pa2
    const __m256d odd = _mm256_unpackhi_pd(qv, pa);   // q1 pa1 q3 pa3
    _mm256_storeu_pd(out + 2 * j, _mm256_permute2f128_pd(even, odd, 0x20));
    _mm256_storeu_pd(out + 2 * j + 4, _mm256_permute2f128_pd(even, odd, 0x31));
  }
  for (; j < n; ++j) {
    out[2 * j] = q[j];
    out[2 * j + 1] = p[j] * a[j];
  }
}

__attribute__((target("avx2"))) void damping_terms_avx2(const double* dz, const double* p_core,
                                                        const double* gp, const double* p_in,
                                                        const double* h, const double* a, Index n,
                                                        double* terms) {
  Index j = 0;
  for (; j + 4 <= n; j += 4) {
    __m256d unused, g;
    split(_mm256_loadu_pd(dz + 2 * j), _mm256_loadu_pd(dz + 2 * j + 4), unused, g);
    const __m256d outer = _mm256_mul_pd(g, _mm256_loadu_pd(p_core + j));
    const __m256d inner = _mm256_mul_pd(_mm256_loadu_pd(gp + j), _mm256_loadu_pd(p_in + j));
    const __m256d grad_a = _mm256_add_pd(outer, inner);
    const __m256d t =
        _mm256_mul_pd(_mm256_mul_pd(grad_a, _mm256_loadu_pd(h + j)), _mm256_loadu_pd(a + j));
    _mm256_storeu_pd(terms + j, t);
  }
  for (; j < n; ++j) {
    terms[j] = ((dz[2 * j + 1] * p_core[j] + gp[j] * p_in[j]) * h[j]) * a[j];
  }
}

#else

void split_scaled_rows_avx2(const double*, Index, const double*, double*, double*, double*) {}
void join_scaled_rows_avx2(const double*, const double*, const double*, Index, double*) {}
void damping_terms_avx2(const double*, const double*, const double*, const double*, const double*,
                        const double*, Index, double*) {}

#endif

}  // namespace csympnet::kernels
