// sigmoid_into()'s AVX-512 kernel (activation.hpp): the same values, to the bit, as the
// portable build's Eigen evaluation of
//   e = exp(−|x|)  (Eigen's packet exp on element pairs, std::exp on an odd last element),
//   σ = n / (1 + e),  n = 1 for x ≥ 0, e otherwise,
// eight elements per instruction instead of two.
//
// Why the bits agree: Eigen's packet exp is a fixed sequence of IEEE operations (Cephes'
// method: n = ⌊x log2(e) + ½⌋, g = x − n·C1 − n·C2, a rational approximation of e^g, then
// scaling by 2^n), each a multiply, add, subtract, divide, floor or power-of-two scaling, and
// the SSE2 build evaluates them without FMA. The same operations on wider registers give the
// same results. For arguments in [−700, 0] the clamping and the non-finite guard of Eigen's
// routine are inactive and 2^n is a normal number, so scaling is exact whichever way it is
// done; lanes outside that range (or NaN) are handed to Eigen's own routine.
#include <cmath>
#include <cstring>

#include "sigmoid.hpp"

#include "registry.hpp"

#include "sse2_order.hpp"

namespace csympnet::kernels {

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

// σ for the element pairs [i, i + count) with Eigen's own SSE2 packet exp.
void sigmoid_pairs_eigen(const double* x, double* out, Index i, Index count) {
  namespace ei = Eigen::internal;
  using Packet = ei::packet_traits<double>::type;
  const Packet one = ei::pset1<Packet>(1.0);
  for (Index j = i; j < i + count; j += 2) {
    const Packet xv = ei::ploadu<Packet>(x + j);
    const Packet e = ei::pexp(ei::pnegate(ei::pabs(xv)));
    const Packet num = ei::pselect(ei::pcmp_le(ei::pset1<Packet>(0.0), xv), one, e);
    ei::pstoreu(out + j, ei::pdiv(num, ei::padd(one, e)));
  }
}

namespace {

constexpr double kLowest = -700.0;  // below this, Eigen's clamp and scaling cases are handed back

__attribute__((target("avx512f"))) void sigmoid_avx512(const double* x, double* out, Index n2) {
  const __m512d one = _mm512_set1_pd(1.0);
  const __m512d zero = _mm512_setzero_pd();
  const __m512i sign = _mm512_set1_epi64(static_cast<long long>(0x8000000000000000ULL));
  for (Index i = 0; i < n2; i += 8) {
    const Index count = n2 - i < 8 ? n2 - i : 8;
    const __mmask8 live = static_cast<__mmask8>((1u << count) - 1u);
    const __m512d xv = _mm512_maskz_loadu_pd(live, x + i);
    const __m512d v = _mm512_castsi512_pd(_mm512_or_si512(_mm512_castpd_si512(xv), sign));  // −|x|
    // Lanes Eigen would treat differently (see the top) go to Eigen, pairwise.
    const __mmask8 handled = _mm512_mask_cmp_pd_mask(live, v, _mm512_set1_pd(kLowest), _CMP_GE_OQ);
    if (handled != live) {
      sigmoid_pairs_eigen(x, out, i, count);
      continue;
    }
    const __m512d e = cephes_exp512(v);
    const __mmask8 nonneg = _mm512_cmp_pd_mask(xv, zero, _CMP_GE_OQ);
    const __m512d num = _mm512_mask_blend_pd(nonneg, e, one);
    _mm512_mask_storeu_pd(out + i, live, _mm512_div_pd(num, _mm512_add_pd(one, e)));
  }
}

}  // namespace

bool sigmoid_self_check() {
  // The kernel must reproduce Eigen on this machine, else it is not used.
  constexpr Index kN = 64;
  double x[kN], mine[kN], ref[kN];
  for (Index i = 0; i < kN; ++i) {
    x[i] = (static_cast<double>(i) - 31.5) * 0.37 + 1e-3 * static_cast<double>(i % 7);
  }
  x[5] = -0.0;
  x[9] = 0.0;
  sigmoid_avx512(x, mine, kN);
  sigmoid_pairs_eigen(x, ref, 0, kN);
  for (Index i = 0; i < kN; ++i) {
    if (std::memcmp(&mine[i], &ref[i], sizeof(double)) != 0) return false;
  }
  return true;
}

void sigmoid_kernel(const double* x, double* out, Index n) {
  const Index n2 = n - n % 2;  // Eigen's packet region; an odd last element is scalar
  sigmoid_avx512(x, out, n2);
  if (n2 < n) {
    const double e = std::exp(-std::abs(x[n2]));
    out[n2] = (x[n2] >= 0.0 ? 1.0 : e) / (1.0 + e);
  }
}

bool sigmoid_simd(const double* x, double* out, Index n) {
  if (use(Family::kSigmoid)) {
    sigmoid_kernel(x, out, n);
  } else if (use(Family::kSigmoidAvx2)) {
    sigmoid_kernel_avx2(x, out, n);
  } else {
    return false;
  }
  return true;
}

#else

bool sigmoid_self_check() {
  return false;
}

void sigmoid_kernel(const double*, double*, Index) {}

void sigmoid_pairs_eigen(const double*, double*, Index, Index) {}

bool sigmoid_simd(const double*, double*, Index) {
  return false;
}

#endif

}  // namespace csympnet::kernels
