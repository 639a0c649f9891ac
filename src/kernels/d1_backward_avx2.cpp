// The AVX2 d = 1 LA-SympNet backward sweep of d1_sweeps.hpp, for machines without AVX-512: the
// operations of d1_backward_avx512.cpp, in its order, four samples per register, and the
// parameter gradients' running sums in ColumnSums' AVX2 form (the same order).
//
// Samples go in blocks of 20 (kColumnSumsBlockAvx2, the sums' row): five registers per row, so
// that the gradients of q and p (ten registers) and a unit's temporaries fit AVX2's sixteen (in
// blocks of 40, as the AVX-512 sweep's, they spilled to the stack in every unit). The steps are
// read from memory.
#include "d1_sweeps.hpp"

#include "registry.hpp"

#include "sse2_order.hpp"

#include "d1_block.hpp"  // after sse2_order.hpp, whose CSYMPNET_SSE2_ORDER_KERNELS it needs

namespace csympnet::kernels {

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace {

using namespace d1_block;

constexpr Index kBlock = kColumnSumsBlockAvx2;       // samples per block
constexpr int kRegs = static_cast<int>(kBlock / 4);  // registers per row

template <bool kFull, bool kPoly>
using BlockOf = Block256<kRegs, kFull, kPoly>;
using Row = __m256d[kRegs];

// g_dst of a unit, kept for its step-polynomial coefficient (row not null).
template <bool kFull, bool kPoly>
__attribute__((target("avx2"), always_inline)) inline void keep(const BlockOf<kFull, kPoly>& b,
                                                                const Row& gdst, double* row) {
  if (row == nullptr) return;
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) store(b, r, row, gdst[r]);
}

// Linear sublayer, backward (dst += (S src) τ):  g = g_dst τ,  column += g src  (dA = 2 Σ),
// g_src += S g.
template <bool kFull, bool kPoly>
__attribute__((target("avx2"), always_inline)) inline void shear_backward(
    const BlockOf<kFull, kPoly>& b, Row& gsrc, const Row& gdst, double s_value, __m256d c,
    const double* src, double* col) {
  const __m256d s = _mm256_set1_pd(s_value);
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) {
    const __m256d g = _mm256_mul_pd(gdst[r], step(b, r, c));
    _mm256_store_pd(col + 4 * r, _mm256_mul_pd(g, load(b, r, src)));
    gsrc[r] = _mm256_add_pd(gsrc[r], _mm256_mul_pd(s, g));
  }
}

// Activation module, backward (dst += (σ a) τ):  g = g_dst τ,  column += g σ  (da = Σ),
// g_src += ((g σ)(1 − σ)) a.
template <bool kFull, bool kPoly>
__attribute__((target("avx2"), always_inline)) inline void activation_backward(
    const BlockOf<kFull, kPoly>& b, Row& gsrc, const Row& gdst, double a_value, __m256d c,
    const double* sig, double* col) {
  const __m256d a = _mm256_set1_pd(a_value);
  const __m256d one = _mm256_set1_pd(1.0);
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) {
    const __m256d g = _mm256_mul_pd(gdst[r], step(b, r, c));
    const __m256d s = load(b, r, sig);
    const __m256d gs = _mm256_mul_pd(g, s);
    _mm256_store_pd(col + 4 * r, gs);
    gsrc[r] = _mm256_add_pd(gsrc[r], _mm256_mul_pd(_mm256_mul_pd(gs, _mm256_sub_pd(one, s)), a));
  }
}

// One block of d1_backward_simd()'s sweep: samples [j0, j0 + cnt) of gq, gp; the
// products of every gradient column for these samples go to their running sums.
template <bool kFull, bool kPoly>
__attribute__((target("avx2"))) void backward_block(const D1Core& core, const double* theta,
                                                    const Matrix* rec, const double* h_row,
                                                    Index j0, Index cnt, double* gq_row,
                                                    double* gp_row, BackwardScratch& scratch) {
  const BlockOf<kFull, kPoly> b(h_row, j0, cnt);
  Row gq, gp;
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) {
    gq[r] = load(b, r, gq_row + j0);
    gp[r] = load(b, r, gp_row + j0);
  }
  const __m256d zero = _mm256_setzero_pd();
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
      const __m256d c = kPoly ? _mm256_set1_pd(theta[act_coef(core, k)]) : zero;
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
        _mm256_store_pd(col + 4 * r, _mm256_mul_pd(bias_q ? gq[r] : gp[r], steps(b, r)));
      }
      scratch.sums.column_done(cnt);
    }
    for (Index i = m - 1; i >= 0; --i) {
      --unit;
      const double* src = rec[unit].data() + j0;
      const double s = theta[base + i] + theta[base + i];
      const __m256d c = kPoly ? _mm256_set1_pd(theta[shear_coef(core, k, i)]) : zero;
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

bool d1_backward_kernel_avx2(const D1Core& core, const double* theta, const Matrix* steps,
                             const double* h, Index n, double* gq, double* gp, double* grad) {
  if (n < 1) return false;
  BackwardScratch scratch(core, n, ColumnSums::Isa::kAvx2);
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

bool d1_backward_kernel_avx2(const D1Core&, const double*, const Matrix*, const double*, Index,
                             double*, double*, double*) {
  return false;
}

#endif

}  // namespace csympnet::kernels
