// The AVX-512 kernel of the fma-order products (fma_product.hpp): register tiles of up to
// 3 x 8 rows by 8 columns, 24 chains in flight, one FMA per chain and step l. The last 8-row
// vector of a tile is masked to the rows that remain, so every m is covered without a scalar
// rest. Columns go in tiles of 8 (the rest in one narrower tile); within a column tile every
// row group runs over the same columns of B, which stay in L1, while A's block (the inner
// block of fma_product.cpp) stays in L2.
#include "fma_product_kernels.hpp"

#ifdef CSYMPNET_FMA_KERNELS

#include <immintrin.h>

#include <array>
#include <utility>

namespace csympnet::kernels {

namespace {

#define CSYMPNET_FMA512 __attribute__((target("avx512f")))

constexpr int kCols = 8;  // columns per tile
constexpr int kVecs = 3;  // 8-row vectors per tile, at most

// MV vectors of rows from i0 (the last one masked to `last`) by NC columns from j0.
template <int MV, int NC>
CSYMPNET_FMA512 void tile(const FmaArgs& p, Index i0, Index j0, __mmask8 last, Index k0, Index k1,
                          const double* in, Index ldi, double* out, Index ldo) {
  __mmask8 mask[MV];
#pragma GCC unroll 4
  for (int v = 0; v < MV; ++v) mask[v] = v + 1 < MV ? __mmask8{0xFF} : last;
  __m512d acc[MV][NC];
#pragma GCC unroll 8
  for (int j = 0; j < NC; ++j) {
#pragma GCC unroll 4
    for (int v = 0; v < MV; ++v) {
      acc[v][j] = in == nullptr ? _mm512_setzero_pd()
                                : _mm512_maskz_loadu_pd(mask[v], in + i0 + 8 * v + (j0 + j) * ldi);
    }
  }
  const Index lda = p.lda, bl = p.bl, bj = p.bj;
  const double* a = p.a + i0 + k0 * lda;
  const double* b = p.b + k0 * bl + j0 * bj;
  for (Index l = k0; l < k1; ++l, a += lda, b += bl) {
    __m512d av[MV];
#pragma GCC unroll 4
    for (int v = 0; v < MV; ++v) av[v] = _mm512_maskz_loadu_pd(mask[v], a + 8 * v);
#pragma GCC unroll 8
    for (int j = 0; j < NC; ++j) {
      const __m512d bv = _mm512_set1_pd(b[j * bj]);
#pragma GCC unroll 4
      for (int v = 0; v < MV; ++v) acc[v][j] = _mm512_fmadd_pd(av[v], bv, acc[v][j]);
    }
  }
  if (out != nullptr) {
#pragma GCC unroll 8
    for (int j = 0; j < NC; ++j) {
#pragma GCC unroll 4
      for (int v = 0; v < MV; ++v)
        _mm512_mask_storeu_pd(out + i0 + 8 * v + (j0 + j) * ldo, mask[v], acc[v][j]);
    }
    return;
  }
  const Epilogue mode = p.mode;
#pragma GCC unroll 8
  for (int j = 0; j < NC; ++j) {
    const __m512d hv = _mm512_set1_pd(mode == Epilogue::kAddScaled ? p.h[j0 + j] : 0.0);
#pragma GCC unroll 4
    for (int v = 0; v < MV; ++v) {
      double* dst = p.c + i0 + 8 * v + (j0 + j) * p.ldc;
      __m512d r = acc[v][j];
      if (mode == Epilogue::kAdd) {
        r = _mm512_add_pd(_mm512_maskz_loadu_pd(mask[v], dst), r);
      } else if (mode == Epilogue::kAddScaled) {
        r = _mm512_fmadd_pd(r, hv, _mm512_maskz_loadu_pd(mask[v], dst));
      }
      _mm512_mask_storeu_pd(dst, mask[v], r);
    }
  }
}

using TileFn = void (*)(const FmaArgs&, Index, Index, __mmask8, Index, Index, const double*, Index,
                        double*, Index);

template <int MV, int... NC>
constexpr std::array<TileFn, kCols> tiles_of(std::integer_sequence<int, NC...>) {
  return {tile<MV, NC + 1>...};
}

// kTiles[MV − 1][NC − 1].
constexpr std::array<std::array<TileFn, kCols>, kVecs> kTiles = {
    tiles_of<1>(std::make_integer_sequence<int, kCols>{}),
    tiles_of<2>(std::make_integer_sequence<int, kCols>{}),
    tiles_of<3>(std::make_integer_sequence<int, kCols>{})};

}  // namespace

void fma_product_avx512(const FmaArgs& p, Index k0, Index k1, const double* in, Index ldi,
                        double* out, Index ldo) {
  const Index vecs = (p.m + 7) / 8;
  const int last_rows = static_cast<int>(p.m - 8 * (vecs - 1));
  const auto last = static_cast<__mmask8>((1u << last_rows) - 1u);
  for (Index j0 = 0; j0 < p.n; j0 += kCols) {
    const auto nc = static_cast<int>(p.n - j0 < kCols ? p.n - j0 : kCols);
    for (Index v0 = 0; v0 < vecs;) {
      // Groups of 3 vectors, a rest of 4 as 2 + 2 (never a lone vector after full groups).
      const Index left = vecs - v0;
      const int mv = left == 4 ? 2 : left >= 3 ? 3 : static_cast<int>(left);
      const __mmask8 mask = v0 + mv == vecs ? last : __mmask8{0xFF};
      kTiles[static_cast<std::size_t>(mv - 1)][static_cast<std::size_t>(nc - 1)](
          p, 8 * v0, j0, mask, k0, k1, in, ldi, out, ldo);
      v0 += mv;
    }
  }
}

}  // namespace csympnet::kernels

#endif  // CSYMPNET_FMA_KERNELS
