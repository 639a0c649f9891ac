// The exact-order product kernels of exact_product.hpp.
//
// The order, per entry C(i, j) of C = A B (k = inner dimension), that Eigen 3.4's GEMM uses
// in the SSE2 build when its blocking does not split the inner dimension (kc >= k):
//   * rows i < m4 = 4⌊m/4⌋ (its 2-packet micro-kernel): s = 0; s += A(i,l) B(l,j), l = 0..k−1;
//   * rows m4, m4+1 when m ≡ 2 (mod 4), columns j < 4⌊n/4⌋ (its 1-packet kernel): two sums,
//       c over even l and d over odd l for l < k8 = 8⌊k/8⌋, then s = c + d and s += A(i,l) B(l,j)
//       for l = k8..k−1;  other columns: the plain running sum;
//   * then C(i, j) = 0 + s (the destination is zeroed and the block added to it).
// Odd m, a split inner dimension, lazy (tiny) products and builds whose Eigen uses other
// packets or FMA are not covered: exact_product() returns false there.
#include "exact_product.hpp"

#include <cstring>
#include <random>

#include "exact_simd.hpp"

namespace csympnet::detail {

namespace {

#ifdef CSYMPNET_EXACT_SIMD

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

__attribute__((target("avx512f"), always_inline)) inline void put512(double* p, __m512d v,
                                                                     Epilogue mode,
                                                                     const double* hs) {
  if (mode == Epilogue::kStore) {
    _mm512_storeu_pd(p, v);
  } else if (mode == Epilogue::kAdd) {
    _mm512_storeu_pd(p, _mm512_add_pd(_mm512_loadu_pd(p), v));
  } else {
    _mm512_storeu_pd(p, _mm512_add_pd(_mm512_loadu_pd(p), _mm512_mul_pd(v, _mm512_set1_pd(*hs))));
  }
}

// Rows m4, m4 + 1 of an m ≡ 2 (mod 4) product in Eigen's 1-packet order (see the top), with
// the same registers it uses: one SSE2 packet holds the two rows, four columns at a time.
void tail_rows(Index m4, Index n, Index k, const double* a, Index lda, const double* b, Index bl,
               Index bj, double* c, Index ldc, Epilogue mode, const double* h) {
  const Index k8 = k & ~Index{7};
  const Index n4 = n & ~Index{3};
  const double* ar = a + m4;
  const __m128d zero = _mm_setzero_pd();
  Index j = 0;
  for (; j < n4; j += 4) {
    const double* b0 = b + j * bj;
    const double* b1 = b0 + bj;
    const double* b2 = b1 + bj;
    const double* b3 = b2 + bj;
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
    put128(c + m4 + j * ldc, _mm_add_pd(zero, c0), mode, h + j);
    put128(c + m4 + (j + 1) * ldc, _mm_add_pd(zero, c1), mode, h + j + 1);
    put128(c + m4 + (j + 2) * ldc, _mm_add_pd(zero, c2), mode, h + j + 2);
    put128(c + m4 + (j + 3) * ldc, _mm_add_pd(zero, c3), mode, h + j + 3);
  }
  for (; j < n; ++j) {  // the last n mod 4 columns: one running sum each
    const double* bc = b + j * bj;
    __m128d s = zero;
    for (Index l = 0; l < k; ++l) {
      s = _mm_add_pd(s, _mm_mul_pd(_mm_loadu_pd(ar + l * lda), _mm_set1_pd(bc[l * bl])));
    }
    put128(c + m4 + j * ldc, _mm_add_pd(zero, s), mode, h + j);
  }
}

// How a tile treats the two tail rows of an m ≡ 2 (mod 4) product (see the top).
enum class Tail { kNone, kPairs, kRunning };  // none; even/odd sums; one running sum

// One l step of an AVX-512 tile: R x 8 rows of A from a, NC columns of B; with a tail, rows
// m4, m4 + 1 (at `at`) into tacc, in 128-bit registers: the two rows need no more, and on
// CPUs that split wide operations (AMD Zen 4) a 128-bit multiply or add costs a quarter of a
// 512-bit one.
template <int R, int NC, bool kWithTail>
__attribute__((target("avx512f"), always_inline)) inline void step512(
    Index l, const double* a, const double* at, Index lda, const double* b, Index bl, Index bj,
    __m512d (&acc)[R][NC], __m128d (&tacc)[NC]) {
  __m512d av[R];
#pragma GCC unroll 4
  for (int r = 0; r < R; ++r) av[r] = _mm512_loadu_pd(a + l * lda + 8 * r);
  __m128d tv = _mm_setzero_pd();
  if constexpr (kWithTail) tv = _mm_loadu_pd(at + l * lda);
#pragma GCC unroll 8
  for (int s = 0; s < NC; ++s) {
    const double bs = b[l * bl + s * bj];
    const __m512d bv = _mm512_set1_pd(bs);
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) acc[r][s] = _mm512_add_pd(acc[r][s], _mm512_mul_pd(av[r], bv));
    if constexpr (kWithTail) tacc[s] = _mm_add_pd(tacc[s], _mm_mul_pd(tv, _mm_set1_pd(bs)));
  }
}

// AVX-512 tile: R x 8 rows and NC columns, one running sum per entry over l; the tail rows
// (if any) in Eigen's order for their columns: kPairs for columns in its 4-column blocks,
// kRunning for the last n mod 4 columns.
template <int R, int NC, Tail kTail>
__attribute__((target("avx512f"), always_inline)) inline void tile512(
    Index k, const double* a, const double* at, Index lda, const double* b, Index bl, Index bj,
    double* c, double* ct, Index ldc, Epilogue mode, const double* h) {
  constexpr bool kWithTail = kTail != Tail::kNone;
  __m512d acc[R][NC];
  __m128d even[NC];
  __m128d odd[NC];
#pragma GCC unroll 8
  for (int s = 0; s < NC; ++s) {
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) acc[r][s] = _mm512_setzero_pd();
    even[s] = _mm_setzero_pd();
    odd[s] = _mm_setzero_pd();
  }
  Index l = 0;
  if constexpr (kTail == Tail::kPairs) {
    for (const Index k8 = k & ~Index{7}; l < k8; l += 2) {
      step512<R, NC, true>(l, a, at, lda, b, bl, bj, acc, even);
      step512<R, NC, true>(l + 1, a, at, lda, b, bl, bj, acc, odd);
    }
#pragma GCC unroll 8
    for (int s = 0; s < NC; ++s) even[s] = _mm_add_pd(even[s], odd[s]);
  }
  for (; l < k; ++l) step512<R, NC, kWithTail>(l, a, at, lda, b, bl, bj, acc, even);
  const __m512d zero = _mm512_setzero_pd();
#pragma GCC unroll 8
  for (int s = 0; s < NC; ++s) {
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) {
      put512(c + s * ldc + 8 * r, _mm512_add_pd(zero, acc[r][s]), mode, h + s);
    }
    if constexpr (kWithTail)
      put128(ct + s * ldc, _mm_add_pd(_mm_setzero_pd(), even[s]), mode, h + s);
  }
}

