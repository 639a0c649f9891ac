// The AVX-512 kernels of column_scaling.hpp: a column at a time, eight rows per register and
// the last m mod 8 rows masked; each element's multiplies and add as in the scalar formula.
#include "exact_simd.hpp"  // first: no FMA contraction in this file

#include "column_scaling.hpp"

namespace csympnet::detail {

#ifdef CSYMPNET_EXACT_SIMD

namespace {

bool avx512() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") != 0;
  }();
  return has;
}

__mmask8 tail_mask(Index rows) {
  return static_cast<__mmask8>((1u << rows) - 1u);
}

// out(:, j) = x(:, j) h_j
__attribute__((target("avx512f"))) void times_avx512(Index m, Index n, const double* x,
                                                     const double* h, double* out) {
  const Index m8 = m & ~Index{7};
  const __mmask8 tail = tail_mask(m - m8);
  for (Index j = 0; j < n; ++j, x += m, out += m) {
    const __m512d hj = _mm512_set1_pd(h[j]);
    Index i = 0;
    for (; i < m8; i += 8) _mm512_storeu_pd(out + i, _mm512_mul_pd(_mm512_loadu_pd(x + i), hj));
    if (tail != 0) {
      _mm512_mask_storeu_pd(out + i, tail, _mm512_mul_pd(_mm512_maskz_loadu_pd(tail, x + i), hj));
    }
  }
}

// out(:, j) = (x(:, j) ⊙ a) h_j, or out(:, j) + that
template <bool kAccumulate>
__attribute__((target("avx512f"))) void times_scaled_avx512(Index m, Index n, const double* x,
                                                            const double* a, const double* h,
                                                            double* out) {
  const Index m8 = m & ~Index{7};
  const __mmask8 tail = tail_mask(m - m8);
  for (Index j = 0; j < n; ++j, x += m, out += m) {
    const __m512d hj = _mm512_set1_pd(h[j]);
    Index i = 0;
    for (; i < m8; i += 8) {
      __m512d v = _mm512_mul_pd(_mm512_mul_pd(_mm512_loadu_pd(x + i), _mm512_loadu_pd(a + i)), hj);
      if constexpr (kAccumulate) v = _mm512_add_pd(_mm512_loadu_pd(out + i), v);
      _mm512_storeu_pd(out + i, v);
    }
    if (tail != 0) {
      const __m512d xa =
          _mm512_mul_pd(_mm512_maskz_loadu_pd(tail, x + i), _mm512_maskz_loadu_pd(tail, a + i));
      __m512d v = _mm512_mul_pd(xa, hj);
      if constexpr (kAccumulate) v = _mm512_add_pd(_mm512_maskz_loadu_pd(tail, out + i), v);
      _mm512_mask_storeu_pd(out + i, tail, v);
    }
  }
}

// out(:, j) += h_j b
__attribute__((target("avx512f"))) void outer_avx512(Index m, Index n, const double* b,
                                                     const double* h, double* out) {
  const Index m8 = m & ~Index{7};
  const __mmask8 tail = tail_mask(m - m8);
  for (Index j = 0; j < n; ++j, out += m) {
    const __m512d hj = _mm512_set1_pd(h[j]);
    Index i = 0;
    for (; i < m8; i += 8) {
      _mm512_storeu_pd(out + i, _mm512_add_pd(_mm512_loadu_pd(out + i),
                                              _mm512_mul_pd(hj, _mm512_loadu_pd(b + i))));
    }
    if (tail != 0) {
      const __m512d v = _mm512_add_pd(_mm512_maskz_loadu_pd(tail, out + i),
                                      _mm512_mul_pd(hj, _mm512_maskz_loadu_pd(tail, b + i)));
      _mm512_mask_storeu_pd(out + i, tail, v);
    }
  }
}

}  // namespace

bool add_outer_simd(Index m, Index n, const double* b, const double* h, double* out) {
  if (!avx512()) return false;
  outer_avx512(m, n, b, h, out);
  return true;
}

bool columns_times_simd(Index m, Index n, const double* x, const double* h, double* out) {
  if (!avx512()) return false;
  times_avx512(m, n, x, h, out);
  return true;
}

bool columns_times_scaled_simd(Index m, Index n, const double* x, const double* a, const double* h,
                               double* out, bool accumulate) {
  if (!avx512()) return false;
  if (accumulate) {
    times_scaled_avx512<true>(m, n, x, a, h, out);
  } else {
    times_scaled_avx512<false>(m, n, x, a, h, out);
  }
  return true;
}

#else

bool add_outer_simd(Index, Index, const double*, const double*, double*) {
  return false;
}

bool columns_times_simd(Index, Index, const double*, const double*, double*) {
  return false;
}
bool columns_times_scaled_simd(Index, Index, const double*, const double*, const double*, double*,
                               bool) {
  return false;
}

#endif

}  // namespace csympnet::detail
