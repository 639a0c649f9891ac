// Internal to d1_forward_avx512.cpp and d1_backward_avx512.cpp (include after sse2_order.hpp):
// what the d = 1 forward and backward sweeps share: θ's layout, and the block of samples a sweep
// holds in registers with its steps.
#pragma once

#include "d1_sweeps.hpp"

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace csympnet::kernels::d1_block {

inline Index module_offset(const D1Core& c, Index k) {
  return k * (c.sublayers + 3);
}
inline Index shear_coef(const D1Core& c, Index k, Index i) {
  return c.coef0 + k * c.sublayers + i;
}
inline Index act_coef(const D1Core& c, Index k) {
  return c.coef0 + c.layers * c.sublayers + k;
}
inline Index n_units(const D1Core& c) {
  return c.layers * c.sublayers + c.layers - 1;
}

// The rows of a block live in arrays of kR registers (8 samples each) that are only ever
// indexed by constants (every loop over them unrolled, src and dst chosen by a branch, not a
// pointer), so that the compiler keeps them in registers.
template <int kR>
using Regs = __m512d[kR];

// The samples [j0, j0 + cnt) of one block (cnt ≤ 8 kR): which lanes are live, and the steps h,
// held in registers through the sweep. A full block (kFull) uses plain loads and stores, which
// fold into the arithmetic; kPoly: step_terms = 2.
template <int kR, bool kFull, bool kPoly>
struct Block {
  __mmask8 m[kR];
  __m512d h[kR];
  __attribute__((target("avx512f,avx512vl"), always_inline))
  Block(const double* h_row, Index j0, Index cnt) {
#pragma GCC unroll 16
    for (int r = 0; r < kR; ++r) {
      const Index live = cnt - 8 * r;
      m[r] = live >= 8   ? __mmask8{0xFF}
             : live <= 0 ? __mmask8{0}
                         : static_cast<__mmask8>((1u << live) - 1u);
      h[r] = kFull ? _mm512_loadu_pd(h_row + j0 + 8 * r)
                   : _mm512_maskz_loadu_pd(m[r], h_row + j0 + 8 * r);
    }
  }
};

template <int kR, bool kFull, bool kPoly>
__attribute__((target("avx512f,avx512vl"), always_inline)) inline __m512d load(
    const Block<kR, kFull, kPoly>& b, int r, const double* x) {
  if constexpr (kFull) {
    return _mm512_loadu_pd(x + 8 * r);
  } else {
    return _mm512_maskz_loadu_pd(b.m[r], x + 8 * r);
  }
}

template <int kR, bool kFull, bool kPoly>
__attribute__((target("avx512f,avx512vl"), always_inline)) inline void store(
    const Block<kR, kFull, kPoly>& b, int r, double* x, __m512d v) {
  if constexpr (kFull) {
    _mm512_storeu_pd(x + 8 * r, v);
  } else {
    _mm512_mask_storeu_pd(x + 8 * r, b.m[r], v);
  }
}

// The unit's step for register r: h itself, or τ = h (1 + c h) as unit_step() evaluates it.
template <int kR, bool kFull, bool kPoly>
__attribute__((target("avx512f,avx512vl"), always_inline)) inline __m512d step(
    const Block<kR, kFull, kPoly>& b, int r, __m512d c) {
  if constexpr (kPoly) {
    return _mm512_mul_pd(b.h[r], _mm512_add_pd(_mm512_set1_pd(1.0), _mm512_mul_pd(c, b.h[r])));
  } else {
    return b.h[r];
  }
}

}  // namespace csympnet::kernels::d1_block

#endif