// The same with 4 rows of A in a 256-bit register (the tail in lanes 0, 1 of another).
template <int NC, Tail kTail>
__attribute__((target("avx512f"), always_inline)) inline void tile4x(
    Index k, const double* a, const double* at, Index lda, const double* b, Index bl, Index bj,
    double* c, double* ct, Index ldc, Epilogue mode, const double* h) {
  constexpr bool kWithTail = kTail != Tail::kNone;
  __m256d acc[NC];
  __m256d even[NC];
  __m256d odd[NC];
#pragma GCC unroll 8
  for (int s = 0; s < NC; ++s) acc[s] = even[s] = odd[s] = _mm256_setzero_pd();
  Index l = 0;
  const Index k8 = kTail == Tail::kPairs ? (k & ~Index{7}) : 0;
  for (; l < k8; l += 2) {
    const __m256d av0 = _mm256_loadu_pd(a + l * lda);
    const __m256d tv0 = _mm256_zextpd128_pd256(_mm_loadu_pd(at + l * lda));
    const __m256d av1 = _mm256_loadu_pd(a + (l + 1) * lda);
    const __m256d tv1 = _mm256_zextpd128_pd256(_mm_loadu_pd(at + (l + 1) * lda));
#pragma GCC unroll 8
    for (int s = 0; s < NC; ++s) {
      const __m256d b0 = _mm256_set1_pd(b[l * bl + s * bj]);
      const __m256d b1 = _mm256_set1_pd(b[(l + 1) * bl + s * bj]);
      acc[s] = _mm256_add_pd(acc[s], _mm256_mul_pd(av0, b0));
      even[s] = _mm256_add_pd(even[s], _mm256_mul_pd(tv0, b0));
      acc[s] = _mm256_add_pd(acc[s], _mm256_mul_pd(av1, b1));
      odd[s] = _mm256_add_pd(odd[s], _mm256_mul_pd(tv1, b1));
    }
  }
  if constexpr (kTail == Tail::kPairs) {
#pragma GCC unroll 8
    for (int s = 0; s < NC; ++s) even[s] = _mm256_add_pd(even[s], odd[s]);
  }
  for (; l < k; ++l) {
    const __m256d av = _mm256_loadu_pd(a + l * lda);
    __m256d tv = _mm256_setzero_pd();
    if constexpr (kWithTail) tv = _mm256_zextpd128_pd256(_mm_loadu_pd(at + l * lda));
#pragma GCC unroll 8
    for (int s = 0; s < NC; ++s) {
      const __m256d bv = _mm256_set1_pd(b[l * bl + s * bj]);
      acc[s] = _mm256_add_pd(acc[s], _mm256_mul_pd(av, bv));
      if constexpr (kWithTail) even[s] = _mm256_add_pd(even[s], _mm256_mul_pd(tv, bv));
    }
  }
  const __m256d zero = _mm256_setzero_pd();
#pragma GCC unroll 8
  for (int s = 0; s < NC; ++s) {
    put256(c + s * ldc, _mm256_add_pd(zero, acc[s]), mode, h + s);
    if constexpr (kWithTail) {
      put128(ct + s * ldc, _mm256_castpd256_pd128(_mm256_add_pd(zero, even[s])), mode, h + s);
    }
  }
}

