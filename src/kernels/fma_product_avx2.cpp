// The AVX2 + FMA kernel of the fma-order products (fma_product.hpp), for CPUs without AVX-512:
// register tiles of up to 2 x 4 rows by 6 columns (12 chains in flight of 16 registers). Where
// m is not a multiple of 4, the last 4-row vector of the last row group is read and written
// with masked loads and stores. Columns and rows are swept as in fma_product_avx512.cpp.
#include "fma_product_kernels.hpp"

#ifdef CSYMPNET_FMA_KERNELS

#include <immintrin.h>

#include <array>
#include <utility>

namespace csympnet::kernels {

namespace {

#define CSYMPNET_FMA256 __attribute__((target("avx2,fma")))

constexpr int kCols = 6;  // columns per tile
constexpr int kVecs = 2;  // 4-row vectors per tile, at most

// The last vector's rows: masked (kMask) to the lanes set in `last`, else whole.
template <bool kMask>
CSYMPNET_FMA256 inline __m256d load(const double* p, __m256i last) {
  if constexpr (kMask) {
    return _mm256_maskload_pd(p, last);
  } else {
    (void)last;
    return _mm256_loadu_pd(p);
  }
}
template <bool kMask>
CSYMPNET_FMA256 inline void store(double* p, __m256i last, __m256d v) {
  if constexpr (kMask) {
    _mm256_maskstore_pd(p, last, v);
  } else {
    (void)last;
    _mm256_storeu_pd(p, v);
  }
}

// MV vectors of rows from i0 by NC columns from j0; with kMask the last vector has only its
// first last_rows lanes.
template <int MV, int NC, bool kMask>
CSYMPNET_FMA256 void tile(const FmaArgs& p, Index i0, Index j0, int last_rows, Index k0, Index k1,
                          const double* in, Index ldi, double* out, Index ldo) {
  const __m256i last =
      _mm256_set_epi64x(last_rows > 3 ? -1 : 0, last_rows > 2 ? -1 : 0, last_rows > 1 ? -1 : 0, -1);
  __m256d acc[MV][NC];
#pragma GCC unroll 8
  for (int j = 0; j < NC; ++j) {
#pragma GCC unroll 2
    for (int v = 0; v < MV; ++v) {
      if (in == nullptr) {
        acc[v][j] = _mm256_setzero_pd();
      } else {
        const double* src = in + i0 + 4 * v + (j0 + j) * ldi;
        acc[v][j] = v + 1 == MV ? load<kMask>(src, last) : _mm256_loadu_pd(src);
      }
    }
  }
  const Index lda = p.lda, bl = p.bl, bj = p.bj;
  const double* a = p.a + i0 + k0 * lda;
  const double* b = p.b + k0 * bl + j0 * bj;
  for (Index l = k0; l < k1; ++l, a += lda, b += bl) {
    __m256d av[MV];
#pragma GCC unroll 2
    for (int v = 0; v < MV; ++v)
      av[v] = v + 1 == MV ? load<kMask>(a + 4 * v, last) : _mm256_loadu_pd(a + 4 * v);
#pragma GCC unroll 8
    for (int j = 0; j < NC; ++j) {
      const __m256d bv = _mm256_broadcast_sd(b + j * bj);
#pragma GCC unroll 2
      for (int v = 0; v < MV; ++v) acc[v][j] = _mm256_fmadd_pd(av[v], bv, acc[v][j]);
    }
  }
  const Epilogue mode = p.mode;
#pragma GCC unroll 8
  for (int j = 0; j < NC; ++j) {
    const __m256d hv =
        _mm256_set1_pd(out == nullptr && mode == Epilogue::kAddScaled ? p.h[j0 + j] : 0.0);
#pragma GCC unroll 2
    for (int v = 0; v < MV; ++v) {
      const bool masked = v + 1 == MV;
      double* dst =
          out != nullptr ? out + i0 + 4 * v + (j0 + j) * ldo : p.c + i0 + 4 * v + (j0 + j) * p.ldc;
      __m256d r = acc[v][j];
      if (out == nullptr && mode != Epilogue::kStore) {
        const __m256d cv = masked ? load<kMask>(dst, last) : _mm256_loadu_pd(dst);
        r = mode == Epilogue::kAdd ? _mm256_add_pd(cv, r) : _mm256_fmadd_pd(r, hv, cv);
      }
      if (masked) {
        store<kMask>(dst, last, r);
      } else {
        _mm256_storeu_pd(dst, r);
      }
    }
  }
}

using TileFn = void (*)(const FmaArgs&, Index, Index, int, Index, Index, const double*, Index,
                        double*, Index);

template <int MV, bool kMask, int... NC>
constexpr std::array<TileFn, kCols> tiles_of(std::integer_sequence<int, NC...>) {
  return {tile<MV, NC + 1, kMask>...};
}

// kTiles[masked][MV − 1][NC − 1].
constexpr std::array<std::array<std::array<TileFn, kCols>, kVecs>, 2> kTiles = {
    {{tiles_of<1, false>(std::make_integer_sequence<int, kCols>{}),
      tiles_of<2, false>(std::make_integer_sequence<int, kCols>{})},
     {tiles_of<1, true>(std::make_integer_sequence<int, kCols>{}),
      tiles_of<2, true>(std::make_integer_sequence<int, kCols>{})}}};

}  // namespace

void fma_product_avx2(const FmaArgs& p, Index k0, Index k1, const double* in, Index ldi,
                      double* out, Index ldo) {
  const Index vecs = (p.m + 3) / 4;
  const auto last_rows = static_cast<int>(p.m - 4 * (vecs - 1));
  const bool ragged = last_rows < 4;
  for (Index j0 = 0; j0 < p.n; j0 += kCols) {
    const auto nc = static_cast<int>(p.n - j0 < kCols ? p.n - j0 : kCols);
    for (Index v0 = 0; v0 < vecs;) {
      const int mv = vecs - v0 >= 2 ? 2 : 1;
      const bool masked = ragged && v0 + mv == vecs;
      kTiles[masked ? 1 : 0][static_cast<std::size_t>(mv - 1)][static_cast<std::size_t>(nc - 1)](
          p, 4 * v0, j0, last_rows, k0, k1, in, ldi, out, ldo);
      v0 += mv;
    }
  }
}

}  // namespace csympnet::kernels

#endif  // CSYMPNET_FMA_KERNELS
