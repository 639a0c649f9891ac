// scaled_exp_simd()'s AVX2 form (scaled_exp.hpp), for machines without AVX-512: the operations of
// scaled_exp_avx512.cpp, in its order, four elements per instruction (why the bits agree with
// the portable build is stated there). A group of four with a lane outside [−700, 700], or NaN,
// goes to Eigen's own routine, as do the last two elements of the packet region when it holds a
// multiple of four plus two.
#include "scaled_exp.hpp"

#include <cmath>
#include <cstring>

#include "registry.hpp"

#include "sse2_order.hpp"

namespace csympnet::kernels {

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace {

constexpr double kBound = 700.0;

// n2 is even: the pairs region of Eigen's loop.
__attribute__((target("avx2"))) void exp_avx2(double c, const double* h, double* out, Index n2) {
  const __m256d cv = _mm256_set1_pd(c);
  Index i = 0;
  for (; i + 4 <= n2; i += 4) {
    const __m256d x = _mm256_mul_pd(cv, _mm256_loadu_pd(h + i));
    const __m256d inside = _mm256_and_pd(_mm256_cmp_pd(x, _mm256_set1_pd(-kBound), _CMP_GE_OQ),
                                         _mm256_cmp_pd(x, _mm256_set1_pd(kBound), _CMP_LE_OQ));
    if (_mm256_movemask_pd(inside) != 0xF) {
      scaled_exp_pairs_eigen(c, h, out, i, 4);
      continue;
    }
    _mm256_storeu_pd(out + i, cephes_exp256(x));
  }
  if (i < n2) scaled_exp_pairs_eigen(c, h, out, i, n2 - i);
}

}  // namespace

bool scaled_exp_avx2_self_check() {
  // As scaled_exp_self_check(): both signs up to the bounds, tiny arguments around 0.
  constexpr Index kN = 66;
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
  exp_avx2(c, h, mine, kN);
  scaled_exp_pairs_eigen(c, h, ref, 0, kN);
  for (Index i = 0; i < kN; ++i) {
    if (std::memcmp(&mine[i], &ref[i], sizeof(double)) != 0) return false;
  }
  return true;
}

void scaled_exp_kernel_avx2(double c, const double* h, double* out, Index n) {
  const Index n2 = n - n % 2;  // Eigen's packet region; an odd last element is scalar
  exp_avx2(c, h, out, n2);
  if (n2 < n) out[n2] = std::exp(c * h[n2]);
}

#else

bool scaled_exp_avx2_self_check() {
  return false;
}

void scaled_exp_kernel_avx2(double, const double*, double*, Index) {}

#endif

}  // namespace csympnet::kernels