// AVX (256-bit): tiles of R x 4 rows and NC columns.
template <int R, int NC>
__attribute__((target("avx"), always_inline)) inline void tile256(Index k, const double* a,
                                                                  Index lda, const double* b,
                                                                  Index bl, Index bj, double* c,
                                                                  Index ldc, Epilogue mode,
                                                                  const double* h) {
  __m256d acc[R][NC];
#pragma GCC unroll 8
  for (int s = 0; s < NC; ++s) {
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) acc[r][s] = _mm256_setzero_pd();
  }
  for (Index l = 0; l < k; ++l) {
    __m256d av[R];
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) av[r] = _mm256_loadu_pd(a + l * lda + 4 * r);
#pragma GCC unroll 8
    for (int s = 0; s < NC; ++s) {
      const __m256d bv = _mm256_set1_pd(b[l * bl + s * bj]);
#pragma GCC unroll 4
      for (int r = 0; r < R; ++r) acc[r][s] = _mm256_add_pd(acc[r][s], _mm256_mul_pd(av[r], bv));
    }
  }
  const __m256d zero = _mm256_setzero_pd();
#pragma GCC unroll 8
  for (int s = 0; s < NC; ++s) {
#pragma GCC unroll 4
    for (int r = 0; r < R; ++r) {
      put256(c + s * ldc + 4 * r, _mm256_add_pd(zero, acc[r][s]), mode, h + s);
    }
  }
}

