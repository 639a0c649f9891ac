// The AVX-512 d = 1 LA-SympNet sweeps of la_scalar_sweep.hpp.
//
// Samples go in blocks of kBlock = 80 (ten registers per row; one s1 batch): each block of q
// and p (forward) or of their gradients (backward) stays in registers through every unit, so
// a unit costs its arithmetic and the recording of one row, not loads and stores of q and p.
// Blocks are independent except for the parameter gradients' running sums (column_sums.hpp),
// which continue from one block to the next in sample order.
#include "la_scalar_sweep.hpp"

#include <memory>

#include "column_sums.hpp"
#include "csympnet/models/activation.hpp"

#include "exact_simd.hpp"

namespace csympnet::detail {

#ifdef CSYMPNET_EXACT_SIMD

namespace {

constexpr Index kBlock = kColumnSumsBlock;  // samples per block
constexpr Index kRegs = kBlock / 8;         // registers per row

using ConstRowMap = Eigen::Map<const RowVector>;

Index module_offset(const LaScalarCore& c, Index k) {
  return k * (c.sublayers + 3);
}
Index shear_coef(const LaScalarCore& c, Index k, Index i) {
  return c.coef0 + k * c.sublayers + i;
}
Index act_coef(const LaScalarCore& c, Index k) {
  return c.coef0 + c.layers * c.sublayers + k;
}
Index n_units(const LaScalarCore& c) {
  return c.layers * c.sublayers + c.layers - 1;
}
// Columns of the gradient sums: per module, its activation (if any), b_p, b_q, its shears.
Index n_columns(const LaScalarCore& c) {
  return n_units(c) + 2 * c.layers;
}

// Lanes of register r that hold samples of a block of cnt samples.
struct BlockMasks {
  __mmask8 m[kRegs];
  explicit BlockMasks(Index cnt) {
    for (Index r = 0; r < kRegs; ++r) {
      const Index live = cnt - 8 * r;
      m[r] = live >= 8   ? __mmask8{0xFF}
             : live <= 0 ? __mmask8{0}
                         : static_cast<__mmask8>((1u << live) - 1u);
    }
  }
};

// The rows of a block live in arrays of registers that are only ever indexed by constants
// (every loop over them unrolled, src and dst chosen by a branch, not a pointer), so that the
// compiler keeps them in registers.
using Regs = __m512d[kRegs];

// The samples of one block: its steps and which lanes are live. A full block (kFull) uses
// plain loads and stores, which fold into the arithmetic; kPoly: step_terms = 2.
template <bool kFull, bool kPoly>
struct BlockView {
  const double* h;  // the block's steps
  BlockMasks mk;
  BlockView(const double* h_row, Index j0, Index cnt) : h(h_row + j0), mk(cnt) {}
};

template <bool kFull, bool kPoly>
__attribute__((target("avx512f"), always_inline)) inline __m512d load(
    const BlockView<kFull, kPoly>& b, Index r, const double* x) {
  if constexpr (kFull) {
    return _mm512_loadu_pd(x + 8 * r);
  } else {
    return _mm512_maskz_loadu_pd(b.mk.m[r], x + 8 * r);
  }
}

template <bool kFull, bool kPoly>
__attribute__((target("avx512f"), always_inline)) inline void store(
    const BlockView<kFull, kPoly>& b, Index r, double* x, __m512d v) {
  if constexpr (kFull) {
    _mm512_storeu_pd(x + 8 * r, v);
  } else {
    _mm512_mask_storeu_pd(x + 8 * r, b.mk.m[r], v);
  }
}

// The unit's step for register r: h itself, or τ = h (1 + c h) as unit_step() evaluates it.
template <bool kFull, bool kPoly>
__attribute__((target("avx512f"), always_inline)) inline __m512d step(
    const BlockView<kFull, kPoly>& b, Index r, __m512d c) {
  const __m512d h = load(b, r, b.h);
  if constexpr (kPoly) {
    return _mm512_mul_pd(h, _mm512_add_pd(_mm512_set1_pd(1.0), _mm512_mul_pd(c, h)));
  } else {
    return h;
  }
}

// Linear sublayer, forward: dst += (S src) τ, recording src at rec (when not null).
template <bool kFull, bool kPoly>
__attribute__((target("avx512f"), always_inline)) inline void shear_forward(
    const BlockView<kFull, kPoly>& b, const Regs& src, Regs& dst, double s_value, __m512d c,
    double* rec) {
  if (rec != nullptr) {
#pragma GCC unroll 16
    for (Index r = 0; r < kRegs; ++r) store(b, r, rec, src[r]);
  }
  const __m512d s = _mm512_set1_pd(s_value);
#pragma GCC unroll 16
  for (Index r = 0; r < kRegs; ++r) {
    const __m512d tau = step(b, r, c);
    dst[r] = _mm512_add_pd(dst[r], _mm512_mul_pd(_mm512_mul_pd(s, src[r]), tau));
  }
}

// Activation module, forward: dst += (σ(src) a) τ, σ written to sig (cnt values). σ of a block
// is σ of those samples of the row: blocks start at even samples and only the last can end at
// an odd one, so sigmoid_simd treats every sample as it does in one call on the whole row.
template <bool kFull, bool kPoly>
__attribute__((target("avx512f"), always_inline)) inline void activation_forward(
    const BlockView<kFull, kPoly>& b, Index cnt, const Regs& src, Regs& dst, double a_value,
    __m512d c, double* sig) {
  alignas(64) double src_buf[kBlock];
#pragma GCC unroll 16
  for (Index r = 0; r < kRegs; ++r) _mm512_store_pd(src_buf + 8 * r, src[r]);
  sigmoid_simd(src_buf, sig, cnt);
  const __m512d a = _mm512_set1_pd(a_value);
#pragma GCC unroll 16
  for (Index r = 0; r < kRegs; ++r) {
    const __m512d tau = step(b, r, c);
    dst[r] = _mm512_add_pd(dst[r], _mm512_mul_pd(_mm512_mul_pd(load(b, r, sig), a), tau));
  }
}

// One block of la_scalar_flow_simd(): samples [j0, j0 + cnt) of q, p.
template <bool kFull, bool kPoly>
__attribute__((target("avx512f"))) void flow_block(const LaScalarCore& core, const double* theta,
                                                   double* q_row, double* p_row,
                                                   const double* h_row, Index j0, Index cnt,
                                                   std::vector<Matrix>* mats, std::size_t slot0) {
  const BlockView<kFull, kPoly> b(h_row, j0, cnt);
  Regs q, p;
#pragma GCC unroll 16
  for (Index r = 0; r < kRegs; ++r) {
    q[r] = load(b, r, q_row + j0);
    p[r] = load(b, r, p_row + j0);
  }
  alignas(64) double sig_buf[kBlock];
  const __m512d zero = _mm512_setzero_pd();
  std::size_t slot = slot0;
  auto record = [&]() { return mats != nullptr ? (*mats)[slot++].data() + j0 : nullptr; };
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
    for (Index r = 0; r < kRegs; ++r) {
      const __m512d hv = load(b, r, b.h);
      p[r] = _mm512_add_pd(p[r], _mm512_mul_pd(hv, bp));
      q[r] = _mm512_add_pd(q[r], _mm512_mul_pd(hv, bq));
    }
    if (k + 1 < core.layers) {
      const double a = theta[off + m + 2];
      const __m512d c = kPoly ? _mm512_set1_pd(theta[act_coef(core, k)]) : zero;
      double* sig = mats != nullptr ? record() : sig_buf;
      if (k % 2 == 0) {
        activation_forward(b, cnt, q, p, a, c, sig);  // kick p += (σ(q) a) τ
      } else {
        activation_forward(b, cnt, p, q, a, c, sig);  // drift q += (σ(p) a) τ
      }
    }
  }
#pragma GCC unroll 16
  for (Index r = 0; r < kRegs; ++r) {
    store(b, r, q_row + j0, q[r]);
    store(b, r, p_row + j0, p[r]);
  }
}

// Scratch of one backward call: the columns' running sums, and, with step polynomials, every
// unit's upstream gradient row for the coefficient sums at the end.
struct BackwardScratch {
  ColumnSums sums;
  Index ld = 0;  // row stride of `upstream`
  double* upstream = nullptr;
  std::unique_ptr<double[]> storage;

