// Internal to product_avx512.cpp: its register tiles. Each computes its entries in the
// order stated at the top of product.cpp; the tiles differ only in which entries share
// a register. Include after sse2_order.hpp (no FMA contraction).
//
// Costs on AMD Zen 4, which runs a 512-bit operation as two 256-bit halves (1 multiply and
// 1 add per cycle at 512 bits, 2 of each at 256 or 128 bits), measured on this project's
// build machine, in cycles per l of a tile (multiplies and adds of 512 bits, 1 cycle each):
//   * 8 rows x 16 columns, the broadcast folded into the multiply (`vmulpd (mem){1to8}`):
//     16.0, the ideal. An explicit `vbroadcastsd zmm` takes a pipe slot: 8 x 8 with one per
//     multiply 15.4 (ideal 8), 16 x 8 with one per two multiplies 24 (ideal 16). So the main
//     tiles are 8 rows by 16 columns, each B value feeding one multiply;
//   * copying 16 pairs (B(l, s), B(l + 1, s)) alongside, per l: +0.8 with 128-bit loads and
//     stores, +3 as single doubles, +6 through `vmovhpd` stores (which take a pipe slot).
#pragma once

#include "product_targets.hpp"

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace csympnet::kernels::tiles512 {

#define CSYMPNET_AVX512_INLINE __attribute__((target("avx512f"), always_inline)) inline

// How B is stored: B(l, j) = b[l + j·bj] (kCols) or b[l·bl + j] (kRows).
enum class BLayout { kCols, kRows };

template <BLayout L>
CSYMPNET_AVX512_INLINE const double* b_at(const double* b, Index bl, Index bj, Index l, int s) {
  if constexpr (L == BLayout::kCols) {
    (void)bl;
    return b + l + s * bj;
  } else {
    (void)bj;
    return b + l * bl + s;
  }
}

// p, as a pointer the compiler cannot see through: loads of the copy of B are not merged with
// the multiplies' broadcast loads of the same addresses (merged, each broadcast would come
// from a register and take a pipe slot).
CSYMPNET_AVX512_INLINE const double* opaque(const double* p) {
  asm("" : "+r"(p));
  return p;
}

// v, kept in a register: a vector used by two multiplies would otherwise be folded into both
// as a memory operand, and the scalar they share broadcast with a pipe slot instead.
CSYMPNET_AVX512_INLINE __m512d in_register(__m512d v) {
  asm("" : "+v"(v));
  return v;
}

CSYMPNET_AVX512_INLINE void put512(double* p, __m512d v, Epilogue mode, const double* hs) {
  if (mode == Epilogue::kStore) {
    _mm512_storeu_pd(p, v);
  } else if (mode == Epilogue::kAdd) {
    _mm512_storeu_pd(p, _mm512_add_pd(_mm512_loadu_pd(p), v));
  } else {
    _mm512_storeu_pd(p, _mm512_add_pd(_mm512_loadu_pd(p), _mm512_mul_pd(v, _mm512_set1_pd(*hs))));
  }
}

// Writes the finished sums of tail rows m4 (s0) and m4 + 1 (s1) of 8 consecutive columns,
// one row per register: v = 0 + s, then each column's pair (m4, m4 + 1) to the epilogue.
CSYMPNET_AVX512_INLINE void put_rows8(__m512d s0, __m512d s1, double* ct, Index ldc, Epilogue mode,
                                      const double* h) {
  const __m512d r0 = _mm512_add_pd(_mm512_setzero_pd(), s0);
  const __m512d r1 = _mm512_add_pd(_mm512_setzero_pd(), s1);
  // Columns 0, 2, 4, 6 from the low halves of the 128-bit lanes, 1, 3, 5, 7 from the high
  // halves. (All-lanes zero masking is the plain instruction; GCC 12's unmasked intrinsic trips
  // -Wuninitialized on its undefined pass-through.)
  alignas(64) double pairs[16];
  _mm512_store_pd(pairs, _mm512_maskz_unpacklo_pd(0xFF, r0, r1));
  _mm512_store_pd(pairs + 8, _mm512_maskz_unpackhi_pd(0xFF, r0, r1));
#pragma GCC unroll 8
  for (int q = 0; q < 8; ++q) {
    put128(ct + q * ldc, _mm_load_pd(pairs + (q % 2 == 0 ? q : 7 + q)), mode, h + q);
  }
}

// Main rows: 8 (V = __m512d) or 4 (V = __m256d) rows of A from a, NC columns of B into c, one
// running sum per entry (s = 0; s += A(i,l) B(l,j), l = 0..k−1; c = 0 + s, then the
// epilogue).
//
// NR > 0: the tail rows m4, m4 + 1 (at = &A(m4, 0), ct = &C(m4, 0) of this panel) of the last
// NR columns, which lie after 4⌊n/4⌋ (one running sum each), ride along in 128-bit registers:
// alone their sums would wait on the add latency at every l.
//
// NP8 > 0 (B stored by rows): the tail rows of the first 8·NP8 columns, in Eigen's 4-column
// blocks, ride along as row vectors: 8 columns of one tail row per register, A(m4, l) and
// A(m4 + 1, l) broadcast, two sums (even and odd l below k8) added before l = k8..k−1.
//
// kCopy (B stored by columns): the tile also copies the first NP = NC − NR columns of B for the
// tail rows, in pair-lane order (tail_tile_pairs): for each l-pair below k8 = 8⌊k/8⌋ the
// pairs (B(l, s), B(l + 1, s)), s = 0..NP−1, then for each l ≥ k8 the pairs (B(l, s), B(l, s)).
// One 128-bit load and store per pair: no pipe slots, unlike any transposition of B.
template <typename V, int NC, BLayout L, bool kCopy, int NR, int NP8>
CSYMPNET_AVX512_INLINE void main_tile(Index k, const double* a, Index lda, const double* b,
                                      Index bl, Index bj, double* c, Index ldc, Epilogue mode,
                                      const double* h, double* copy, const double* at, double* ct) {
  constexpr bool k512 = sizeof(V) == 64;
  constexpr int NP = NC - NR;
  static_assert(!kCopy || L == BLayout::kCols);
  static_assert(NP8 == 0 || L == BLayout::kRows);
  V acc[NC];
  __m128d run[NR > 0 ? NR : 1];
  __m512d rows[2][2][NP8 > 0 ? NP8 : 1];  // [parity of l][tail row][8-column chunk]
#pragma GCC unroll 4
  for (int q = 0; q < 2 * 2 * NP8; ++q)
    rows[q / (2 * NP8)][q / NP8 % 2][q % NP8] = _mm512_setzero_pd();
#pragma GCC unroll 16
  for (int s = 0; s < NC; ++s) {
    if constexpr (k512) {
      acc[s] = _mm512_setzero_pd();
    } else {
      acc[s] = _mm256_setzero_pd();
    }
  }
#pragma GCC unroll 4
  for (int r = 0; r < NR; ++r) run[r] = _mm_setzero_pd();
  // Column s of B at group[s / 4] + (s % 4)·bj (stored by columns): four moving pointers and
  // three fixed offsets address 16 columns (a pointer per column would not fit in the general
  // registers beside the rest).
  constexpr int kGroups = (NC + 3) / 4;
  const double* group[kGroups];
#pragma GCC unroll 4
  for (int g = 0; g < kGroups; ++g) group[g] = b + 4 * g * (L == BLayout::kCols ? bj : 1);
  const auto column = [&](int s) -> const double* {
    if constexpr (L == BLayout::kCols) {
      return group[s / 4] + (s % 4) * bj;
    } else {
      return group[s / 4] + s % 4;
    }
  };
  const Index next = L == BLayout::kCols ? 1 : bl;  // from B(l, ·) to B(l + 1, ·)
  const auto step = [&]<int kParity>(Index l) __attribute__((always_inline)) {
    V av;
    if constexpr (k512) {
      av = _mm512_loadu_pd(a + l * lda);
    } else {
      av = _mm256_loadu_pd(a + l * lda);
    }
#pragma GCC unroll 16
    for (int s = 0; s < NC; ++s) {
      if constexpr (k512) {
        acc[s] = _mm512_add_pd(acc[s], _mm512_mul_pd(av, _mm512_set1_pd(*column(s))));
      } else {
        acc[s] = _mm256_add_pd(acc[s], _mm256_mul_pd(av, _mm256_set1_pd(*column(s))));
      }
    }
    if constexpr (NR > 0) {
      const __m128d tv = _mm_loadu_pd(at + l * lda);
#pragma GCC unroll 4
      for (int r = 0; r < NR; ++r) {
        run[r] = _mm_add_pd(run[r], _mm_mul_pd(tv, _mm_set1_pd(*opaque(column(NP + r)))));
      }
    }
#pragma GCC unroll 2
    for (int q = 0; q < NP8; ++q) {
      // B's row in a register, A's values as the multiplies' broadcast operands.
      const __m512d brow = in_register(_mm512_loadu_pd(column(8 * q)));
      const double* al = at + l * lda;
      __m512d(&acc2)[2][NP8 > 0 ? NP8 : 1] = rows[kParity];
      acc2[0][q] = _mm512_add_pd(acc2[0][q], _mm512_mul_pd(_mm512_set1_pd(*opaque(al)), brow));
      acc2[1][q] = _mm512_add_pd(acc2[1][q], _mm512_mul_pd(_mm512_set1_pd(*opaque(al + 1)), brow));
    }
#pragma GCC unroll 4
    for (int g = 0; g < kGroups; ++g) group[g] += next;
  };
  Index l = 0;
  const Index k8 = k & ~Index{7};
  if constexpr (kCopy) {
    for (; l < k8; l += 2, copy += 2 * NP) {
      // The copy's loads through pointers the compiler cannot match with the multiplies'
      // (one asm per group of 4 columns keeps the addressing free).
      const double* hidden[kGroups];
#pragma GCC unroll 4
      for (int g = 0; g < kGroups; ++g) hidden[g] = opaque(group[g]);
#pragma GCC unroll 16
      for (int s = 0; s < NP; ++s) {
        __m128d pair = _mm_loadu_pd(hidden[s / 4] + (s % 4) * bj);
        asm("" : "+x"(pair));  // one load for both: the compiler would split it in two
        _mm_storeu_pd(copy + 2 * s, pair);
      }
      step.template operator()<0>(l);
      step.template operator()<1>(l + 1);
    }
    for (; l < k; ++l, copy += 2 * NP) {
      const double* hidden[kGroups];
#pragma GCC unroll 4
      for (int g = 0; g < kGroups; ++g) hidden[g] = opaque(group[g]);
#pragma GCC unroll 16
      for (int s = 0; s < NP; ++s) {
        _mm_storeu_pd(copy + 2 * s, _mm_loaddup_pd(hidden[s / 4] + (s % 4) * bj));
      }
      step.template operator()<0>(l);
    }
  } else if constexpr (NP8 > 0) {
    for (; l < k8; l += 2) {
      step.template operator()<0>(l);
      step.template operator()<1>(l + 1);
    }
#pragma GCC unroll 4
    for (int q = 0; q < 2 * NP8; ++q) {
      rows[0][q / NP8][q % NP8] =
          _mm512_add_pd(rows[0][q / NP8][q % NP8], rows[1][q / NP8][q % NP8]);
    }
  }
  for (; l < k; ++l) step.template operator()<0>(l);
#pragma GCC unroll 16
  for (int s = 0; s < NC; ++s) {
    if constexpr (k512) {
      put512(c + s * ldc, _mm512_add_pd(_mm512_setzero_pd(), acc[s]), mode, h + s);
    } else {
      put256(c + s * ldc, _mm256_add_pd(_mm256_setzero_pd(), acc[s]), mode, h + s);
    }
  }
#pragma GCC unroll 4
  for (int r = 0; r < NR; ++r) {
    put128(ct + (NP + r) * ldc, _mm_add_pd(_mm_setzero_pd(), run[r]), mode, h + NP + r);
  }
#pragma GCC unroll 2
  for (int q = 0; q < NP8; ++q) {
    put_rows8(rows[0][0][q], rows[0][1][q], ct + 8 * q * ldc, ldc, mode, h + 8 * q);
  }
}

// The tail rows' A in pair-lane order for tail_tile_pairs: for each l-pair below k8, 8 lanes
// (A(m4, l), A(m4, l + 1)) x 4 and 8 lanes (A(m4 + 1, l), A(m4 + 1, l + 1)) x 4; then for each
// l ≥ k8, 8 lanes (A(m4, l), A(m4 + 1, l)) x 4. (k8 + 7) x 8 doubles at most.
inline void pack_tail_a(Index k, const double* at, Index lda, double* out) {
  const Index k8 = k & ~Index{7};
  Index l = 0;
  for (; l < k8; l += 2, out += 16) {
    for (int q = 0; q < 8; q += 2) {
      out[q] = at[l * lda];
      out[q + 1] = at[(l + 1) * lda];
      out[8 + q] = at[l * lda + 1];
      out[8 + q + 1] = at[(l + 1) * lda + 1];
    }
  }
  for (; l < k; ++l, out += 8) {
    for (int q = 0; q < 8; q += 2) {
      out[q] = at[l * lda];
      out[q + 1] = at[l * lda + 1];
    }
  }
}

// Tail rows m4, m4 + 1 of 4G columns in Eigen's 4-column blocks, from main_tile's pair-lane
// copy of B (row pitch 8G per l-pair or l) and pack_tail_a's A. Below k8 one register per row
// and 4 columns holds each column's even-l sum c and odd-l sum d side by side; c + d then puts
// the two rows of a column side by side, (m4, m4 + 1), which the last l ≥ k8 extend and the
// epilogue writes: each entry sees exactly the operations of tail_tile128<·, true>.
template <int G>
CSYMPNET_AVX512_INLINE void tail_tile_pairs(Index k, const double* ap, const double* copy,
                                            double* ct, Index ldc, Epilogue mode, const double* h) {
  constexpr Index kPitch = 8 * G;
  __m512d t0[G], t1[G];  // rows m4, m4 + 1: lanes (c, d) of columns 4g .. 4g + 3
#pragma GCC unroll 4
  for (int g = 0; g < G; ++g) t0[g] = t1[g] = _mm512_setzero_pd();
  const Index k8 = k & ~Index{7};
  for (Index l = 0; l < k8; l += 2, ap += 16, copy += kPitch) {
    const __m512d a0 = _mm512_load_pd(ap);
    const __m512d a1 = _mm512_load_pd(ap + 8);
#pragma GCC unroll 4
    for (int g = 0; g < G; ++g) {
      const __m512d z = _mm512_loadu_pd(copy + 8 * g);
      t0[g] = _mm512_add_pd(t0[g], _mm512_mul_pd(a0, z));
      t1[g] = _mm512_add_pd(t1[g], _mm512_mul_pd(a1, z));
    }
  }
  // (All-lanes zero masking is the plain instruction; GCC 12's unmasked intrinsic trips
  // -Wuninitialized on its undefined pass-through.)
  __m512d u[G];  // lanes (m4, m4 + 1) of columns 4g .. 4g + 3
#pragma GCC unroll 4
  for (int g = 0; g < G; ++g) {
    u[g] = _mm512_add_pd(_mm512_maskz_unpacklo_pd(0xFF, t0[g], t1[g]),
                         _mm512_maskz_unpackhi_pd(0xFF, t0[g], t1[g]));
    if (k8 == 0) u[g] = _mm512_setzero_pd();
  }
  for (Index l = k8; l < k; ++l, ap += 8, copy += kPitch) {
    const __m512d aa = _mm512_load_pd(ap);
#pragma GCC unroll 4
    for (int g = 0; g < G; ++g) {
      u[g] = _mm512_add_pd(u[g], _mm512_mul_pd(aa, _mm512_loadu_pd(copy + 8 * g)));
    }
  }
#pragma GCC unroll 4
  for (int g = 0; g < G; ++g) {
    alignas(64) double pairs[8];
    _mm512_store_pd(pairs, _mm512_add_pd(_mm512_setzero_pd(), u[g]));
#pragma GCC unroll 4
    for (int q = 0; q < 4; ++q) {
      put128(ct + (4 * g + q) * ldc, _mm_load_pd(pairs + 2 * q), mode, h + 4 * g + q);
    }
  }
}

// Tail rows m4, m4 + 1 (at = &A(m4, 0), ct = &C(m4, 0)), NC columns, one column per 128-bit
// register (Eigen's own layout). kPairs (columns in Eigen's 4-column blocks): even and odd
// l < k8 = 8⌊k/8⌋ into two sums, added before l = k8..k−1; otherwise one running sum.
template <int NC, bool kPairs, BLayout L>
CSYMPNET_AVX512_INLINE void tail_tile128(Index k, const double* at, Index lda, const double* b,
                                         Index bl, Index bj, double* ct, Index ldc, Epilogue mode,
                                         const double* h) {
  __m128d even[NC];
  __m128d odd[NC];
#pragma GCC unroll 8
  for (int s = 0; s < NC; ++s) even[s] = odd[s] = _mm_setzero_pd();
  Index l = 0;
  if constexpr (kPairs) {
    for (const Index k8 = k & ~Index{7}; l < k8; l += 2) {
      const __m128d ae = _mm_loadu_pd(at + l * lda);
      const __m128d ao = _mm_loadu_pd(at + (l + 1) * lda);
#pragma GCC unroll 8
      for (int s = 0; s < NC; ++s) {
        const __m128d be = _mm_set1_pd(*b_at<L>(b, bl, bj, l, s));
        const __m128d bo = _mm_set1_pd(*b_at<L>(b, bl, bj, l + 1, s));
        even[s] = _mm_add_pd(even[s], _mm_mul_pd(ae, be));
        odd[s] = _mm_add_pd(odd[s], _mm_mul_pd(ao, bo));
      }
    }
#pragma GCC unroll 8
    for (int s = 0; s < NC; ++s) even[s] = _mm_add_pd(even[s], odd[s]);
  }
  for (; l < k; ++l) {
    const __m128d av = _mm_loadu_pd(at + l * lda);
#pragma GCC unroll 8
    for (int s = 0; s < NC; ++s) {
      even[s] = _mm_add_pd(even[s], _mm_mul_pd(av, _mm_set1_pd(*b_at<L>(b, bl, bj, l, s))));
    }
  }
#pragma GCC unroll 8
  for (int s = 0; s < NC; ++s) {
    put128(ct + s * ldc, _mm_add_pd(_mm_setzero_pd(), even[s]), mode, h + s);
  }
}

#undef CSYMPNET_AVX512_INLINE

}  // namespace csympnet::kernels::tiles512

#endif  // CSYMPNET_SSE2_ORDER_KERNELS
