// The AVX-512 kernel of the fma-order products (fma_product.hpp): register tiles of up to
// 3 x 8 rows by 8 columns, 24 chains in flight, one FMA per chain and step l. The last vector
// of rows is a zmm masked to the rows that remain (so every m is covered without a scalar
// rest), or a ymm or xmm where exactly 4 or 2 remain. Columns go in tiles of 8 (the rest in one
// narrower tile); within a column tile every row group runs over the same columns of B, which stay
// in L1, while A's block (the inner block of fma_product.cpp) stays in L2.
#include "fma_product_kernels.hpp"

#ifdef CSYMPNET_FMA_KERNELS

#include <immintrin.h>

#include <array>
#include <utility>

namespace csympnet::kernels {

namespace {

#define CSYMPNET_FMA512 __attribute__((target("avx512f,fma"), always_inline)) inline
#define CSYMPNET_FMA512_OUTLINE __attribute__((target("avx512f,fma")))

constexpr int kCols = 8;  // columns per tile
constexpr int kVecs = 3;  // 8-row vectors per tile, at most

// The registers of a tile's last vector (lanes(): the low lanes of a broadcast, no instruction) of
// rows: a zmm masked to the rows that remain, or, where exactly 4 or 2 rows remain (m = 100, m =
// 10, 50), a ymm or xmm, whose operations take half or a quarter of a zmm's pipe slots on CPUs that
// split 512-bit operations.
struct Zmm {
  using V = __m512d;
  CSYMPNET_FMA512 static V zero() { return _mm512_setzero_pd(); }
  CSYMPNET_FMA512 static V load(const double* p, __mmask8 m) { return _mm512_maskz_loadu_pd(m, p); }
  CSYMPNET_FMA512 static void store(double* p, __mmask8 m, V v) { _mm512_mask_storeu_pd(p, m, v); }
  CSYMPNET_FMA512 static V lanes(__m512d v) { return v; }
  CSYMPNET_FMA512 static V fma(V a, V b, V c) { return _mm512_fmadd_pd(a, b, c); }
  CSYMPNET_FMA512 static V add(V a, V b) { return _mm512_add_pd(a, b); }
};
struct Ymm {
  using V = __m256d;
  CSYMPNET_FMA512 static V zero() { return _mm256_setzero_pd(); }
  CSYMPNET_FMA512 static V load(const double* p, __mmask8) { return _mm256_loadu_pd(p); }
  CSYMPNET_FMA512 static void store(double* p, __mmask8, V v) { _mm256_storeu_pd(p, v); }
  CSYMPNET_FMA512 static V lanes(__m512d v) { return __builtin_shufflevector(v, v, 0, 1, 2, 3); }
  CSYMPNET_FMA512 static V fma(V a, V b, V c) { return _mm256_fmadd_pd(a, b, c); }
  CSYMPNET_FMA512 static V add(V a, V b) { return _mm256_add_pd(a, b); }
};
struct Xmm {
  using V = __m128d;
  CSYMPNET_FMA512 static V zero() { return _mm_setzero_pd(); }
  CSYMPNET_FMA512 static V load(const double* p, __mmask8) { return _mm_loadu_pd(p); }
  CSYMPNET_FMA512 static void store(double* p, __mmask8, V v) { _mm_storeu_pd(p, v); }
  CSYMPNET_FMA512 static V lanes(__m512d v) { return __builtin_shufflevector(v, v, 0, 1); }
  CSYMPNET_FMA512 static V fma(V a, V b, V c) { return _mm_fmadd_pd(a, b, c); }
  CSYMPNET_FMA512 static V add(V a, V b) { return _mm_add_pd(a, b); }
};

// The epilogue of one register of entries at dst (kAdd: C + s; kAddScaled: fma(s, h_j, C)).
template <typename R>
CSYMPNET_FMA512 void finish(const FmaArgs& p, double* dst, __mmask8 mask, typename R::V s,
                            typename R::V hv) {
  if (p.mode == Epilogue::kAdd) {
    s = R::add(R::load(dst, mask), s);
  } else if (p.mode == Epilogue::kAddScaled) {
    s = R::fma(s, hv, R::load(dst, mask));
  }
  R::store(dst, mask, s);
}

// MV − 1 whole 8-row vectors and a last vector of registers T (masked to `last` when T is
// Zmm) from row i0, by NC columns from j0.
template <int MV, int NC, typename T>
CSYMPNET_FMA512_OUTLINE void tile(const FmaArgs& p, Index i0, Index j0, __mmask8 last, Index k0,
                                  Index k1, const double* in, Index ldi, double* out, Index ldo) {
  constexpr int F = MV - 1;          // whole vectors
  constexpr int FA = F > 0 ? F : 1;  // (an array of none is not C++)
  constexpr __mmask8 kAll = 0xFF;
  __m512d acc[FA][NC];
  typename T::V tail[NC];
  const Index it = i0 + 8 * F;  // the last vector's first row
#pragma GCC unroll 8
  for (int j = 0; j < NC; ++j) {
#pragma GCC unroll 4
    for (int v = 0; v < F; ++v) {
      acc[v][j] =
          in == nullptr ? _mm512_setzero_pd() : _mm512_loadu_pd(in + i0 + 8 * v + (j0 + j) * ldi);
    }
    tail[j] = in == nullptr ? T::zero() : T::load(in + it + (j0 + j) * ldi, last);
  }
  const Index lda = p.lda, bl = p.bl, bj = p.bj;
  const double* a = p.a + i0 + k0 * lda;
  const double* b = p.b + k0 * bl + j0 * bj;
  for (Index l = k0; l < k1; ++l, a += lda, b += bl) {
    __m512d av[FA];
#pragma GCC unroll 4
    for (int v = 0; v < F; ++v) av[v] = _mm512_loadu_pd(a + 8 * v);
    const typename T::V at = T::load(a + 8 * F, last);
#pragma GCC unroll 8
    for (int j = 0; j < NC; ++j) {
      const __m512d bv = _mm512_set1_pd(b[j * bj]);
#pragma GCC unroll 4
      for (int v = 0; v < F; ++v) acc[v][j] = _mm512_fmadd_pd(av[v], bv, acc[v][j]);
      tail[j] = T::fma(at, T::lanes(bv), tail[j]);
    }
  }
  if (out != nullptr) {
#pragma GCC unroll 8
    for (int j = 0; j < NC; ++j) {
#pragma GCC unroll 4
      for (int v = 0; v < F; ++v) _mm512_storeu_pd(out + i0 + 8 * v + (j0 + j) * ldo, acc[v][j]);
      T::store(out + it + (j0 + j) * ldo, last, tail[j]);
    }
    return;
  }
#pragma GCC unroll 8
  for (int j = 0; j < NC; ++j) {
    const __m512d hv = _mm512_set1_pd(p.mode == Epilogue::kAddScaled ? p.h[j0 + j] : 0.0);
    double* col = p.c + (j0 + j) * p.ldc;
#pragma GCC unroll 4
    for (int v = 0; v < F; ++v) finish<Zmm>(p, col + i0 + 8 * v, kAll, acc[v][j], hv);
    finish<T>(p, col + it, last, tail[j], T::lanes(hv));
  }
}

using TileFn = void (*)(const FmaArgs&, Index, Index, __mmask8, Index, Index, const double*, Index,
                        double*, Index);

template <int MV, typename T, int... NC>
constexpr std::array<TileFn, kCols> tiles_of(std::integer_sequence<int, NC...>) {
  return {tile<MV, NC + 1, T>...};
}

template <typename T>
constexpr std::array<std::array<TileFn, kCols>, kVecs> tiles_with() {
  return {tiles_of<1, T>(std::make_integer_sequence<int, kCols>{}),
          tiles_of<2, T>(std::make_integer_sequence<int, kCols>{}),
          tiles_of<3, T>(std::make_integer_sequence<int, kCols>{})};
}

// kTiles[last vector: zmm, ymm, xmm][MV − 1][NC − 1].
constexpr std::array<std::array<std::array<TileFn, kCols>, kVecs>, 3> kTiles = {
    tiles_with<Zmm>(), tiles_with<Ymm>(), tiles_with<Xmm>()};

}  // namespace

void fma_product_avx512(const FmaArgs& p, Index k0, Index k1, const double* in, Index ldi,
                        double* out, Index ldo) {
  const Index vecs = (p.m + 7) / 8;
  const int last_rows = static_cast<int>(p.m - 8 * (vecs - 1));
  const auto last = static_cast<__mmask8>((1u << last_rows) - 1u);
  // The last row group's last vector: a ymm for 4 rows, an xmm for 2, else a masked zmm.
  const std::size_t last_kind = last_rows == 4 ? 1 : last_rows == 2 ? 2 : 0;
  for (Index j0 = 0; j0 < p.n; j0 += kCols) {
    const auto nc = static_cast<std::size_t>(p.n - j0 < kCols ? p.n - j0 : kCols);
    for (Index v0 = 0; v0 < vecs;) {
      // Groups of 3 vectors, a rest of 4 as 2 + 2 (never a lone vector after full groups).
      const Index left = vecs - v0;
      const int mv = left == 4 ? 2 : left >= 3 ? 3 : static_cast<int>(left);
      const bool at_end = v0 + mv == vecs;
      kTiles[at_end ? last_kind : 0][static_cast<std::size_t>(mv - 1)][nc - 1](
          p, 8 * v0, j0, at_end ? last : __mmask8{0xFF}, k0, k1, in, ldi, out, ldo);
      v0 += mv;
    }
  }
}

}  // namespace csympnet::kernels

#endif  // CSYMPNET_FMA_KERNELS
