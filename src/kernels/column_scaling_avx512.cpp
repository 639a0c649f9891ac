// The AVX-512 kernels of column_scaling.hpp: a column at a time, eight rows per 512-bit
// register, then the last m mod 8 rows in a 256-bit, a 128-bit and a scalar step; each
// element's multiplies and add as in the scalar formula.
//
// Why no masked tail: on Zen 4 a masked 512-bit store followed by a load of the next column,
// whose bytes it spans, waits for the store to complete (measured alone, m = 10, n = 400: 3.7 µs
// with masked tails, 0.6 µs without).
#include "sse2_order.hpp"  // first: no FMA contraction in this file

#include "column_scaling.hpp"

#include <cstring>

#include "registry.hpp"

namespace csympnet::kernels {

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace {

#define CSYMPNET_LANES __attribute__((target("avx512f"), always_inline)) static inline

// The same few operations on 8, 4, 2 and 1 lanes.
struct Lanes8 {
  static constexpr Index kWidth = 8;
  CSYMPNET_LANES __m512d load(const double* p) { return _mm512_loadu_pd(p); }
  CSYMPNET_LANES void store(double* p, __m512d v) { _mm512_storeu_pd(p, v); }
  CSYMPNET_LANES __m512d set1(double x) { return _mm512_set1_pd(x); }
  CSYMPNET_LANES __m512d mul(__m512d a, __m512d b) { return _mm512_mul_pd(a, b); }
  CSYMPNET_LANES __m512d add(__m512d a, __m512d b) { return _mm512_add_pd(a, b); }
};
struct Lanes4 {
  static constexpr Index kWidth = 4;
  CSYMPNET_LANES __m256d load(const double* p) { return _mm256_loadu_pd(p); }
  CSYMPNET_LANES void store(double* p, __m256d v) { _mm256_storeu_pd(p, v); }
  CSYMPNET_LANES __m256d set1(double x) { return _mm256_set1_pd(x); }
  CSYMPNET_LANES __m256d mul(__m256d a, __m256d b) { return _mm256_mul_pd(a, b); }
  CSYMPNET_LANES __m256d add(__m256d a, __m256d b) { return _mm256_add_pd(a, b); }
};
struct Lanes2 {
  static constexpr Index kWidth = 2;
  CSYMPNET_LANES __m128d load(const double* p) { return _mm_loadu_pd(p); }
  CSYMPNET_LANES void store(double* p, __m128d v) { _mm_storeu_pd(p, v); }
  CSYMPNET_LANES __m128d set1(double x) { return _mm_set1_pd(x); }
  CSYMPNET_LANES __m128d mul(__m128d a, __m128d b) { return _mm_mul_pd(a, b); }
  CSYMPNET_LANES __m128d add(__m128d a, __m128d b) { return _mm_add_pd(a, b); }
};
struct Lanes1 {
  static constexpr Index kWidth = 1;
  CSYMPNET_LANES double load(const double* p) { return *p; }
  CSYMPNET_LANES void store(double* p, double v) { *p = v; }
  CSYMPNET_LANES double set1(double x) { return x; }
  CSYMPNET_LANES double mul(double a, double b) { return a * b; }
  CSYMPNET_LANES double add(double a, double b) { return a + b; }
};

#undef CSYMPNET_LANES

// Op::template rows<L>(j, i) for rows [i, i + L::kWidth) of column j, over every column.
template <typename Op>
__attribute__((target("avx512f"), always_inline)) inline void sweep(Index m, Index n,
                                                                    const Op& op) {
  for (Index j = 0; j < n; ++j) {
    Index i = 0;
    for (; i + 8 <= m; i += 8) op.template rows<Lanes8>(j, i);
    if (i + 4 <= m) {
      op.template rows<Lanes4>(j, i);
      i += 4;
    }
    if (i + 2 <= m) {
      op.template rows<Lanes2>(j, i);
      i += 2;
    }
    if (i < m) op.template rows<Lanes1>(j, i);
  }
}

#define CSYMPNET_ROWS   \
  template <typename L> \
  __attribute__((target("avx512f"), always_inline)) void

// out(:, j) = x(:, j) h_j
struct Times {
  Index m;
  const double *x, *h;
  double* out;
  CSYMPNET_ROWS rows(Index j, Index i) const {
    const Index at = j * m + i;
    L::store(out + at, L::mul(L::load(x + at), L::set1(h[j])));
  }
};

// out(:, j) = (x(:, j) ⊙ a) h_j, or out(:, j) + that
template <bool kAccumulate>
struct TimesScaled {
  Index m;
  const double *x, *a, *h;
  double* out;
  CSYMPNET_ROWS rows(Index j, Index i) const {
    const Index at = j * m + i;
    auto v = L::mul(L::mul(L::load(x + at), L::load(a + i)), L::set1(h[j]));
    if constexpr (kAccumulate) v = L::add(L::load(out + at), v);
    L::store(out + at, v);
  }
};

// out(:, j) += h_j b
struct Outer {
  Index m;
  const double *b, *h;
  double* out;
  CSYMPNET_ROWS rows(Index j, Index i) const {
    const Index at = j * m + i;
    L::store(out + at, L::add(L::load(out + at), L::mul(L::set1(h[j]), L::load(b + i))));
  }
};

#undef CSYMPNET_ROWS

__attribute__((target("avx512f"))) void times_avx512(Index m, Index n, const double* x,
                                                     const double* h, double* out) {
  sweep(m, n, Times{m, x, h, out});
}

template <bool kAccumulate>
__attribute__((target("avx512f"))) void times_scaled_avx512(Index m, Index n, const double* x,
                                                            const double* a, const double* h,
                                                            double* out) {
  sweep(m, n, TimesScaled<kAccumulate>{m, x, a, h, out});
}

__attribute__((target("avx512f"))) void outer_avx512(Index m, Index n, const double* b,
                                                     const double* h, double* out) {
  sweep(m, n, Outer{m, b, h, out});
}

// A form's kernels against the formulas of the Eigen expressions they replace
// (column_scaling.hpp), element by element, for every row count up to two registers and a tail
// of each width.
template <typename Times, typename TimesScaled, typename Outer>
bool agrees_with_formulas(Times times, TimesScaled times_scaled, Outer outer) {
  constexpr Index kM = 23, kN = 3;
  double x[kM * kN], a[kM], h[kN], base[kM * kN];
  for (Index i = 0; i < kM * kN; ++i) {
    x[i] = 0.29 * static_cast<double>(i % 13) - 1.7;
    base[i] = 0.5 - 0.037 * static_cast<double>(i % 17);
  }
  for (Index i = 0; i < kM; ++i) a[i] = 0.8 + 0.019 * static_cast<double>(i);
  for (Index j = 0; j < kN; ++j) h[j] = 0.01 + 0.3 * static_cast<double>(j);
  auto same = [](double u, double v) { return std::memcmp(&u, &v, sizeof(double)) == 0; };
  for (Index m = 1; m <= kM; ++m) {
    double t[kM * kN], s0[kM * kN], s1[kM * kN], o[kM * kN];
    std::memcpy(s1, base, sizeof(base));
    std::memcpy(o, base, sizeof(base));
    times(m, kN, x, h, t);
    times_scaled(m, kN, x, a, h, s0, false);
    times_scaled(m, kN, x, a, h, s1, true);
    outer(m, kN, a, h, o);
    for (Index j = 0; j < kN; ++j) {
      for (Index i = 0; i < m; ++i) {
        const Index e = i + j * m;
        const double scaled = (x[e] * a[i]) * h[j];
        if (!same(t[e], x[e] * h[j]) || !same(s0[e], scaled) || !same(s1[e], base[e] + scaled) ||
            !same(o[e], base[e] + h[j] * a[i])) {
          return false;
        }
      }
    }
  }
  return true;
}

__attribute__((target("avx512f"))) void times_scaled_either_avx512(Index m, Index n,
                                                                   const double* x, const double* a,
                                                                   const double* h, double* out,
                                                                   bool accumulate) {
  if (accumulate) {
    times_scaled_avx512<true>(m, n, x, a, h, out);
  } else {
    times_scaled_avx512<false>(m, n, x, a, h, out);
  }
}

}  // namespace

bool column_scaling_self_check() {
  return agrees_with_formulas(times_avx512, times_scaled_either_avx512, outer_avx512);
}

bool column_scaling_avx2_self_check() {
  return agrees_with_formulas(columns_times_avx2, columns_times_scaled_avx2, add_outer_avx2);
}

bool add_outer_simd(Index m, Index n, const double* b, const double* h, double* out) {
  if (use(Family::kColumnScaling)) {
    outer_avx512(m, n, b, h, out);
  } else if (use(Family::kColumnScalingAvx2)) {
    add_outer_avx2(m, n, b, h, out);
  } else {
    return false;
  }
  return true;
}

bool columns_times_simd(Index m, Index n, const double* x, const double* h, double* out) {
  if (use(Family::kColumnScaling)) {
    times_avx512(m, n, x, h, out);
  } else if (use(Family::kColumnScalingAvx2)) {
    columns_times_avx2(m, n, x, h, out);
  } else {
    return false;
  }
  return true;
}

bool columns_times_scaled_simd(Index m, Index n, const double* x, const double* a, const double* h,
                               double* out, bool accumulate) {
  if (use(Family::kColumnScaling)) {
    times_scaled_either_avx512(m, n, x, a, h, out, accumulate);
  } else if (use(Family::kColumnScalingAvx2)) {
    columns_times_scaled_avx2(m, n, x, a, h, out, accumulate);
  } else {
    return false;
  }
  return true;
}

#else

bool column_scaling_self_check() {
  return false;
}

bool column_scaling_avx2_self_check() {
  return false;
}

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

}  // namespace csympnet::kernels
