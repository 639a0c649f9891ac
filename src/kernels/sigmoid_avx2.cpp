// sigmoid_into()'s AVX2 kernel (activation.hpp), for machines without AVX-512: the operations of
// sigmoid_avx512.cpp, in its order, four elements per instruction (the reasons the bits agree
// with the portable build are stated there). Lanes whose −|x| lies below −700, or is NaN, go to
// Eigen's own routine with the rest of their group of four, as do the last two elements of the
// packet region when it holds a multiple of four plus two.
#include <cmath>
#include <cstring>

#include "sigmoid.hpp"

#include "registry.hpp"

#include "sse2_order.hpp"

namespace csympnet::kernels {

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace {

constexpr double kLowest = -700.0;

__attribute__((target("avx2"))) void sigmoid_avx2(const double* x, double* out, Index n2) {
  const __m256d one = _mm256_set1_pd(1.0);
  const __m256d zero = _mm256_setzero_pd();
  const __m256d sign = _mm256_set1_pd(-0.0);
  Index i = 0;
  for (; i + 4 <= n2; i += 4) {
    const __m256d xv = _mm256_loadu_pd(x + i);
    const __m256d v = _mm256_or_pd(xv, sign);  // −|x|
    if (_mm256_movemask_pd(_mm256_cmp_pd(v, _mm256_set1_pd(kLowest), _CMP_GE_OQ)) != 0xF) {
      sigmoid_pairs_eigen(x, out, i, 4);
      continue;
    }
    const __m256d e = cephes_exp256(v);
    const __m256d nonneg = _mm256_cmp_pd(xv, zero, _CMP_GE_OQ);
    const __m256d num = _mm256_blendv_pd(e, one, nonneg);
    _mm256_storeu_pd(out + i, _mm256_div_pd(num, _mm256_add_pd(one, e)));
  }
  if (i < n2) sigmoid_pairs_eigen(x, out, i, n2 - i);
}

}  // namespace

bool sigmoid_avx2_self_check() {
  // The kernel must reproduce Eigen on this machine, else it is not used.
  constexpr Index kN = 66;
  double x[kN], mine[kN], ref[kN];
  for (Index i = 0; i < kN; ++i) {
    x[i] = (static_cast<double>(i) - 31.5) * 0.37 + 1e-3 * static_cast<double>(i % 7);
  }
  x[5] = -0.0;
  x[9] = 0.0;
  x[13] = 699.999;
  x[14] = -699.999;
  sigmoid_avx2(x, mine, kN);
  sigmoid_pairs_eigen(x, ref, 0, kN);
  for (Index i = 0; i < kN; ++i) {
    if (std::memcmp(&mine[i], &ref[i], sizeof(double)) != 0) return false;
  }
  return true;
}

void sigmoid_kernel_avx2(const double* x, double* out, Index n) {
  const Index n2 = n - n % 2;  // Eigen's packet region; an odd last element is scalar
  sigmoid_avx2(x, out, n2);
  if (n2 < n) {
    const double e = std::exp(-std::abs(x[n2]));
    out[n2] = (x[n2] >= 0.0 ? 1.0 : e) / (1.0 + e);
  }
}

#else

bool sigmoid_avx2_self_check() {
  return false;
}

void sigmoid_kernel_avx2(const double*, double*, Index) {}

#endif

}  // namespace csympnet::kernels
