// The AVX2 forms of column_scaling.hpp's kernels, for machines without AVX-512: a column at a
// time, four rows per 256-bit register, then the last m mod 4 rows in a 128-bit and a scalar
// step; each element's multiplies and add as in the scalar formula (column_scaling_avx512.cpp,
// whose structure this follows; the operations need AVX only, the family is named for the
// machines it serves).
#include "sse2_order.hpp"  // first: no FMA contraction in this file

#include "column_scaling.hpp"

namespace csympnet::kernels {

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace {

#define CSYMPNET_LANES __attribute__((target("avx2"), always_inline)) static inline

// The same few operations on 4, 2 and 1 lanes.
struct Lanes4 {
  CSYMPNET_LANES __m256d load(const double* p) { return _mm256_loadu_pd(p); }
  CSYMPNET_LANES void store(double* p, __m256d v) { _mm256_storeu_pd(p, v); }
  CSYMPNET_LANES __m256d set1(double x) { return _mm256_set1_pd(x); }
  CSYMPNET_LANES __m256d mul(__m256d a, __m256d b) { return _mm256_mul_pd(a, b); }
  CSYMPNET_LANES __m256d add(__m256d a, __m256d b) { return _mm256_add_pd(a, b); }
};
struct Lanes2 {
  CSYMPNET_LANES __m128d load(const double* p) { return _mm_loadu_pd(p); }
  CSYMPNET_LANES void store(double* p, __m128d v) { _mm_storeu_pd(p, v); }
  CSYMPNET_LANES __m128d set1(double x) { return _mm_set1_pd(x); }
  CSYMPNET_LANES __m128d mul(__m128d a, __m128d b) { return _mm_mul_pd(a, b); }
  CSYMPNET_LANES __m128d add(__m128d a, __m128d b) { return _mm_add_pd(a, b); }
};
struct Lanes1 {
  CSYMPNET_LANES double load(const double* p) { return *p; }
  CSYMPNET_LANES void store(double* p, double v) { *p = v; }
  CSYMPNET_LANES double set1(double x) { return x; }
  CSYMPNET_LANES double mul(double a, double b) { return a * b; }
  CSYMPNET_LANES double add(double a, double b) { return a + b; }
};

#undef CSYMPNET_LANES

// Op::template rows<L>(j, i) for rows [i, i + width of L) of column j, over every column.
template <typename Op>
__attribute__((target("avx2"), always_inline)) inline void sweep(Index m, Index n, const Op& op) {
  for (Index j = 0; j < n; ++j) {
    Index i = 0;
    for (; i + 4 <= m; i += 4) op.template rows<Lanes4>(j, i);
    if (i + 2 <= m) {
      op.template rows<Lanes2>(j, i);
      i += 2;
    }
    if (i < m) op.template rows<Lanes1>(j, i);
  }
}

#define CSYMPNET_ROWS   \
  template <typename L> \
  __attribute__((target("avx2"), always_inline)) void

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

}  // namespace

__attribute__((target("avx2"))) void columns_times_avx2(Index m, Index n, const double* x,
                                                        const double* h, double* out) {
  sweep(m, n, Times{m, x, h, out});
}

__attribute__((target("avx2"))) void columns_times_scaled_avx2(Index m, Index n, const double* x,
                                                               const double* a, const double* h,
                                                               double* out, bool accumulate) {
  if (accumulate) {
    sweep(m, n, TimesScaled<true>{m, x, a, h, out});
  } else {
    sweep(m, n, TimesScaled<false>{m, x, a, h, out});
  }
}

__attribute__((target("avx2"))) void add_outer_avx2(Index m, Index n, const double* b,
                                                    const double* h, double* out) {
  sweep(m, n, Outer{m, b, h, out});
}

#else

void columns_times_avx2(Index, Index, const double*, const double*, double*) {}
void columns_times_scaled_avx2(Index, Index, const double*, const double*, const double*, double*,
                               bool) {}
void add_outer_avx2(Index, Index, const double*, const double*, double*) {}

#endif

}  // namespace csympnet::kernels
