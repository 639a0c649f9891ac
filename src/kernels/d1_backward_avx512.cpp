// The AVX-512 d = 1 LA-SympNet backward sweep of d1_sweeps.hpp.
//
// Samples go in blocks of 40 (five registers per row): the block's gradients of q and p and its
// steps h stay in registers through every unit. Blocks run first to last, since the parameter
// gradients' running sums (column_sums.hpp) continue from one block to the next in sample order.
// Forty rather than eighty samples: with h in registers too, eighty would not fit the 32
// registers, and the sums' buffer of 48 columns of 40 stays in the L1 cache.
#include "d1_sweeps.hpp"

#include "registry.hpp"

#include "sse2_order.hpp"

#include "d1_block.hpp"  // after sse2_order.hpp, whose CSYMPNET_SSE2_ORDER_KERNELS it needs

namespace csympnet::kernels {

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace {

using namespace d1_block;

constexpr Index kBlock = kColumnSumsBlock;           // samples per block
constexpr int kRegs = static_cast<int>(kBlock / 8);  // registers per row

template <bool kFull, bool kPoly>
using BlockOf = Block<kRegs, kFull, kPoly>;

// g_dst of a unit, kept for its step-polynomial coefficient (row not null).
template <bool kFull, bool kPoly>
__attribute__((target("avx512f,avx512vl"), always_inline)) inline void keep(
    const BlockOf<kFull, kPoly>& b, const Regs<kRegs>& gdst, double* row) {
  if (row == nullptr) return;
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) store(b, r, row, gdst[r]);
}

// Linear sublayer, backward (dst += (S src) τ):  g = g_dst τ,  column += g src  (dA = 2 Σ),
// g_src += S g.
template <bool kFull, bool kPoly>
__attribute__((target("avx512f,avx512vl"), always_inline)) inline void shear_backward(
    const BlockOf<kFull, kPoly>& b, Regs<kRegs>& gsrc, const Regs<kRegs>& gdst, double s_value,
    __m512d c, const double* src, double* col) {
  const __m512d s = _mm512_set1_pd(s_value);
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) {
    const __m512d g = _mm512_mul_pd(gdst[r], step(b, r, c));
    _mm512_store_pd(col + 8 * r, _mm512_mul_pd(g, load(b, r, src)));
    gsrc[r] = _mm512_add_pd(gsrc[r], _mm512_mul_pd(s, g));
  }
}

// Activation module, backward (dst += (σ a) τ):  g = g_dst τ,  column += g σ  (da = Σ),
// g_src += ((g σ)(1 − σ)) a.
template <bool kFull, bool kPoly>
__attribute__((target("avx512f,avx512vl"), always_inline)) inline void activation_backward(
    const BlockOf<kFull, kPoly>& b, Regs<kRegs>& gsrc, const Regs<kRegs>& gdst, double a_value,
    __m512d c, const double* sig, double* col) {
  const __m512d a = _mm512_set1_pd(a_value);
  const __m512d one = _mm512_set1_pd(1.0);
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) {
    const __m512d g = _mm512_mul_pd(gdst[r], step(b, r, c));
    const __m512d s = load(b, r, sig);
    const __m512d gs = _mm512_mul_pd(g, s);
    _mm512_store_pd(col + 8 * r, gs);
    gsrc[r] = _mm512_add_pd(gsrc[r], _mm512_mul_pd(_mm512_mul_pd(gs, _mm512_sub_pd(one, s)), a));
  }
}

