// ColumnSums (column_sums.hpp): the 8 x 8 transposes and the running sums in AVX-512.
#include "column_sums.hpp"

#include <cstdint>

#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
#define CSYMPNET_COLUMN_SUMS_SIMD 1
#include <immintrin.h>
#endif

namespace csympnet::detail {

ColumnSums::ColumnSums(Index columns) {
  const Index cols8 = (columns + 7) / 8 * 8;  // whole groups of 8 lanes
  if (cols8 > 256) {
    sums_heap_.reset(new double[static_cast<std::size_t>(cols8 + 8)]);
    sums_ = sums_heap_.get();
    while (reinterpret_cast<std::uintptr_t>(sums_) % 64 != 0) ++sums_;
  }
  for (Index i = 0; i < cols8; ++i) sums_[i] = -0.0;
}

#ifdef CSYMPNET_COLUMN_SUMS_SIMD

namespace {

// x[s] = the products of the 8 columns at rows t, t + kColumnSumsBlock, ..., t + 7
// kColumnSumsBlock, at sample s of the 8 from t on: one 8 x 8 transpose. Its first step is done by
// the loads (a_r = [column r, samples 4 half .. +3 | column r + 4, the same samples]), the rest by
// lane selections over register pairs (vpermt2pd; lanes 8.. are the second register's).
__attribute__((target("avx512f"), always_inline)) inline void transpose_tile(const double* t,
                                                                             __m512d (&x)[8]) {
  const __m512i even = _mm512_set_epi64(14, 6, 12, 4, 10, 2, 8, 0);
  const __m512i odd = _mm512_set_epi64(15, 7, 13, 5, 11, 3, 9, 1);
  const __m512i lo = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0);
  const __m512i hi = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);
#pragma GCC unroll 2
  for (int half = 0; half < 2; ++half) {
    __m512d a[4];
#pragma GCC unroll 4
    for (int r = 0; r < 4; ++r) {
      const double* row = t + r * kColumnSumsBlock + 4 * half;
      a[r] = _mm512_mask_loadu_pd(_mm512_maskz_loadu_pd(0x0F, row), 0xF0,
                                  row + 4 * kColumnSumsBlock - 4);
    }
    // e01: columns 0, 1 (and 4, 5) at samples 0 and 2 of the half; o01 at samples 1 and 3.
    const __m512d e01 = _mm512_permutex2var_pd(a[0], even, a[1]);
    const __m512d o01 = _mm512_permutex2var_pd(a[0], odd, a[1]);
    const __m512d e23 = _mm512_permutex2var_pd(a[2], even, a[3]);
    const __m512d o23 = _mm512_permutex2var_pd(a[2], odd, a[3]);
    x[4 * half + 0] = _mm512_permutex2var_pd(e01, lo, e23);
    x[4 * half + 1] = _mm512_permutex2var_pd(o01, lo, o23);
    x[4 * half + 2] = _mm512_permutex2var_pd(e01, hi, e23);
    x[4 * half + 3] = _mm512_permutex2var_pd(o01, hi, o23);
  }
}

// Advances the running sums of kGroups groups of 8 columns (rows of kColumnSumsBlock products from
// rows on) by the block's cnt samples, in sample order (sums += x, the order of sequential_dot).
// Each group's sums are one chain of dependent adds; several groups at once keep the adder busy.
template <int kGroups>
__attribute__((target("avx512f"))) void sum_groups(const double* rows, double* sums, Index cnt) {
  __m512d acc[kGroups];
  const double* t[kGroups];
#pragma GCC unroll 4
  for (int gi = 0; gi < kGroups; ++gi) {
    acc[gi] = _mm512_load_pd(sums + 8 * gi);
    t[gi] = rows + 8 * gi * kColumnSumsBlock;
  }
  for (Index j = 0; j < cnt; j += 8) {
    const Index live = cnt - j;
#pragma GCC unroll 4
    for (int gi = 0; gi < kGroups; ++gi) {
      __m512d x[8];
      transpose_tile(t[gi] + j, x);
#pragma GCC unroll 8
      for (Index s = 0; s < 8; ++s) {
        if (s < live) acc[gi] = _mm512_add_pd(acc[gi], x[s]);
      }
    }
  }
#pragma GCC unroll 4
  for (int gi = 0; gi < kGroups; ++gi) _mm512_store_pd(sums + 8 * gi, acc[gi]);
}

}  // namespace

__attribute__((target("avx512f"))) void ColumnSums::flush(Index cnt) {
  const Index groups = (filled_ + 7) / 8;
  // Rows past the last column go to sums that are never read: zeros rather than stale values.
  for (Index i = filled_ * kColumnSumsBlock; i < groups * 8 * kColumnSumsBlock; ++i) {
    products_[i] = 0.0;
  }
  double* sums = sums_ + first_;
  if (groups == 3) sum_groups<3>(products_, sums, cnt);
  if (groups == 2) sum_groups<2>(products_, sums, cnt);
  if (groups == 1) sum_groups<1>(products_, sums, cnt);
  first_ += filled_;
  filled_ = 0;
}

#else

void ColumnSums::flush(Index) {}  // not reached: la_scalar_sweep.cpp's kernels need AVX-512

#endif

}  // namespace csympnet::detail
