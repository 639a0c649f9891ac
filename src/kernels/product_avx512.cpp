// The AVX-512 kernel of the SSE2-order products (product_targets.hpp): every entry in
// the order stated at the top of product.cpp, with the register tiles of
// product_tiles512.hpp.
//
// The columns are swept in panels of 16 (then one each of 12, 10, 8, 6, 4, 2, 1 for the rest,
// so that every tile keeps several sums in flight). Within a panel, every 8-row block of the
// main rows (and a 4-row rest in 256-bit registers) runs over the same columns of B, which
// stay in L1. The two tail rows of an m ≡ 2 (mod 4) product, in Eigen's 4-column blocks:
//   * B stored by rows (the gradients' (G H) Xᵀ): row vectors of B, 8 columns of one tail row
//     per register, riding along in the last main block's loop;
//   * B stored by columns: the last main block copies the panel's B in pairs of l (loads and
//     stores, no pipe slots), from which the tail rows run 4 columns x 2 sums per register;
//   * where no copy fits (k > kMaxCopyK) or no main rows exist (m = 2): a pass of their own,
//     the two rows of one column per 128-bit register, as Eigen holds them.
// Each way fills all 8 lanes, where a 128-bit register per column costs a 512-bit operation's
// pipe slot for a quarter of the entries. The last n mod 4 columns' tail rows (one running sum
// each) ride along in the last main block in 128-bit registers.
#include "sse2_order.hpp"
//
#include "product_tiles512.hpp"

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace csympnet::kernels {

namespace {

using tiles512::BLayout;
using tiles512::main_tile;
using tiles512::tail_tile128;
using tiles512::tail_tile_pairs;

#define CSYMPNET_AVX512_OUTLINE __attribute__((target("avx512f"), noinline))

constexpr int kPanel = 16;        // columns per panel: 16 sums and a row register (of 32)
constexpr Index kMaxCopyK = 128;  // the tail rows copy at most (64 + 7) x 32 doubles of B

// Where the tail rows come from in a panel sweep.
enum class Tail {
  kNone,  // no tail rows, or a pass of their own
  kCopy,  // the panel's copy of B (B stored by columns)
  kRows,  // B itself (stored by rows)
};

// `tiles` panels of NC columns from column j0: all main rows, then (T ≠ kNone) the tail rows.
// Every panel but the last one or two lies before 4⌊n/4⌋ (sweep's split of the rest), so a
// panel's tail columns are NP = NC − NC mod 4 in Eigen's 4-column blocks, then NC mod 4 after.
template <int NC, BLayout L, Tail T>
CSYMPNET_AVX512_OUTLINE void panels(const ProductArgs& p, Index j0, Index tiles, double* copy,
                                    const double* tail_a) {
  constexpr int NR = T == Tail::kNone ? 0 : NC % 4;
  constexpr int NP = NC - NC % 4;
  constexpr bool kCopy = T == Tail::kCopy && NP > 0;
  constexpr int NP8 = T == Tail::kRows ? NP / 8 : 0;  // 8-column chunks riding along
  const Index m4 = p.m & ~Index{3};
  const Index blocks8 = m4 / 8;
  const bool has4 = m4 % 8 == 4;
  const Index k = p.k, lda = p.lda, bl = p.bl, bj = p.bj, ldc = p.ldc;
  const Epilogue mode = p.mode;
  const double* at = p.a + m4;
  for (Index t = 0; t < tiles; ++t) {
    const Index j = j0 + t * NC;
    const double* b = p.b + j * bj;
    double* c = p.c + j * ldc;
    double* ct = c + m4;
    const double* h = p.h + j;
    // The last main block carries the tail's running columns and makes the copy.
    const Index plain8 = T != Tail::kNone && !has4 ? blocks8 - 1 : blocks8;
    for (Index ib = 0; ib < plain8; ++ib) {
      main_tile<__m512d, NC, L, false, 0, 0>(k, p.a + 8 * ib, lda, b, bl, bj, c + 8 * ib, ldc, mode,
                                             h, nullptr, nullptr, nullptr);
    }
    if constexpr (T != Tail::kNone) {
      if (!has4) {
        const Index i = 8 * plain8;
        main_tile<__m512d, NC, L, kCopy, NR, NP8>(k, p.a + i, lda, b, bl, bj, c + i, ldc, mode, h,
                                                  copy, at, ct);
      }
    }
    if (has4) {
      const Index i = 8 * blocks8;
      main_tile<__m256d, NC, L, kCopy, NR, NP8>(k, p.a + i, lda, b, bl, bj, c + i, ldc, mode, h,
                                                copy, at, ct);
    }
    if constexpr (T == Tail::kCopy && NP > 0) {
      tail_tile_pairs<NP / 4>(k, tail_a, copy, ct, ldc, mode, h);
    } else if constexpr (T == Tail::kRows && NP % 8 == 4) {  // 4 columns left by the chunks
      constexpr int q = NP - 4;
      tail_tile128<4, true, BLayout::kRows>(k, at, lda, b + q, bl, 1, ct + q * ldc, ldc, mode,
                                            h + q);
    }
  }
}

// All n columns: panels of 16, then one narrower panel per width of the rest's greedy split.
template <BLayout L, Tail T>
void sweep(const ProductArgs& p, double* copy = nullptr, const double* tail_a = nullptr) {
  const Index full = p.n / kPanel;
  if (full > 0) panels<kPanel, L, T>(p, 0, full, copy, tail_a);
  Index j = full * kPanel;
  const auto rest = [&](Index w) { return p.n - j >= w; };
  if (rest(12)) panels<12, L, T>(p, j, 1, copy, tail_a), j += 12;
  if (rest(10)) panels<10, L, T>(p, j, 1, copy, tail_a), j += 10;
  if (rest(8)) panels<8, L, T>(p, j, 1, copy, tail_a), j += 8;
  if (rest(6)) panels<6, L, T>(p, j, 1, copy, tail_a), j += 6;
  if (rest(4)) panels<4, L, T>(p, j, 1, copy, tail_a), j += 4;
  if (rest(2)) panels<2, L, T>(p, j, 1, copy, tail_a), j += 2;
  if (rest(1)) panels<1, L, T>(p, j, 1, copy, tail_a);
}

// The tail rows alone (m = 2, or B stored by columns with k > kMaxCopyK), one column per
// 128-bit register: tiles of 8 and 4 columns in Eigen's 4-column blocks, then the last n mod 4.
template <int NC, bool kPairs, BLayout L>
CSYMPNET_AVX512_OUTLINE void tail_columns(const ProductArgs& p, Index j0, Index tiles) {
  const Index m4 = p.m - 2;
  const Index step = L == BLayout::kCols ? p.bj : 1;
  for (Index t = 0; t < tiles; ++t) {
    const Index j = j0 + t * NC;
    tail_tile128<NC, kPairs, L>(p.k, p.a + m4, p.lda, p.b + j * step, p.bl, p.bj,
                                p.c + m4 + j * p.ldc, p.ldc, p.mode, p.h + j);
  }
}

template <BLayout L>
void tail_pass(const ProductArgs& p) {
  const Index n4 = p.n & ~Index{3};
  if (n4 >= 8) tail_columns<8, true, L>(p, 0, n4 / 8);
  if (n4 % 8 == 4) tail_columns<4, true, L>(p, n4 - 4, 1);
  const Index rest = p.n - n4;
  if (rest == 3) tail_columns<3, false, L>(p, n4, 1);
  if (rest == 2) tail_columns<2, false, L>(p, n4, 1);
  if (rest == 1) tail_columns<1, false, L>(p, n4, 1);
}

}  // namespace

void product_avx512(const ProductArgs& p) {
  const Index m4 = p.m & ~Index{3};
  const bool tail = p.m - m4 == 2;
  const bool by_rows = p.bl != 1;  // else bj = 1: sse2_order_product() hands no other layout
  if (tail && m4 == 0) {
    if (by_rows) {
      tail_pass<BLayout::kRows>(p);
    } else {
      tail_pass<BLayout::kCols>(p);
    }
  } else if (by_rows) {
    if (tail) {
      sweep<BLayout::kRows, Tail::kRows>(p);
    } else {
      sweep<BLayout::kRows, Tail::kNone>(p);
    }
  } else if (tail && p.k <= kMaxCopyK) {
    alignas(64) double copy[(kMaxCopyK / 2 + 7) * 2 * kPanel];  // l-pairs below k8, then l
    alignas(64) double tail_a[(kMaxCopyK + 7) * 8];
    tiles512::pack_tail_a(p.k, p.a + m4, p.lda, tail_a);
    sweep<BLayout::kCols, Tail::kCopy>(p, copy, tail_a);
  } else {
    sweep<BLayout::kCols, Tail::kNone>(p);
    if (tail) tail_pass<BLayout::kCols>(p);
  }
}

}  // namespace csympnet::kernels

#endif  // CSYMPNET_SSE2_ORDER_KERNELS
