// The AVX-512 d = 1 LA-SympNet forward sweep of d1_sweeps.hpp (the backward sweep is
// d1_backward_avx512.cpp).
//
// Samples go in blocks of 80 (ten registers per row; one s1 batch): the block's q, p and steps
// h stay in registers through every unit, so a unit costs its arithmetic and the recording of
// one row. σ is computed in registers too (activation_forward). Blocks run last to first: the
// backward sweep reads the records first to last, so what it reads first was written last and
// is more likely still in the L1 cache.
#include "d1_sweeps.hpp"

#include "registry.hpp"
#include "sigmoid.hpp"

#include "sse2_order.hpp"

#include "d1_block.hpp"  // after sse2_order.hpp, whose CSYMPNET_SSE2_ORDER_KERNELS it needs

namespace csympnet::kernels {

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace {

using namespace d1_block;

constexpr int kRegs = 10;            // registers per row
constexpr Index kBlock = 8 * kRegs;  // samples per block

// Linear sublayer, forward: dst += (S src) τ, recording src at rec (when not null).
template <bool kFull, bool kPoly>
__attribute__((target("avx512f,avx512vl"), always_inline)) inline void shear_forward(
    const Block<kRegs, kFull, kPoly>& b, const Regs<kRegs>& src, Regs<kRegs>& dst, double s_value,
    __m512d c, double* rec) {
  if (rec != nullptr) {
#pragma GCC unroll 16
    for (int r = 0; r < kRegs; ++r) store(b, r, rec, src[r]);
  }
  const __m512d s = _mm512_set1_pd(s_value);
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) {
    dst[r] = _mm512_add_pd(dst[r], _mm512_mul_pd(_mm512_mul_pd(s, src[r]), step(b, r, c)));
  }
}

// σ of the 8 samples of src at sig, by sigmoid_simd: lanes whose −|x| is below −700 or NaN,
// which its kernel hands to Eigen's routine. Out of line and cold, so that the sweep's registers
// are saved around the call only here.
__attribute__((noinline, cold)) void sigmoid_group(const double* src, double* sig) {
  sigmoid_kernel(src, sig, 8);
}

// Activation module, forward: dst += (σ(src) a) τ, σ written to sig (cnt values). σ of a block
// is σ of those samples of the row: blocks start at even samples and only the last can end at
// an odd one, so sigmoid_simd treats every sample as it does in one call on the whole row. In a
// full block, σ is computed in registers with sigmoid_simd's kernel's operations, group of 8 by
// group of 8 as that kernel does (e = exp(−|x|) by cephes_exp512, σ = n / (1 + e) with n = 1
// for x ≥ 0, e otherwise); a group with a lane that kernel would hand to Eigen goes to
// sigmoid_simd itself.
template <bool kFull, bool kPoly>
__attribute__((target("avx512f,avx512vl"), always_inline)) inline void activation_forward(
    const Block<kRegs, kFull, kPoly>& b, Index cnt, const Regs<kRegs>& src, Regs<kRegs>& dst,
    double a_value, __m512d c, double* sig) {
  const __m512d a = _mm512_set1_pd(a_value);
  if constexpr (kFull) {
    const __m512d one = _mm512_set1_pd(1.0);
    const __m512i sign = _mm512_set1_epi64(static_cast<long long>(0x8000000000000000ULL));
#pragma GCC unroll 16
    for (int r = 0; r < kRegs; ++r) {
      const __m512d v = _mm512_castsi512_pd(_mm512_or_si512(_mm512_castpd_si512(src[r]), sign));
      __m512d s;
      if (_mm512_cmp_pd_mask(v, _mm512_set1_pd(-700.0), _CMP_GE_OQ) == 0xFF) {
        const __m512d e = cephes_exp512(v);
        const __mmask8 nonneg = _mm512_cmp_pd_mask(src[r], _mm512_setzero_pd(), _CMP_GE_OQ);
        s = _mm512_div_pd(_mm512_mask_blend_pd(nonneg, e, one), _mm512_add_pd(one, e));
        _mm512_storeu_pd(sig + 8 * r, s);
      } else {
        alignas(64) double x[8];
        _mm512_store_pd(x, src[r]);
        sigmoid_group(x, sig + 8 * r);
        s = _mm512_loadu_pd(sig + 8 * r);
      }
      dst[r] = _mm512_add_pd(dst[r], _mm512_mul_pd(_mm512_mul_pd(s, a), step(b, r, c)));
    }
  } else {
    alignas(64) double src_buf[kBlock];
#pragma GCC unroll 16
    for (int r = 0; r < kRegs; ++r) _mm512_store_pd(src_buf + 8 * r, src[r]);
    sigmoid_kernel(src_buf, sig, cnt);
#pragma GCC unroll 16
    for (int r = 0; r < kRegs; ++r) {
      dst[r] =
          _mm512_add_pd(dst[r], _mm512_mul_pd(_mm512_mul_pd(load(b, r, sig), a), step(b, r, c)));
    }
  }
}

// One block of d1_flow_simd(): samples [j0, j0 + cnt) of q, p; rec (null: nothing
// recorded) holds the record rows of every unit.
template <bool kFull, bool kPoly>
__attribute__((target("avx512f,avx512vl"))) void flow_block(const D1Core& core, const double* theta,
                                                            double* q_row, double* p_row,
                                                            const double* h_row, Index j0,
                                                            Index cnt, double* const* rec) {
  const Block<kRegs, kFull, kPoly> b(h_row, j0, cnt);
  Regs<kRegs> q, p;
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) {
    q[r] = load(b, r, q_row + j0);
    p[r] = load(b, r, p_row + j0);
  }
  alignas(64) double sig_buf[kBlock];
  const __m512d zero = _mm512_setzero_pd();
  auto record = [&]() { return rec != nullptr ? *rec++ + j0 : nullptr; };
  const Index m = core.sublayers;
  for (Index k = 0; k < core.layers; ++k) {
    const Index off = module_offset(core, k);
    for (Index i = 0; i < m; ++i) {
      const double s = theta[off + i] + theta[off + i];  // S = 2A
      const __m512d c = kPoly ? _mm512_set1_pd(theta[shear_coef(core, k, i)]) : zero;
      if (i % 2 == 0) {
        shear_forward(b, q, p, s, c, record());  // kick p += (S q) τ
      } else {
        shear_forward(b, p, q, s, c, record());  // drift q += (S p) τ
      }
    }
    // p += h b_p, q += h b_q.
    const __m512d bp = _mm512_set1_pd(theta[off + m]);
    const __m512d bq = _mm512_set1_pd(theta[off + m + 1]);
#pragma GCC unroll 16
    for (int r = 0; r < kRegs; ++r) {
      p[r] = _mm512_add_pd(p[r], _mm512_mul_pd(b.h[r], bp));
      q[r] = _mm512_add_pd(q[r], _mm512_mul_pd(b.h[r], bq));
    }
    if (k + 1 < core.layers) {
      const double a = theta[off + m + 2];
      const __m512d c = kPoly ? _mm512_set1_pd(theta[act_coef(core, k)]) : zero;
      double* sig = rec != nullptr ? record() : sig_buf;
      if (k % 2 == 0) {
        activation_forward(b, cnt, q, p, a, c, sig);  // kick p += (σ(q) a) τ
      } else {
        activation_forward(b, cnt, p, q, a, c, sig);  // drift q += (σ(p) a) τ
      }
    }
  }
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) {
    store(b, r, q_row + j0, q[r]);
    store(b, r, p_row + j0, p[r]);
  }
}

}  // namespace

