// conformal_rows.hpp's AVX-512 kernels: CSympNet-ID's d = 1 passes, eight samples per
// instruction. A 2 x n batch is stored as (q_0, p_0, q_1, p_1, …): two registers hold eight
// samples, split into a q and a p register by one two-source permute each, and joined back
// likewise. Permutes and masked loads and stores move values unchanged; the arithmetic is the
// portable loops' multiplies and adds, one instruction per operation, in their order (the file
// is compiled with fp-contract off, so that none is fused into an FMA).
#include "conformal_rows.hpp"

#include <cstring>

#include "registry.hpp"
#include "sse2_order.hpp"  // first of this file's own code: fp-contract off, under gcc and clang

#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
#define CSYMPNET_CONFORMAL_ROWS_SIMD 1
#include <immintrin.h>
#endif

namespace csympnet::kernels {

#ifdef CSYMPNET_CONFORMAL_ROWS_SIMD

namespace {

// Masks for `count` (1..8) samples from column j: one lane per sample, and the two registers'
// lanes of the interleaved 2 x n storage.
struct Masks {
  __mmask8 one, lo, hi;
};

Masks masks_for(Index count) {
  const unsigned c = static_cast<unsigned>(count);
  Masks m;
  m.one = static_cast<__mmask8>((1u << c) - 1u);
  m.lo = static_cast<__mmask8>(c >= 4 ? 0xFFu : (1u << (2 * c)) - 1u);
  m.hi = static_cast<__mmask8>(c > 4 ? (1u << (2 * c - 8)) - 1u : 0u);
  return m;
}

// Rows 0 and 1 of eight interleaved samples (lo: samples 0-3, hi: samples 4-7).
__attribute__((target("avx512f"))) inline void split(__m512d lo, __m512d hi, __m512d& top,
                                                     __m512d& bottom) {
  const __m512i even = _mm512_set_epi64(14, 12, 10, 8, 6, 4, 2, 0);
  const __m512i odd = _mm512_set_epi64(15, 13, 11, 9, 7, 5, 3, 1);
  top = _mm512_permutex2var_pd(lo, even, hi);
  bottom = _mm512_permutex2var_pd(lo, odd, hi);
}

__attribute__((target("avx512f"))) void split_avx512(const double* z, Index n, const double* a,
                                                     double* q, double* p, double* p_raw) {
  for (Index j = 0; j < n; j += 8) {
    const Masks m = masks_for(n - j < 8 ? n - j : 8);
    __m512d top, bottom;
    split(_mm512_maskz_loadu_pd(m.lo, z + 2 * j), _mm512_maskz_loadu_pd(m.hi, z + 2 * j + 8), top,
          bottom);
    _mm512_mask_storeu_pd(q + j, m.one, top);
    if (p_raw != nullptr) _mm512_mask_storeu_pd(p_raw + j, m.one, bottom);
    const __m512d av = _mm512_maskz_loadu_pd(m.one, a + j);
    _mm512_mask_storeu_pd(p + j, m.one, _mm512_mul_pd(bottom, av));
  }
}

__attribute__((target("avx512f"))) void join_avx512(const double* q, const double* p,
                                                    const double* a, Index n, double* out) {
  const __m512i first = _mm512_set_epi64(11, 3, 10, 2, 9, 1, 8, 0);
  const __m512i second = _mm512_set_epi64(15, 7, 14, 6, 13, 5, 12, 4);
  for (Index j = 0; j < n; j += 8) {
    const Masks m = masks_for(n - j < 8 ? n - j : 8);
    const __m512d qv = _mm512_maskz_loadu_pd(m.one, q + j);
    const __m512d pa =
        _mm512_mul_pd(_mm512_maskz_loadu_pd(m.one, p + j), _mm512_maskz_loadu_pd(m.one, a + j));
    _mm512_mask_storeu_pd(out + 2 * j, m.lo, _mm512_permutex2var_pd(qv, first, pa));
    _mm512_mask_storeu_pd(out + 2 * j + 8, m.hi, _mm512_permutex2var_pd(qv, second, pa));
  }
}

__attribute__((target("avx512f"))) void terms_avx512(const double* dz, const double* p_core,
                                                     const double* gp, const double* p_in,
                                                     const double* h, const double* a, Index n,
                                                     double* terms) {
  for (Index j = 0; j < n; j += 8) {
    const Masks m = masks_for(n - j < 8 ? n - j : 8);
    __m512d unused, g;
    split(_mm512_maskz_loadu_pd(m.lo, dz + 2 * j), _mm512_maskz_loadu_pd(m.hi, dz + 2 * j + 8),
          unused, g);
    const __m512d outer = _mm512_mul_pd(g, _mm512_maskz_loadu_pd(m.one, p_core + j));
    const __m512d inner =
        _mm512_mul_pd(_mm512_maskz_loadu_pd(m.one, gp + j), _mm512_maskz_loadu_pd(m.one, p_in + j));
    const __m512d grad_a = _mm512_add_pd(outer, inner);
    const __m512d t = _mm512_mul_pd(_mm512_mul_pd(grad_a, _mm512_maskz_loadu_pd(m.one, h + j)),
                                    _mm512_maskz_loadu_pd(m.one, a + j));
    _mm512_mask_storeu_pd(terms + j, m.one, t);
  }
}

}  // namespace

bool conformal_rows_built() {
  return true;
}

// A form's three kernels against the portable loops' formulas (csympnet_id.cpp), element by
// element, for every sample count up to three registers' worth (every tail).
template <typename Split, typename Join, typename Terms>
bool agrees_with_portable(Split split_rows, Join join_rows, Terms damping_terms) {
  constexpr Index kMax = 27;
  double z[2 * kMax], a[kMax], h[kMax], pc[kMax], gp[kMax], pin[kMax];
  for (Index i = 0; i < 2 * kMax; ++i) z[i] = 0.37 * static_cast<double>(i % 11) - 1.3;
  for (Index j = 0; j < kMax; ++j) {
    a[j] = 0.9 + 0.013 * static_cast<double>(j);
    h[j] = 0.1 + 0.007 * static_cast<double>(j % 5);
    pc[j] = 1.7 - 0.11 * static_cast<double>(j);
    gp[j] = -0.3 + 0.05 * static_cast<double>(j % 7);
    pin[j] = 0.21 * static_cast<double>(j % 3) - 0.4;
  }
  auto same = [](double x, double y) { return std::memcmp(&x, &y, sizeof(double)) == 0; };
  for (Index n = 1; n <= kMax; ++n) {
    double q[kMax], p[kMax], raw[kMax], out[2 * kMax], terms[kMax];
    split_rows(z, n, a, q, p, raw);
    join_rows(q, raw, a, n, out);
    damping_terms(z, pc, gp, pin, h, a, n, terms);
    for (Index j = 0; j < n; ++j) {
      const double p_ref = z[2 * j + 1] * a[j];
      const double t_ref = ((z[2 * j + 1] * pc[j] + gp[j] * pin[j]) * h[j]) * a[j];
      if (!same(q[j], z[2 * j]) || !same(p[j], p_ref) || !same(raw[j], z[2 * j + 1]) ||
          !same(out[2 * j], z[2 * j]) || !same(out[2 * j + 1], p_ref) || !same(terms[j], t_ref)) {
        return false;
      }
    }
  }
  return true;
}

bool conformal_rows_self_check() {
  return agrees_with_portable(split_avx512, join_avx512, terms_avx512);
}

bool conformal_rows_avx2_self_check() {
  return agrees_with_portable(split_scaled_rows_avx2, join_scaled_rows_avx2, damping_terms_avx2);
}

bool split_scaled_rows_simd(const double* z, Index n, const double* a, double* q, double* p,
                            double* p_raw) {
  if (use(Family::kConformalRows)) {
    split_avx512(z, n, a, q, p, p_raw);
  } else if (use(Family::kConformalRowsAvx2)) {
    split_scaled_rows_avx2(z, n, a, q, p, p_raw);
  } else {
    return false;
  }
  return true;
}

bool join_scaled_rows_simd(const double* q, const double* p, const double* a, Index n,
                           double* out) {
  if (use(Family::kConformalRows)) {
    join_avx512(q, p, a, n, out);
  } else if (use(Family::kConformalRowsAvx2)) {
    join_scaled_rows_avx2(q, p, a, n, out);
  } else {
    return false;
  }
  return true;
}

bool damping_terms_simd(const double* dz, const double* p_core, const double* gp,
                        const double* p_in, const double* h, const double* a, Index n,
                        double* terms) {
  if (use(Family::kConformalRows)) {
    terms_avx512(dz, p_core, gp, p_in, h, a, n, terms);
  } else if (use(Family::kConformalRowsAvx2)) {
    damping_terms_avx2(dz, p_core, gp, p_in, h, a, n, terms);
  } else {
    return false;
  }
  return true;
}

#else

bool conformal_rows_built() {
  return false;
}

bool conformal_rows_self_check() {
  return false;
}

bool conformal_rows_avx2_self_check() {
  return false;
}

bool split_scaled_rows_simd(const double*, Index, const double*, double*, double*, double*) {
  return false;
}

bool join_scaled_rows_simd(const double*, const double*, const double*, Index, double*) {
  return false;
}

bool damping_terms_simd(const double*, const double*, const double*, const double*, const double*,
                        const double*, Index, double*) {
  return false;
}

#endif

}  // namespace csympnet::kernels