// Column sweep of one row tile: tiles of NC columns, then the remaining columns in tiles of
// 4, 2 and 1 (NC = 8) or 2 and 1 (NC = 4), so that short tiles still have several
// independent sums in flight.
#define CSYMPNET_TILE(TILE, R, NC) \
  TILE<R, NC>(k, a + i, lda, b + j * bj, bl, bj, c + i + j * ldc, ldc, mode, h + j)
#define CSYMPNET_SWEEP(TILE, R, NC)                              \
  do {                                                           \
    Index j = 0;                                                 \
    for (; j + (NC) <= n; j += (NC)) CSYMPNET_TILE(TILE, R, NC); \
    if ((NC) > 4 && j + 4 <= n) {                                \
      CSYMPNET_TILE(TILE, R, 4);                                 \
      j += 4;                                                    \
    }                                                            \
    if (j + 2 <= n) {                                            \
      CSYMPNET_TILE(TILE, R, 2);                                 \
      j += 2;                                                    \
    }                                                            \
    if (j < n) CSYMPNET_TILE(TILE, R, 1);                        \
  } while (false)

// Column sweep of one AVX-512 row tile with the tail rows attached when kTail: NC-column
// tiles, then tiles of 4 (both in Eigen's 4-column blocks: even/odd sums for the tail), then
// 2 and 1 (its last n mod 4 columns: running sums).
template <int R, int NC, bool kTail>
__attribute__((target("avx512f"), always_inline)) inline void sweep512(
    Index n, Index k, const double* a, const double* at, Index lda, const double* b, Index bl,
    Index bj, double* c, double* ct, Index ldc, Epilogue mode, const double* h) {
  constexpr Tail kBlocks = kTail ? Tail::kPairs : Tail::kNone;
  constexpr Tail kRest = kTail ? Tail::kRunning : Tail::kNone;
  Index j = 0;
  for (; j + NC <= n; j += NC) {
    tile512<R, NC, kBlocks>(k, a, at, lda, b + j * bj, bl, bj, c + j * ldc, ct + j * ldc, ldc, mode,
                            h + j);
  }
  if (NC > 4 && j + 4 <= n) {
    tile512<R, 4, kBlocks>(k, a, at, lda, b + j * bj, bl, bj, c + j * ldc, ct + j * ldc, ldc, mode,
                           h + j);
    j += 4;
  }
  if (j + 2 <= n) {
    tile512<R, 2, kRest>(k, a, at, lda, b + j * bj, bl, bj, c + j * ldc, ct + j * ldc, ldc, mode,
                         h + j);
    j += 2;
  }
  if (j < n)
    tile512<R, 1, kRest>(k, a, at, lda, b + j * bj, bl, bj, c + j * ldc, ct + j * ldc, ldc, mode,
                         h + j);
}

template <bool kTail>
__attribute__((target("avx512f"), always_inline)) inline void sweep4x(
    Index n, Index k, const double* a, const double* at, Index lda, const double* b, Index bl,
    Index bj, double* c, double* ct, Index ldc, Epilogue mode, const double* h) {
  constexpr Tail kBlocks = kTail ? Tail::kPairs : Tail::kNone;
  constexpr Tail kRest = kTail ? Tail::kRunning : Tail::kNone;
  Index j = 0;
  for (; j + 8 <= n; j += 8) {
    tile4x<8, kBlocks>(k, a, at, lda, b + j * bj, bl, bj, c + j * ldc, ct + j * ldc, ldc, mode,
                       h + j);
  }
  if (j + 4 <= n) {
    tile4x<4, kBlocks>(k, a, at, lda, b + j * bj, bl, bj, c + j * ldc, ct + j * ldc, ldc, mode,
                       h + j);
    j += 4;
  }
  if (j + 2 <= n) {
    tile4x<2, kRest>(k, a, at, lda, b + j * bj, bl, bj, c + j * ldc, ct + j * ldc, ldc, mode,
                     h + j);
    j += 2;
  }
  if (j < n)
    tile4x<1, kRest>(k, a, at, lda, b + j * bj, bl, bj, c + j * ldc, ct + j * ldc, ldc, mode,
                     h + j);
}