bool d1_flow_simd(const D1Core& core, const double* theta, double* q, double* p, const double* h,
                  Index n, Matrix* steps) {
  if (n < 1) return false;
  if (use(Family::kD1Sweeps)) return d1_flow_kernel(core, theta, q, p, h, n, steps);
  if (use(Family::kD1SweepsAvx2)) return d1_flow_kernel_avx2(core, theta, q, p, h, n, steps);
  return false;
}

bool d1_flow_kernel(const D1Core& core, const double* theta, double* q, double* p, const double* h,
                    Index n, Matrix* steps) {
  if (n < 1) return false;
  RecordRows rows(steps != nullptr ? n_units(core) : 0);
  double* const* rec = rows.gather(steps, n_units(core), n);
  for (Index j0 = (n - 1) / kBlock * kBlock; j0 >= 0; j0 -= kBlock) {
    const Index cnt = n - j0 < kBlock ? n - j0 : kBlock;
    auto run = [&](auto block) { block(core, theta, q, p, h, j0, cnt, rec); };
    if (cnt == kBlock) {
      core.poly ? run(flow_block<true, true>) : run(flow_block<true, false>);
    } else {
      core.poly ? run(flow_block<false, true>) : run(flow_block<false, false>);
    }
  }
  return true;
}

#else

bool d1_flow_simd(const D1Core&, const double*, double*, double*, const double*, Index, Matrix*) {
  return false;
}

bool d1_flow_kernel(const D1Core&, const double*, double*, double*, const double*, Index, Matrix*) {
  return false;
}

#endif

}  // namespace csympnet::kernels
