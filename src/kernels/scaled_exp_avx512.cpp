// scaled_exp_simd() (scaled_exp.hpp): exp(c h_j), the same values to the bit as the portable
// build's Eigen expression `(c * h.array()).exp()`, eight elements per instruction instead of
// two. The approach of sigmoid_avx512.cpp, for arguments of either sign.
//
// Why the bits agree: Eigen's packet exp (pexp_double) is a fixed sequence of IEEE operations
// (Cephes' method: n = ⌊x log2(e) + ½⌋, g = x − n·C1 − n·C2, a rational approximation of e^g,
// then scaling by 2^n and max(·, x) as a non-finite guard), each a multiply, add, subtract,
// divide, floor or power-of-two scaling, and the SSE2 build evaluates them without FMA. The
// same operations on wider registers give the same results. For x in [−700, 700] Eigen's
// clamping is inactive, 2^n and the result are normal numbers, so the scaling is exact however
// it is split, and the guard max(e^x, x) returns e^x; lanes outside that range (or NaN) are
// handed to Eigen's own routine.
#include "scaled_exp.hpp"

#include "registry.hpp"

#include <cmath>
#include <cstring>

#include "sse2_order.hpp"

namespace csympnet::kernels {

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

// The Eigen expression's evaluation: the product c·h as one packet multiply, then pexp.
void scaled_exp_pairs_eigen(double c, const double* h, double* out, Index i, Index count) {
  namespace ei = Eigen::internal;
  using Packet = ei::packet_traits<double>::type;
  const Packet cv = ei::pset1<Packet>(c);
  for (Index j = i; j < i + count; j += 2) {
    ei::pstoreu(out + j, ei::pexp(ei::pmul(cv, ei::ploadu<Packet>(h + j))));
  }
}

namespace {

constexpr double kBound = 700.0;  // |x| beyond this (or NaN): Eigen's own routine

// n2 is even: the pairs region of Eigen's loop.
__attribute__((target("avx512f"))) void exp_avx512(double c, const double* h, double* out,
                                                   Index n2) {
  const __m512d cv = _mm512_set1_pd(c);
  for (Index i = 0; i < n2; i += 8) {
    const Index count = n2 - i < 8 ? n2 - i : 8;
    const __mmask8 live = static_cast<__mmask8>((1u << count) - 1u);
    const __m512d x = _mm512_mul_pd(cv, _mm512_maskz_loadu_pd(live, h + i));
    const __mmask8 above = _mm512_mask_cmp_pd_mask(live, x, _mm512_set1_pd(-kBound), _CMP_GE_OQ);
    const __mmask8 handled = _mm512_mask_cmp_pd_mask(above, x, _mm512_set1_pd(kBound), _CMP_LE_OQ);
    if (handled != live) {
      scaled_exp_pairs_eigen(c, h, out, i, count);
      continue;
    }
    _mm512_mask_storeu_pd(out + i, live, cephes_exp512(x));
  }
}

}  // namespace

bool scaled_exp_self_check() {
  // The kernel must reproduce Eigen on this machine, else it is not used. Arguments of both
  // signs up to the bounds, and tiny ones around 0.
  constexpr Index kN = 64;
  double h[kN], mine[kN], ref[kN];
  for (Index i = 0; i < kN; ++i) {
    h[i] = (static_cast<double>(i) - 31.5) * 22.2 + 1e-3 * static_cast<double>(i % 7);
  }
  h[5] = -0.0;
  h[9] = 0.0;
  h[10] = 1e-300;
  h[11] = -3e-17;
  h[12] = 699.999;
  h[13] = -699.999;
  const double c = -0.999;
  exp_avx512(c, h, mine, kN);
  scaled_exp_pairs_eigen(c, h, ref, 0, kN);
  for (Index i = 0; i < kN; ++i) {
    if (std::memcmp(&mine[i], &ref[i], sizeof(double)) != 0) return false;
  }
  return true;
}

bool scaled_exp_simd(double c, const double* h, double* out, Index n) {
  if (use(Family::kScaledExp)) {
    const Index n2 = n - n % 2;  // Eigen's packet region; an odd last element is scalar
    exp_avx512(c, h, out, n2);
    if (n2 < n) out[n2] = std::exp(c * h[n2]);
    return true;
  }
  if (use(Family::kScaledExpAvx2)) {
    scaled_exp_kernel_avx2(c, h, out, n);
    return true;
  }
  return false;
}

#else

bool scaled_exp_self_check() {
  return false;
}

bool scaled_exp_simd(double, const double*, double*, Index) {
  return false;
}

void scaled_exp_pairs_eigen(double, const double*, double*, Index, Index) {}

#endif

}  // namespace csympnet::kernels
