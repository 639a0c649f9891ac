// Internal to d1_{forward,backward}_{avx512,avx2}.cpp (include after sse2_order.hpp): what the
// d = 1 forward and backward sweeps share: θ's layout, and the block of samples a sweep holds in
// registers with its steps (Block: eight samples per AVX-512 register; Block256: four per AVX2
// register).
#pragma once

#include <memory>

#include "column_sums.hpp"
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

// The record rows' data pointers (one per unit, in application order), gathered once per call:
// the sweep reads one per unit and block, and the Matrix headers are cold after the records.
class RecordRows {
 public:
  explicit RecordRows(Index units) {
    if (units > kLocal) heap_.reset(new double*[static_cast<std::size_t>(units)]);
  }
  double** data() { return heap_ ? heap_.get() : local_; }

  // The rows of steps[0, units), each resized to 1 x n unless it is; null without steps.
  double* const* gather(Matrix* steps, Index units, Index n) {
    if (steps == nullptr) return nullptr;
    prefetch(steps, units);
    for (Index u = 0; u < units; ++u) {
      if (steps[u].rows() != 1 || steps[u].cols() != n) steps[u].resize(1, n);
      data()[u] = steps[u].data();
    }
    return data();
  }

  // Prefetches the headers of rows[0, units): they are read one after the other, each a likely
  // L1 miss, and the prefetches let the misses overlap.
  static void prefetch(const Matrix* rows, Index units) {
    const char* begin = reinterpret_cast<const char*>(rows);
    const char* end = reinterpret_cast<const char*>(rows + units);
    for (const char* line = begin; line < end; line += 64) __builtin_prefetch(line, 0, 3);
  }

 private:
  static constexpr Index kLocal = 256;
  double* local_[kLocal];
  std::unique_ptr<double*[]> heap_;
};

using ConstRowMap = Eigen::Map<const RowVector>;

// Columns of the backward sweep's gradient sums: per module, its activation (if any), b_p, b_q,
// its shears.
inline Index n_columns(const D1Core& c) {
  return n_units(c) + 2 * c.layers;
}

// Scratch of one backward call: the columns' running sums, and, with step polynomials, every
// unit's upstream gradient row for the coefficient sums at the end.
struct BackwardScratch {
  ColumnSums sums;
  Index ld = 0;  // row stride of `upstream`
  double* upstream = nullptr;
  std::unique_ptr<double[]> storage;

  BackwardScratch(const D1Core& core, Index n, ColumnSums::Isa isa) : sums(n_columns(core), isa) {
    if (!core.poly) return;
    ld = (n + 7) / 8 * 8;
    storage.reset(new double[static_cast<std::size_t>(n_units(core) * ld)]);
    upstream = storage.get();
  }
};

// Σ_j g_j x_j h_j² as the portable code writes it (an Eigen reduction, whose order is Eigen's).
inline double poly_sum(const double* g, const double* x, const Vector& h2, Index n) {
  return (ConstRowMap(g, n).array() * ConstRowMap(x, n).array() * ConstRowMap(h2.data(), n).array())
      .sum();
}

// After the backward sweep: the parameter gradients from the columns' sums (in the sweep's column
// order) and, with step polynomials, the coefficients' sums from the kept upstream rows.
inline void add_parameter_gradients(const D1Core& core, const double* theta, const Matrix* steps,
                                    const double* h, Index n, const BackwardScratch& scratch,
                                    double* grad) {
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
    const Matrix* step = steps;
    Index unit = 0;
    for (Index k = 0; k < core.layers; ++k) {
      const Index base = module_offset(core, k);
      for (Index i = 0; i < m; ++i, ++unit) {
        const double s = theta[base + i] + theta[base + i];
        const double* g = scratch.upstream + unit * scratch.ld;
        grad[shear_coef(core, k, i)] += s * poly_sum(g, (step++)->data(), h2, n);
      }
      if (k + 1 < core.layers) {
        const double* g = scratch.upstream + unit++ * scratch.ld;
        grad[act_coef(core, k)] += theta[base + m + 2] * poly_sum(g, (step++)->data(), h2, n);
      }
    }
  }
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

// The AVX2 block: kR registers of 4 samples. Without mask registers, a partial block's dead
// lanes are left out of loads and stores by AVX's masked moves (vmaskmovpd: a dead lane reads 0
// and is never written). The steps are read from memory where used rather than held: sixteen
// registers leave no room for them beside the rows.
template <int kR, bool kFull, bool kPoly>
struct Block256 {
  __m256i m[kR];
  const double* h;  // the block's first step
  Index cnt;        // live samples
  __attribute__((target("avx2"), always_inline)) Block256(const double* h_row, Index j0, Index live)
      : h(h_row + j0), cnt(live) {
    const __m256i lane = _mm256_set_epi64x(3, 2, 1, 0);
#pragma GCC unroll 16
    for (int r = 0; r < kR; ++r) {
      m[r] = _mm256_cmpgt_epi64(_mm256_set1_epi64x(static_cast<long long>(live - 4 * r)), lane);
    }
  }
};

// In a partial block, only the register that straddles its end takes a masked move: on some AMD
// cores (Zen 1 and 2 among them) a masked 256-bit store is microcoded, many times a plain one.
template <int kR, bool kFull, bool kPoly>
__attribute__((target("avx2"), always_inline)) inline __m256d load(
    const Block256<kR, kFull, kPoly>& b, int r, const double* x) {
  if constexpr (kFull) {
    return _mm256_loadu_pd(x + 4 * r);
  } else {
    const Index live = b.cnt - 4 * r;
    if (live >= 4) return _mm256_loadu_pd(x + 4 * r);
    if (live <= 0) return _mm256_setzero_pd();
    return _mm256_maskload_pd(x + 4 * r, b.m[r]);
  }
}

template <int kR, bool kFull, bool kPoly>
__attribute__((target("avx2"), always_inline)) inline void store(
    const Block256<kR, kFull, kPoly>& b, int r, double* x, __m256d v) {
  if constexpr (kFull) {
    _mm256_storeu_pd(x + 4 * r, v);
  } else {
    const Index live = b.cnt - 4 * r;
    if (live >= 4) {
      _mm256_storeu_pd(x + 4 * r, v);
    } else if (live > 0) {
      _mm256_maskstore_pd(x + 4 * r, b.m[r], v);
    }
  }
}

// The steps h of register r.
template <int kR, bool kFull, bool kPoly>
__attribute__((target("avx2"), always_inline)) inline __m256d steps(
    const Block256<kR, kFull, kPoly>& b, int r) {
  return load(b, r, b.h);
}

// The unit's step for register r, as step() above.
template <int kR, bool kFull, bool kPoly>
__attribute__((target("avx2"), always_inline)) inline __m256d step(
    const Block256<kR, kFull, kPoly>& b, int r, __m256d c) {
  const __m256d h = steps(b, r);
  if constexpr (kPoly) {
    return _mm256_mul_pd(h, _mm256_add_pd(_mm256_set1_pd(1.0), _mm256_mul_pd(c, h)));
  } else {
    return h;
  }
}

}  // namespace csympnet::kernels::d1_block

#endif