// All rows with AVX-512: row tiles of 24, 8 and 4; the two tail rows (m ≡ 2 mod 4) ride
// along with the last tile, sharing its loads of B.
__attribute__((target("avx512f"))) void rows_avx512(Index m, Index n, Index k, const double* a,
                                                    Index lda, const double* b, Index bl, Index bj,
                                                    double* c, Index ldc, Epilogue mode,
                                                    const double* h) {
  const Index m4 = m & ~Index{3};
  const bool tail = m - m4 == 2;
  const double* at = a + m4;
  double* ct = c + m4;
  Index i = 0;
  // The last tile (which carries the tail) starts at `last`.
  const Index last = m4 % 8 == 4 ? m4 - 4 : m4 - 8;
  for (; i + 24 <= m4 && !(tail && i + 24 > last); i += 24) {
    sweep512<3, 8, false>(n, k, a + i, at, lda, b, bl, bj, c + i, ct, ldc, mode, h);
  }
  for (; i + 8 <= m4; i += 8) {
    if (tail && i == last) {
      sweep512<1, 8, true>(n, k, a + i, at, lda, b, bl, bj, c + i, ct, ldc, mode, h);
    } else {
      sweep512<1, 8, false>(n, k, a + i, at, lda, b, bl, bj, c + i, ct, ldc, mode, h);
    }
  }
  if (i + 4 <= m4) {
    if (tail) {
      sweep4x<true>(n, k, a + i, at, lda, b, bl, bj, c + i, ct, ldc, mode, h);
    } else {
      sweep4x<false>(n, k, a + i, at, lda, b, bl, bj, c + i, ct, ldc, mode, h);
    }
  }
}

__attribute__((target("avx"))) void main_rows_avx(Index m4, Index n, Index k, const double* a,
                                                  Index lda, const double* b, Index bl, Index bj,
                                                  double* c, Index ldc, Epilogue mode,
                                                  const double* h) {
  Index i = 0;
  for (; i + 12 <= m4; i += 12) CSYMPNET_SWEEP(tile256, 3, 4);
  for (; i + 4 <= m4; i += 4) CSYMPNET_SWEEP(tile256, 1, 4);
}

#undef CSYMPNET_SWEEP
#undef CSYMPNET_TILE

using Rows = void (*)(Index, Index, Index, const double*, Index, const double*, Index, Index,
                      double*, Index, Epilogue, const double*);

// Eigen blocks a product by its cache-size heuristic. Blocks of rows and columns in multiples
// of its micro-tile (4 x 4) leave every entry's arithmetic as above; a split of the inner
// dimension does not (the partial sums would be added), so it is not covered.
bool eigen_order_is_known(Index m, Index n, Index k) {
  Index kc = k, mc = m, nc = n;
  Eigen::internal::computeProductBlockingSizes<double, double, 1, Index>(kc, mc, nc, Index{1});
  return kc >= k && (mc >= m || mc % 4 == 0) && (nc >= n || nc % 4 == 0);
}

__attribute__((target("avx"))) void rows_avx(Index m, Index n, Index k, const double* a, Index lda,
                                             const double* b, Index bl, Index bj, double* c,
                                             Index ldc, Epilogue mode, const double* h) {
  const Index m4 = m & ~Index{3};
  main_rows_avx(m4, n, k, a, lda, b, bl, bj, c, ldc, mode, h);
  if (m - m4 == 2) tail_rows(m4, n, k, a, lda, b, bl, bj, c, ldc, mode, h);
}