  BackwardScratch(const LaScalarCore& core, Index n) : sums(n_columns(core)) {
    if (!core.poly) return;
    ld = (n + 7) / 8 * 8;
    storage.reset(new double[static_cast<std::size_t>(n_units(core) * ld)]);
    upstream = storage.get();
  }
};

// g_dst of a unit, kept for its step-polynomial coefficient (row not null).
template <bool kFull, bool kPoly>
__attribute__((target("avx512f"), always_inline)) inline void keep(const BlockView<kFull, kPoly>& b,
                                                                   const Regs& gdst, double* row) {
  if (row == nullptr) return;
#pragma GCC unroll 16
  for (Index r = 0; r < kRegs; ++r) store(b, r, row, gdst[r]);
}

// Linear sublayer, backward (dst += (S src) τ):  g = g_dst τ,  column += g src  (dA = 2 Σ),
// g_src += S g.
template <bool kFull, bool kPoly>
__attribute__((target("avx512f"), always_inline)) inline void shear_backward(
    const BlockView<kFull, kPoly>& b, Regs& gsrc, const Regs& gdst, double s_value, __m512d c,
    const double* src, double* col) {
  const __m512d s = _mm512_set1_pd(s_value);
#pragma GCC unroll 16
  for (Index r = 0; r < kRegs; ++r) {
    const __m512d tau = step(b, r, c);
    const __m512d g = _mm512_mul_pd(gdst[r], tau);
    _mm512_store_pd(col + 8 * r, _mm512_mul_pd(g, load(b, r, src)));
    gsrc[r] = _mm512_add_pd(gsrc[r], _mm512_mul_pd(s, g));
  }
}

// Activation module, backward (dst += (σ a) τ):  g = g_dst τ,  column += g σ  (da = Σ),
// g_src += ((g σ)(1 − σ)) a.
template <bool kFull, bool kPoly>
__attribute__((target("avx512f"), always_inline)) inline void activation_backward(
    const BlockView<kFull, kPoly>& b, Regs& gsrc, const Regs& gdst, double a_value, __m512d c,
    const double* sig, double* col) {
  const __m512d a = _mm512_set1_pd(a_value);
  const __m512d one = _mm512_set1_pd(1.0);
#pragma GCC unroll 16
  for (Index r = 0; r < kRegs; ++r) {
    const __m512d tau = step(b, r, c);
    const __m512d g = _mm512_mul_pd(gdst[r], tau);
    const __m512d s = load(b, r, sig);
    const __m512d gs = _mm512_mul_pd(g, s);
    _mm512_store_pd(col + 8 * r, gs);
    gsrc[r] = _mm512_add_pd(gsrc[r], _mm512_mul_pd(_mm512_mul_pd(gs, _mm512_sub_pd(one, s)), a));
  }
}

// One block of la_scalar_backward_simd()'s sweep: samples [j0, j0 + cnt) of gq, gp; the
// products of every gradient column for these samples go to their running sums.
template <bool kFull, bool kPoly>
__attribute__((target("avx512f"))) void backward_block(const LaScalarCore& core,
                                                       const double* theta,
                                                       const std::vector<Matrix>& mats,
                                                       std::size_t slot0, const double* h_row,
                                                       Index j0, Index cnt, double* gq_row,
                                                       double* gp_row, BackwardScratch& scratch) {
  const BlockView<kFull, kPoly> b(h_row, j0, cnt);
  Regs gq, gp;
#pragma GCC unroll 16
  for (Index r = 0; r < kRegs; ++r) {
    gq[r] = load(b, r, gq_row + j0);
    gp[r] = load(b, r, gp_row + j0);
  }
  const __m512d zero = _mm512_setzero_pd();
  const Index m = core.sublayers;
  Index unit = n_units(core);  // units counted in application order, as the slots
  auto upstream_row = [&]() { return kPoly ? scratch.upstream + unit * scratch.ld + j0 : nullptr; };
  for (Index k = core.layers - 1; k >= 0; --k) {
    const Index base = module_offset(core, k);
    const Index bias = base + m;
    if (k + 1 < core.layers) {
      --unit;
      const double* sig = mats[slot0 + static_cast<std::size_t>(unit)].data() + j0;
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
      for (Index r = 0; r < kRegs; ++r) {
        _mm512_store_pd(col + 8 * r, _mm512_mul_pd(bias_q ? gq[r] : gp[r], load(b, r, b.h)));
      }
      scratch.sums.column_done(cnt);
    }
    for (Index i = m - 1; i >= 0; --i) {
      --unit;
      const double* src = mats[slot0 + static_cast<std::size_t>(unit)].data() + j0;
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
  for (Index r = 0; r < kRegs; ++r) {
    store(b, r, gq_row + j0, gq[r]);
    store(b, r, gp_row + j0, gp[r]);
  }
}

// Σ_j g_j x_j h_j² as the portable code writes it (an Eigen reduction, whose order is Eigen's).
double poly_sum(const double* g, const double* x, const Vector& h2, Index n) {
  return (ConstRowMap(g, n).array() * ConstRowMap(x, n).array() * ConstRowMap(h2.data(), n).array())
      .sum();
}

}  // namespace

bool la_scalar_simd_supported() {
  static const bool supported = [] {
    __builtin_cpu_init();
    if (!__builtin_cpu_supports("avx512f")) return false;
    double x[2] = {0.5, -0.5}, s[2];
    return sigmoid_simd(x, s, 2);  // its kernel is part of the forward sweep
  }();
  return supported;
}

bool la_scalar_flow_simd(const LaScalarCore& core, const double* theta, double* q, double* p,
                         const double* h, Index n, std::vector<Matrix>* mats, std::size_t slot0) {
  if (n < 1 || !la_scalar_simd_supported()) return false;
  if (mats != nullptr) {
    for (Index u = 0; u < n_units(core); ++u)
      (*mats)[slot0 + static_cast<std::size_t>(u)].resize(1, n);
  }
  for (Index j0 = 0; j0 < n; j0 += kBlock) {
    const Index cnt = n - j0 < kBlock ? n - j0 : kBlock;
    auto run = [&](auto block) { block(core, theta, q, p, h, j0, cnt, mats, slot0); };
    if (cnt == kBlock) {
      core.poly ? run(flow_block<true, true>) : run(flow_block<true, false>);
    } else {
      core.poly ? run(flow_block<false, true>) : run(flow_block<false, false>);
    }
  }
  return true;
}

bool la_scalar_backward_simd(const LaScalarCore& core, const double* theta,
                             const std::vector<Matrix>& mats, std::size_t slot0, const double* h,
                             Index n, double* gq, double* gp, double* grad) {
  if (n < 1 || !la_scalar_simd_supported()) return false;
  BackwardScratch scratch(core, n);
  for (Index j0 = 0; j0 < n; j0 += kBlock) {
    const Index cnt = n - j0 < kBlock ? n - j0 : kBlock;
    auto run = [&](auto block) { block(core, theta, mats, slot0, h, j0, cnt, gq, gp, scratch); };
    if (cnt == kBlock) {
      core.poly ? run(backward_block<true, true>) : run(backward_block<true, false>);
    } else {
      core.poly ? run(backward_block<false, true>) : run(backward_block<false, false>);
    }
    scratch.sums.end_block(cnt);
  }
  // The sums in the sweep's column order; a shear's dA = M + Mᵀ = M + M.
  const Index m = core.sublayers;
  const double* sum = scratch.sums.sums();
  for (Index k = core.layers - 1; k >= 0; --k) {
    const Index base = module_offset(core, k);
    if (k + 1 < core.layers) grad[base + m + 2] += *sum++;
    grad[base + m] += *sum++;
    grad[base + m + 1] += *sum++;
    for (Index i = m - 1; i >= 0; --i, ++sum) grad[base + i] += *sum + *sum;
  }
  if (core.poly) {
    // dc = (S or a) Σ_j h_j² g_dst,j src_j, from the recorded upstream rows.
    const Vector h2 = Vector(Eigen::Map<const Vector>(h, n).array().square());
    std::size_t slot = slot0;
    Index unit = 0;
    for (Index k = 0; k < core.layers; ++k) {
      const Index base = module_offset(core, k);
      for (Index i = 0; i < m; ++i, ++unit) {
        const double s = theta[base + i] + theta[base + i];
        const double* g = scratch.upstream + unit * scratch.ld;
        grad[shear_coef(core, k, i)] += s * poly_sum(g, mats[slot++].data(), h2, n);
      }
      if (k + 1 < core.layers) {
        const double* g = scratch.upstream + unit++ * scratch.ld;
        grad[act_coef(core, k)] += theta[base + m + 2] * poly_sum(g, mats[slot++].data(), h2, n);
      }
    }
  }
  return true;
}

#else

bool la_scalar_simd_supported() {
  return false;
}

bool la_scalar_flow_simd(const LaScalarCore&, const double*, double*, double*, const double*, Index,
                         std::vector<Matrix>*, std::size_t) {
  return false;
}

bool la_scalar_backward_simd(const LaScalarCore&, const double*, const std::vector<Matrix>&,
                             std::size_t, const double*, Index, double*, double*, double*) {
  return false;
}

#endif

}  // namespace csympnet::detail
