// ColumnSums (column_sums.hpp): the 4 x 4 transposes and the running sums in 256-bit registers,
// with AVX-512VL's 32 of them or AVX2's 16.
//
// 256-bit rather than 512-bit registers: on Zen 4 a 512-bit shuffle costs two 256-bit ones, and
// an 8 x 8 tile needs three shuffle steps where a 4 x 4 tile needs two; the sums of 1920
// products take ~540 cycles this way against ~700 with 8 x 8 tiles (vpermt2pd) and 512-bit adds.
#include "column_sums.hpp"

#include <cstdint>

#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
#define CSYMPNET_COLUMN_SUMS_SIMD 1
#include <immintrin.h>
#endif

namespace csympnet::kernels {

ColumnSums::ColumnSums(Index columns, Isa isa)
    : isa_(isa), row_(isa == Isa::kAvx512 ? kColumnSumsBlock : kColumnSumsBlockAvx2) {
  const Index cols8 = (columns + 7) / 8 * 8;  // whole groups of 8 lanes
  if (cols8 > 256) {
    sums_heap_.reset(new double[static_cast<std::size_t>(cols8 + 8)]);
    sums_ = sums_heap_.get();
    while (reinterpret_cast<std::uintptr_t>(sums_) % 64 != 0) ++sums_;
  }
}

#ifdef CSYMPNET_COLUMN_SUMS_SIMD

namespace {

constexpr Index B = kColumnSumsBlock;
constexpr Index B2 = kColumnSumsBlockAvx2;
constexpr Index kFlushColumns = ColumnSums::kFlushColumns;

// The tile at rows t, t + R, t + 2R, t + 3R (four columns of R samples), samples j .. j + 3: x[s]
// holds the four columns at sample j + s, in column order. unpacklo/hi pair the columns 0, 1 and 2,
// 3 at samples (j, j + 2) and (j + 1, j + 3); the 128-bit halves are then exchanged.
template <Index R = B>
__attribute__((target("avx"), always_inline)) inline void transpose_tile(const double* t,
                                                                         __m256d (&x)[4]) {
  const __m256d r0 = _mm256_load_pd(t), r1 = _mm256_load_pd(t + R);
  const __m256d r2 = _mm256_load_pd(t + 2 * R), r3 = _mm256_load_pd(t + 3 * R);
  const __m256d e01 = _mm256_unpacklo_pd(r0, r1), o01 = _mm256_unpackhi_pd(r0, r1);
  const __m256d e23 = _mm256_unpacklo_pd(r2, r3), o23 = _mm256_unpackhi_pd(r2, r3);
  x[0] = _mm256_permute2f128_pd(e01, e23, 0x20);
  x[1] = _mm256_permute2f128_pd(o01, o23, 0x20);
  x[2] = _mm256_permute2f128_pd(e01, e23, 0x31);
  x[3] = _mm256_permute2f128_pd(o01, o23, 0x31);
}

// Advances the running sums of kTiles tiles of 4 columns (rows of B products from rows on) by a
// full block's B samples, in sample order (sums += x, the order of sequential_dot), from −0
// when kFresh (the first block) or from the stored sums. Each tile's sums are one chain of
// dependent adds; twelve at once keep both adders busy. AVX-512VL for its 32 registers: twelve
// sums and a tile's temporaries.
template <int kTiles, bool kFresh>
__attribute__((target("avx512f,avx512vl"))) void sum_tiles(const double* rows, double* sums) {
  __m256d acc[kTiles];
#pragma GCC unroll 16
  for (int ti = 0; ti < kTiles; ++ti) {
    acc[ti] = kFresh ? _mm256_set1_pd(-0.0) : _mm256_load_pd(sums + 4 * ti);
  }
  for (Index j = 0; j < B; j += 4) {
#pragma GCC unroll 16
    for (int ti = 0; ti < kTiles; ++ti) {
      __m256d x[4];
      transpose_tile(rows + 4 * ti * B + j, x);
      acc[ti] = _mm256_add_pd(acc[ti], x[0]);
      acc[ti] = _mm256_add_pd(acc[ti], x[1]);
      acc[ti] = _mm256_add_pd(acc[ti], x[2]);
      acc[ti] = _mm256_add_pd(acc[ti], x[3]);
    }
  }
#pragma GCC unroll 16
  for (int ti = 0; ti < kTiles; ++ti) _mm256_store_pd(sums + 4 * ti, acc[ti]);
}

template <int kTiles>
void sum_full(int tiles, bool fresh, const double* rows, double* sums) {
  if constexpr (kTiles > 0) {
    if (tiles != kTiles) {
      sum_full<kTiles - 1>(tiles, fresh, rows, sums);
    } else {
      (fresh ? sum_tiles<kTiles, true> : sum_tiles<kTiles, false>)(rows, sums);
    }
  }
}

// The same for the last block of a batch, of cnt < B samples: the live samples only (adding
// +0 for a dead one would turn a −0 sum into +0). Tile by tile, one chain at a time.
__attribute__((target("avx512f,avx512vl"))) void sum_partial(Index tiles, bool fresh,
                                                             const double* rows, double* sums,
                                                             Index cnt) {
  for (Index ti = 0; ti < tiles; ++ti) {
    __m256d acc = fresh ? _mm256_set1_pd(-0.0) : _mm256_load_pd(sums + 4 * ti);
    for (Index j = 0; j < cnt; j += 4) {
      __m256d x[4];
      transpose_tile(rows + 4 * ti * B + j, x);
      for (Index s = 0; s < 4 && j + s < cnt; ++s) acc = _mm256_add_pd(acc, x[s]);
    }
    _mm256_store_pd(sums + 4 * ti, acc);
  }
}

// The AVX2 form of sum_tiles, for machines without AVX-512: sixteen registers hold the sums of
// four tiles and one tile's temporaries, so the tiles go four at a time (each tile's sums are
// still one chain of adds in sample order); rows of B2 samples.
template <int kTiles, bool kFresh>
__attribute__((target("avx2"))) void sum_tiles_avx2(const double* rows, double* sums) {
  __m256d acc[kTiles];
#pragma GCC unroll 4
  for (int ti = 0; ti < kTiles; ++ti) {
    acc[ti] = kFresh ? _mm256_set1_pd(-0.0) : _mm256_load_pd(sums + 4 * ti);
  }
  for (Index j = 0; j < B2; j += 4) {
#pragma GCC unroll 4
    for (int ti = 0; ti < kTiles; ++ti) {
      __m256d x[4];
      transpose_tile<B2>(rows + 4 * ti * B2 + j, x);
      acc[ti] = _mm256_add_pd(acc[ti], x[0]);
      acc[ti] = _mm256_add_pd(acc[ti], x[1]);
      acc[ti] = _mm256_add_pd(acc[ti], x[2]);
      acc[ti] = _mm256_add_pd(acc[ti], x[3]);
    }
  }
#pragma GCC unroll 4
  for (int ti = 0; ti < kTiles; ++ti) _mm256_store_pd(sums + 4 * ti, acc[ti]);
}

__attribute__((target("avx2"))) void sum_full_avx2(Index tiles, bool fresh, const double* rows,
                                                   double* sums) {
  Index ti = 0;
  for (; ti + 4 <= tiles; ti += 4) {
    (fresh ? sum_tiles_avx2<4, true> : sum_tiles_avx2<4, false>)(rows + 4 * ti * B2, sums + 4 * ti);
  }
  const double* rest = rows + 4 * ti * B2;
  double* rest_sums = sums + 4 * ti;
  switch (tiles - ti) {
    case 3:
      (fresh ? sum_tiles_avx2<3, true> : sum_tiles_avx2<3, false>)(rest, rest_sums);
      break;
    case 2:
      (fresh ? sum_tiles_avx2<2, true> : sum_tiles_avx2<2, false>)(rest, rest_sums);
      break;
    case 1:
      (fresh ? sum_tiles_avx2<1, true> : sum_tiles_avx2<1, false>)(rest, rest_sums);
      break;
    default:
      break;
  }
}

// sum_partial's AVX2 form.
__attribute__((target("avx2"))) void sum_partial_avx2(Index tiles, bool fresh, const double* rows,
                                                      double* sums, Index cnt) {
  for (Index ti = 0; ti < tiles; ++ti) {
    __m256d acc = fresh ? _mm256_set1_pd(-0.0) : _mm256_load_pd(sums + 4 * ti);
    for (Index j = 0; j < cnt; j += 4) {
      __m256d x[4];
      transpose_tile<B2>(rows + 4 * ti * B2 + j, x);
      for (Index s = 0; s < 4 && j + s < cnt; ++s) acc = _mm256_add_pd(acc, x[s]);
    }
    _mm256_store_pd(sums + 4 * ti, acc);
  }
}

__attribute__((target("avx512f,avx512vl"))) void flush_avx512(Index tiles, bool fresh,
                                                              const double* rows, double* sums,
                                                              Index cnt) {
  if (cnt == B) {
    sum_full<kFlushColumns / 4>(static_cast<int>(tiles), fresh, rows, sums);
  } else {
    sum_partial(tiles, fresh, rows, sums, cnt);
  }
}

__attribute__((target("avx2"))) void flush_avx2(Index tiles, bool fresh, const double* rows,
                                                double* sums, Index cnt) {
  if (cnt == B2) {
    sum_full_avx2(tiles, fresh, rows, sums);
  } else {
    sum_partial_avx2(tiles, fresh, rows, sums, cnt);
  }
}

}  // namespace

void ColumnSums::flush(Index cnt) {
  const Index tiles = (filled_ + 3) / 4;
  // Rows past the last column go to sums that are never read: zeros rather than stale values.
  for (Index i = filled_ * row_; i < tiles * 4 * row_; ++i) products_[i] = 0.0;
  if (isa_ == Isa::kAvx512) {
    flush_avx512(tiles, fresh_, products_, sums_ + first_, cnt);
  } else {
    flush_avx2(tiles, fresh_, products_, sums_ + first_, cnt);
  }
  first_ += filled_;
  filled_ = 0;
}

#else

void ColumnSums::flush(Index) {}  // not reached: the backward sweeps need AVX-512 or AVX2

#endif

}  // namespace csympnet::kernels