bool run(Rows rows, Index m, Index n, Index k, const double* a, Index lda, const double* b,
         Index bl, Index bj, double* c, Epilogue mode = Epilogue::kStore,
         const double* h = nullptr) {
  // Without column factors, any array of n doubles keeps the (unread) h + j pointers valid.
  if (h == nullptr) h = c;
  if (m < 4) {
    tail_rows(0, n, k, a, lda, b, bl, bj, c, m, mode, h);  // m == 2: the tail alone
  } else {
    rows(m, n, k, a, lda, b, bl, bj, c, m, mode, h);
  }
  return true;
}

// Checks once, on random operands of every covered kind, that the kernels reproduce Eigen on
// this build and machine; a kernel that does not is never used.
bool agrees_with_eigen(Rows rows) {
  std::mt19937_64 gen(12345);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Index shapes[][3] = {{10, 37, 10}, {50, 21, 10}, {26, 13, 19}, {100, 9, 64}, {12, 40, 7}};
  for (const auto& s : shapes) {
    const Index m = s[0], n = s[1], k = s[2];
    if (!eigen_order_is_known(m, n, k)) continue;
    Matrix a(m, k), b(k, n), bt(n, k);
    for (Index i = 0; i < a.size(); ++i) a.data()[i] = u(gen);
    for (Index i = 0; i < b.size(); ++i) b.data()[i] = u(gen);
    bt = b.transpose();
    Matrix ref(m, n), mine(m, n), mine_t(m, n);
    ref.noalias() = a * b;
    run(rows, m, n, k, a.data(), m, b.data(), 1, k, mine.data());
    run(rows, m, n, k, a.data(), m, bt.data(), n, 1, mine_t.data());
    const auto bytes = static_cast<std::size_t>(ref.size()) * sizeof(double);
    if (std::memcmp(ref.data(), mine.data(), bytes) != 0 ||
        std::memcmp(ref.data(), mine_t.data(), bytes) != 0) {
      return false;
    }
  }
  return true;
}

struct Choice {
  Rows rows = nullptr;
  const char* isa = "eigen";
};

Choice choose() {
  Choice c;
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f") && agrees_with_eigen(rows_avx512)) {
    c.rows = rows_avx512;
    c.isa = "avx512";
  } else if (__builtin_cpu_supports("avx") && agrees_with_eigen(rows_avx)) {
    c.rows = rows_avx;
    c.isa = "avx";
  }
  return c;
}

const Choice& chosen() {
  static const Choice c = choose();  // thread-safe one-time initialisation
  return c;
}

#endif  // CSYMPNET_EXACT_SIMD

}  // namespace

bool exact_product(Index m, Index n, Index k, const double* a, Index lda, const double* b, Index bl,
                   Index bj, double* c, Epilogue mode, const double* h) {
#ifdef CSYMPNET_EXACT_SIMD
  const Choice& ch = chosen();
  if (ch.rows == nullptr) return false;
  // Eigen's lazy product (tiny sizes), its GEMV fallbacks (a single row or column), odd row
  // counts and blocked shapes follow other orders.
  constexpr Index kCoeffBasedThreshold = 20;  // EIGEN_GEMM_TO_COEFFBASED_THRESHOLD
  if (m < 2 || n < 2 || k < 1 || m % 2 != 0 || k + m + n < kCoeffBasedThreshold) return false;
  if (!eigen_order_is_known(m, n, k)) return false;
  return run(ch.rows, m, n, k, a, lda, b, bl, bj, c, mode, h);
#else
  (void)m, (void)n, (void)k, (void)a, (void)lda, (void)b, (void)bl, (void)bj, (void)c, (void)mode,
      (void)h;
  return false;
#endif
}

const char* exact_product_isa() {
#ifdef CSYMPNET_EXACT_SIMD
  return chosen().isa;
#else
  return "eigen";
#endif
}

}  // namespace csympnet::detail
