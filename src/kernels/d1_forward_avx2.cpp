// The AVX2 d = 1 LA-SympNet forward sweep of d1_sweeps.hpp, for machines without AVX-512: the
// operations of d1_forward_avx512.cpp, in its order, four samples per register.
//
// Samples go in blocks of 20 (five registers per row; 80, s1's batch, is four blocks): with
// sixteen registers, the block's q and p take ten, and the rest hold a unit's temporaries (the
// steps are read from memory, where the AVX-512 sweep holds them). σ is computed in registers as
// sigmoid_avx2.cpp computes it. Blocks run last to first, as in the AVX-512 sweep.
#include "d1_sweeps.hpp"

#include "registry.hpp"
#include "sigmoid.hpp"

#include "sse2_order.hpp"

#include "d1_block.hpp"  // after sse2_order.hpp, whose CSYMPNET_SSE2_ORDER_KERNELS it needs

namespace csympnet::kernels {

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace {

using namespace d1_block;

constexpr int kRegs = 5;             // registers per row
constexpr Index kBlock = 4 * kRegs;  // samples per block (even: see activation_forward)

template <bool kFull, bool kPoly>
using BlockOf = Block256<kRegs, kFull, kPoly>;
using Row = __m256d[kRegs];

// Linear sublayer, forward: dst += (S src) τ, recording src at rec (when not null).
template <bool kFull, bool kPoly>
__attribute__((target("avx2"), always_inline)) inline void shear_forward(
    const BlockOf<kFull, kPoly>& b, const Row& src, Row& dst, double s_value, __m256d c,
    double* rec) {
  if (rec != nullptr) {
#pragma GCC unroll 16
    for (int r = 0; r < kRegs; ++r) store(b, r, rec, src[r]);
  }
  const __m256d s = _mm256_set1_pd(s_value);
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) {
    dst[r] = _mm256_add_pd(dst[r], _mm256_mul_pd(_mm256_mul_pd(s, src[r]), step(b, r, c)));
  }
}

// σ of the 4 samples of src at sig by the AVX2 sigmoid kernel: a group with a lane it hands to
// Eigen. Out of line and cold, as in the AVX-512 sweep.
__attribute__((noinline, cold)) void sigmoid_group(const double* src, double* sig) {
  sigmoid_kernel_avx2(src, sig, 4);
}

// Activation module, forward: dst += (σ(src) a) τ, σ written to sig (cnt values). Blocks start
// at even samples and only the last can end at an odd one, so σ of a block is σ of those samples
// of the row (as in the AVX-512 sweep); in a full block group of 4 by group of 4, as the AVX2
// sigmoid kernel does.
template <bool kFull, bool kPoly>
__attribute__((target("avx2"), always_inline)) inline void activation_forward(
    const BlockOf<kFull, kPoly>& b, Index cnt, const Row& src, Row& dst, double a_value, __m256d c,
    double* sig) {
  const __m256d a = _mm256_set1_pd(a_value);
  if constexpr (kFull) {
    const __m256d one = _mm256_set1_pd(1.0);
    const __m256d sign = _mm256_set1_pd(-0.0);
#pragma GCC unroll 16
    for (int r = 0; r < kRegs; ++r) {
      const __m256d v = _mm256_or_pd(src[r], sign);  // −|x|
      __m256d s;
      if (_mm256_movemask_pd(_mm256_cmp_pd(v, _mm256_set1_pd(-700.0), _CMP_GE_OQ)) == 0xF) {
        const __m256d e = cephes_exp256(v);
        const __m256d nonneg = _mm256_cmp_pd(src[r], _mm256_setzero_pd(), _CMP_GE_OQ);
        s = _mm256_div_pd(_mm256_blendv_pd(e, one, nonneg), _mm256_add_pd(one, e));
        _mm256_storeu_pd(sig + 4 * r, s);
      } else {
        alignas(32) double x[4];
        _mm256_store_pd(x, src[r]);
        sigmoid_group(x, sig + 4 * r);
        s = _mm256_loadu_pd(sig + 4 * r);
      }
      dst[r] = _mm256_add_pd(dst[r], _mm256_mul_pd(_mm256_mul_pd(s, a), step(b, r, c)));
    }
  } else {
    alignas(32) double src_buf[kBlock];
#pragma GCC unroll 16
    for (int r = 0; r < kRegs; ++r) _mm256_store_pd(src_buf + 4 * r, src[r]);
    sigmoid_kernel_avx2(src_buf, sig, cnt);
#pragma GCC unroll 16
    for (int r = 0; r < kRegs; ++r) {
      dst[r] =
          _mm256_add_pd(dst[r], _mm256_mul_pd(_mm256_mul_pd(load(b, r, sig), a), step(b, r, c)));
    }
  }
}

// One block of the sweep: samples [j0, j0 + cnt) of q, p; rec (null: nothing recorded) holds
// the record rows of every unit.
template <bool kFull, bool kPoly>
__attribute__((target("avx2"))) void flow_block(const D1Core& core, const double* theta,
                                                double* q_row, double* p_row, const double* h_row,
                                                Index j0, Index cnt, double* const* rec) {
  const BlockOf<kFull, kPoly> b(h_row, j0, cnt);
  Row q, p;
#pragma GCC unroll 16
  for (int r = 0; r < kRegs; ++r) {
    q[r] = load(b, r, q_row + j0);
    p[r] = load(b, r, p_row + j0);
  }
  alignas(32) double sig_buf[kBlock];
  const __m256d zero = _mm256_setzero_pd();
  auto record = [&]() { return rec != nullptr ? *rec++ + j0 : nullptr; };
  const Index m = core.sublayers;
  for (Index k = 0; k < core.layers; ++k) {
    const Index off = module_offset(core, k);
    for (Index i = 0; i < m; ++i) {
      const double s = theta[off + i] + theta[off + i];  // S = 2A
      const __m256d c = kPoly ? _mm256_set1_pd(theta[shear_coef(core, k, i)]) : zero;
      if (i % 2 == 0) {
        shear_forward(b, q, p, s, c, record());  // kick p += (S q) τ
      } else {
        shear_forward(b, p, q, s, c, record());  // drift q += (S p) τ
      }
    }
    // p += h b_p, q += h b_q.
    const __m256d bp = _mm256_set1_pd(theta[off + m]);
    const __m256d bq = _mm256_set1_pd(theta[off + m + 1]);
#pragma GCC unroll 16
    for (int r = 0; r < kRegs; ++r) {
      const __m256d h = steps(b, r);
      p[r] = _mm256_add_pd(p[r], _mm256_mul_pd(h, bp));
      q[r] = _mm256_add_pd(q[r], _mm256_mul_pd(h, bq));
    }
    if (k + 1 < core.layers) {
      const double a = theta[off + m + 2];
      const __m256d c = kPoly ? _mm256_set1_pd(theta[act_coef(core, k)]) : zero;
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

bool d1_flow_kernel_avx2(const D1Core& core, const double* theta, double* q, double* p,
                         const double* h, Index n, Matrix* steps) {
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

bool d1_flow_kernel_avx2(const D1Core&, const double*, double*, double*, const double*, Index,
                         Matrix*) {
  return false;
}

#endif

}  // namespace csympnet::kernels