// One block of d1_backward_simd()'s sweep: samples [j0, j0 + cnt) of gq, gp; the
// products of every gradient column for these samples go to their running sums.
template <bool kFull, bool kPoly>
__attribute__((target("avx512f,avx512vl"))) void backward_block(
    const D1Core& core, const double* theta, const Matrix* rec, const double* h_row, Index j0,
    Index cnt, double* gq_row, double* gp_row, BackwardScratch& scratch) {
  const BlockOf<kFull, kPoly> b(h_row, j0, cnt);
  Regs<kRegs> gq, gp;
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) {
    gq[r] = load(b, r, gq_row + j0);
    gp[r] = load(b, r, gp_row + j0);
  }
  const __m512d zero = _mm512_setzero_pd();
  const Index m = core.sublayers;
  Index unit = n_units(core);  // units counted in application order, as the recorded rows
  auto upstream_row = [&]() { return kPoly ? scratch.upstream + unit * scratch.ld + j0 : nullptr; };
  for (Index k = core.layers - 1; k >= 0; --k) {
    const Index base = module_offset(core, k);
    const Index bias = base + m;
    if (k + 1 < core.layers) {
      --unit;
      const double* sig = rec[unit].data() + j0;
      const double a = theta[bias + 2];
      const __m512d c = kPoly ? _mm512_set1_pd(theta[act_coef(core, k)]) : zero;
      if (k % 2 == 0) {
        keep(b, gp, upstream_row());
        activation_backward(b, gq, gp, a, c, sig, scratch.sums.next_column());
      } else {
        keep(b, gq, upstream_row());
        activation_backward(b, gp, gq, a, c, sig, scratch.sums.next_column());
      }
      scratch.sums.column_done(cnt);
    }
    // db_p = Σ_j g_p,j h_j, db_q = Σ_j g_q,j h_j.
#pragma GCC unroll 2
    for (int bias_q = 0; bias_q < 2; ++bias_q) {
      double* col = scratch.sums.next_column();
#pragma GCC unroll 16
      for (int r = 0; r < kRegs; ++r) {
        _mm512_store_pd(col + 8 * r, _mm512_mul_pd(bias_q ? gq[r] : gp[r], b.h[r]));
      }
      scratch.sums.column_done(cnt);
    }
    for (Index i = m - 1; i >= 0; --i) {
      --unit;
      const double* src = rec[unit].data() + j0;
      const double s = theta[base + i] + theta[base + i];
      const __m512d c = kPoly ? _mm512_set1_pd(theta[shear_coef(core, k, i)]) : zero;
      if (i % 2 == 0) {
        keep(b, gp, upstream_row());
        shear_backward(b, gq, gp, s, c, src, scratch.sums.next_column());  // kick: dst p, src q
      } else {
        keep(b, gq, upstream_row());
        shear_backward(b, gp, gq, s, c, src, scratch.sums.next_column());  // drift: dst q, src p
      }
      scratch.sums.column_done(cnt);
    }
  }
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) {
    store(b, r, gq_row + j0, gq[r]);
    store(b, r, gp_row + j0, gp[r]);
  }
}

}  // namespace

bool d1_backward_simd(const D1Core& core, const double* theta, const Matrix* steps, const double* h,
                      Index n, double* gq, double* gp, double* grad) {
  if (n < 1) return false;
  if (use(Family::kD1Sweeps)) return d1_backward_kernel(core, theta, steps, h, n, gq, gp, grad);
  if (use(Family::kD1SweepsAvx2)) {
    return d1_backward_kernel_avx2(core, theta, steps, h, n, gq, gp, grad);
  }
  return false;
}

bool d1_backward_kernel(const D1Core& core, const double* theta, const Matrix* steps,
                        const double* h, Index n, double* gq, double* gp, double* grad) {
  if (n < 1) return false;
  BackwardScratch scratch(core, n, ColumnSums::Isa::kAvx512);
  const Matrix* rec = steps;
  for (Index j0 = 0; j0 < n; j0 += kBlock) {
    const Index cnt = n - j0 < kBlock ? n - j0 : kBlock;
    auto run = [&](auto block) { block(core, theta, rec, h, j0, cnt, gq, gp, scratch); };
    if (cnt == kBlock) {
      core.poly ? run(backward_block<true, true>) : run(backward_block<true, false>);
    } else {
      core.poly ? run(backward_block<false, true>) : run(backward_block<false, false>);
    }
    scratch.sums.end_block(cnt);
  }
  add_parameter_gradients(core, theta, steps, h, n, scratch, grad);
  return true;
}

#else

bool d1_backward_simd(const D1Core&, const double*, const Matrix*, const double*, Index, double*,
                      double*, double*) {
  return false;
}

bool d1_backward_kernel(const D1Core&, const double*, const Matrix*, const double*, Index, double*,
                        double*, double*) {
  return false;
}

#endif

}  // namespace csympnet::kernels
