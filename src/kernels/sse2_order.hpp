// What the AVX-512 and AVX2 kernels that reproduce the portable build to the bit share
// (product.cpp, sigmoid_*.cpp, scaled_exp_*.cpp, d1_forward_*.cpp, …). Include it
// first among a kernel file's own code: its pragma applies to everything that follows.
//
// The portable build is x86-64 with Eigen on SSE2 and no FMA. A kernel matches it only if it
// multiplies and adds separately, so contraction into FMA is off in these files, and the
// kernels exist only when Eigen itself is on that SSE2 path (CSYMPNET_SSE2_ORDER_KERNELS); each
// kernel also checks itself against Eigen at run time before it is used.
#pragma once

#include <Eigen/Core>

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("fp-contract=off")  // multiplies and adds stay separate, as in SSE2
#endif
#if defined(__clang__)
#pragma clang fp contract(off)
#endif

// GCC only: clang does not let a lambda inside a target("avx512f") function use AVX-512
// intrinsics (the register tiles are such lambdas), so a clang build (the fuzz targets) runs
// the portable path.
#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__) && !defined(__clang__) && \
    defined(EIGEN_VECTORIZE_SSE2) && !defined(EIGEN_VECTORIZE_AVX) &&                         \
    !defined(EIGEN_VECTORIZE_FMA)
#define CSYMPNET_SSE2_ORDER_KERNELS 1
#include <immintrin.h>

namespace csympnet::kernels {

// The constants of Eigen's pexp_double (Cephes): log2(e), the rational approximation's
// coefficients and the two-part ln 2; one copy for the AVX-512 and AVX2 forms below.
namespace cephes {
inline constexpr double kLog2e = 1.4426950408889634073599;
inline constexpr double kP0 = 1.26177193074810590878e-4;
inline constexpr double kP1 = 3.02994407707441961300e-2;
inline constexpr double kP2 = 9.99999999999999999910e-1;
inline constexpr double kQ0 = 3.00198505138664455042e-6;
inline constexpr double kQ1 = 2.52448340349684104192e-3;
inline constexpr double kQ2 = 2.27265548208155028766e-1;
inline constexpr double kQ3 = 2.00000000000000000009e0;
inline constexpr double kC1 = 0.693145751953125;
inline constexpr double kC2 = 1.42860682030941723212e-6;
}  // namespace cephes

// e^x in every lane, with the operations of Eigen's pexp_double (the Cephes approximation),
// in its order, eight lanes at a time. Valid for lanes in [−700, 700]; callers hand other
// lanes (and NaN) to Eigen, whose clamping and scaling cases this leaves out.
__attribute__((target("avx512f"), always_inline)) inline __m512d cephes_exp512(__m512d x) {
  using namespace cephes;
  __m512d fx = _mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(kLog2e), x), _mm512_set1_pd(0.5));
  fx = _mm512_mask_roundscale_pd(fx, 0xFF, fx, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
  __m512d g = _mm512_sub_pd(x, _mm512_mul_pd(fx, _mm512_set1_pd(kC1)));
  g = _mm512_sub_pd(g, _mm512_mul_pd(fx, _mm512_set1_pd(kC2)));
  const __m512d g2 = _mm512_mul_pd(g, g);
  __m512d px = _mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(kP0), g2), _mm512_set1_pd(kP1));
  px = _mm512_add_pd(_mm512_mul_pd(px, g2), _mm512_set1_pd(kP2));
  px = _mm512_mul_pd(px, g);
  __m512d qx = _mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(kQ0), g2), _mm512_set1_pd(kQ1));
  qx = _mm512_add_pd(_mm512_mul_pd(qx, g2), _mm512_set1_pd(kQ2));
  qx = _mm512_add_pd(_mm512_mul_pd(qx, g2), _mm512_set1_pd(kQ3));
  __m512d e = _mm512_div_pd(px, _mm512_sub_pd(qx, px));
  e = _mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(2.0), e), _mm512_set1_pd(1.0));
  return _mm512_mask_scalef_pd(e, 0xFF, e, fx);  // e · 2^fx, exact: 2^fx and e·2^fx are normal
}

// The same, four lanes at a time with AVX2 (no FMA: the target leaves it out, and fp-contract is
// off above). Without scalef, 2^fx is built from its bits: fx + (2^52 + 1023) holds the integer
// fx + 1023 ∈ [13, 2033] in its low mantissa bits, which a shift by 52 moves into the exponent
// field; the product e · 2^fx is then exact as above, so the bits are those of scalef.
__attribute__((target("avx2"), always_inline)) inline __m256d cephes_exp256(__m256d x) {
  using namespace cephes;
  constexpr double kBiasShift = 4503599627370496.0 + 1023.0;  // 2^52 + the exponent bias
  __m256d fx = _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(kLog2e), x), _mm256_set1_pd(0.5));
  fx = _mm256_round_pd(fx, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
  __m256d g = _mm256_sub_pd(x, _mm256_mul_pd(fx, _mm256_set1_pd(kC1)));
  g = _mm256_sub_pd(g, _mm256_mul_pd(fx, _mm256_set1_pd(kC2)));
  const __m256d g2 = _mm256_mul_pd(g, g);
  __m256d px = _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(kP0), g2), _mm256_set1_pd(kP1));
  px = _mm256_add_pd(_mm256_mul_pd(px, g2), _mm256_set1_pd(kP2));
  px = _mm256_mul_pd(px, g);
  __m256d qx = _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(kQ0), g2), _mm256_set1_pd(kQ1));
  qx = _mm256_add_pd(_mm256_mul_pd(qx, g2), _mm256_set1_pd(kQ2));
  qx = _mm256_add_pd(_mm256_mul_pd(qx, g2), _mm256_set1_pd(kQ3));
  __m256d e = _mm256_div_pd(px, _mm256_sub_pd(qx, px));
  e = _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(2.0), e), _mm256_set1_pd(1.0));
  const __m256i biased = _mm256_castpd_si256(_mm256_add_pd(fx, _mm256_set1_pd(kBiasShift)));
  return _mm256_mul_pd(e, _mm256_castsi256_pd(_mm256_slli_epi64(biased, 52)));
}

}  // namespace csympnet::kernels

#endif
