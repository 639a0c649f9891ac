// adamw_update.hpp: AdamW's update as three Eigen passes (the portable code) or as one AVX-512
// or AVX2 pass with, per element, the same operations in the same order and operand order.
#include "sse2_order.hpp"  // first: no FMA contraction in this file

#include "adamw_update.hpp"

#include <cmath>
#include <cstring>

#include "registry.hpp"

namespace csympnet::kernels {

void adamw_update_portable(const AdamWScalars& s, double* theta_p, double* m_p, double* v_p,
                           const double* g_p, Index n, Index keep) {
  Eigen::Map<Vector> theta(theta_p, n), m(m_p, n), v(v_p, n);
  const Eigen::Map<const Vector> g(g_p, n);
  const double kept = keep >= 0 ? theta(keep) : 0.0;
  theta *= s.decay;
  if (keep >= 0) theta(keep) = kept;
  m = s.b1 * m + s.c1 * g;
  v = s.b2 * v + s.c2 * g.cwiseAbs2();
  theta.array() -= s.step_size * m.array() / (v.array().sqrt() / s.bias2_sqrt + s.eps);
}

#ifdef CSYMPNET_SSE2_ORDER_KERNELS

namespace {

// One pass with, per element, the operations of the portable update's three Eigen passes in
// their order and operand order. Divisions and square roots are the step's cost; eight lanes
// per instruction here against two in SSE2 (on Zen 4, 1.1 against 2.4 cycles per division, 2.1
// against 5 per square root).
__attribute__((target("avx512f"))) void update_avx512(const AdamWScalars& s, double* theta,
                                                      double* m, double* v, const double* g,
                                                      Index n, Index keep) {
  const __m512d decay = _mm512_set1_pd(s.decay), b1 = _mm512_set1_pd(s.b1);
  const __m512d c1 = _mm512_set1_pd(s.c1), b2 = _mm512_set1_pd(s.b2);
  const __m512d c2 = _mm512_set1_pd(s.c2), step_size = _mm512_set1_pd(s.step_size);
  const __m512d bias2_sqrt = _mm512_set1_pd(s.bias2_sqrt), eps = _mm512_set1_pd(s.eps);
  for (Index i = 0; i < n; i += 8) {
    const Index count = n - i < 8 ? n - i : 8;
    const __mmask8 live = static_cast<__mmask8>((1u << count) - 1u);
    const __m512d th = _mm512_maskz_loadu_pd(live, theta + i);
    const __m512d gv = _mm512_maskz_loadu_pd(live, g + i);
    __m512d td = _mm512_mul_pd(th, decay);
    if (keep >= i && keep < i + 8) {
      td = _mm512_mask_mov_pd(td, static_cast<__mmask8>(1u << (keep - i)), th);
    }
    const __m512d mv =
        _mm512_add_pd(_mm512_mul_pd(b1, _mm512_maskz_loadu_pd(live, m + i)), _mm512_mul_pd(c1, gv));
    const __m512d vv = _mm512_add_pd(_mm512_mul_pd(b2, _mm512_maskz_loadu_pd(live, v + i)),
                                     _mm512_mul_pd(c2, _mm512_mul_pd(gv, gv)));
    // (The masked form of the square root: GCC 12's plain one warns of its undefined source.)
    const __m512d root = _mm512_mask_sqrt_pd(vv, 0xFF, vv);
    const __m512d den = _mm512_add_pd(_mm512_div_pd(root, bias2_sqrt), eps);
    const __m512d upd = _mm512_div_pd(_mm512_mul_pd(step_size, mv), den);
    _mm512_mask_storeu_pd(m + i, live, mv);
    _mm512_mask_storeu_pd(v + i, live, vv);
    _mm512_mask_storeu_pd(theta + i, live, _mm512_sub_pd(td, upd));
  }
}

// The same with AVX2, four lanes per instruction, and the last n mod 4 elements one at a time
// with the same scalar operations (each element's arithmetic is independent of its neighbours).
__attribute__((target("avx2"))) void update_avx2(const AdamWScalars& s, double* theta, double* m,
                                                 double* v, const double* g, Index n, Index keep) {
  const __m256d decay = _mm256_set1_pd(s.decay), b1 = _mm256_set1_pd(s.b1);
  const __m256d c1 = _mm256_set1_pd(s.c1), b2 = _mm256_set1_pd(s.b2);
  const __m256d c2 = _mm256_set1_pd(s.c2), step_size = _mm256_set1_pd(s.step_size);
  const __m256d bias2_sqrt = _mm256_set1_pd(s.bias2_sqrt), eps = _mm256_set1_pd(s.eps);
  Index i = 0;
  for (; i + 4 <= n; i += 4) {
    const __m256d th = _mm256_loadu_pd(theta + i);
    const __m256d gv = _mm256_loadu_pd(g + i);
    __m256d td = _mm256_mul_pd(th, decay);
    if (keep >= i && keep < i + 4) {
      alignas(32) double lanes[4];
      _mm256_store_pd(lanes, td);
      lanes[keep - i] = theta[keep];
      td = _mm256_load_pd(lanes);
    }
    const __m256d mv =
        _mm256_add_pd(_mm256_mul_pd(b1, _mm256_loadu_pd(m + i)), _mm256_mul_pd(c1, gv));
    const __m256d vv = _mm256_add_pd(_mm256_mul_pd(b2, _mm256_loadu_pd(v + i)),
                                     _mm256_mul_pd(c2, _mm256_mul_pd(gv, gv)));
    const __m256d den = _mm256_add_pd(_mm256_div_pd(_mm256_sqrt_pd(vv), bias2_sqrt), eps);
    const __m256d upd = _mm256_div_pd(_mm256_mul_pd(step_size, mv), den);
    _mm256_storeu_pd(m + i, mv);
    _mm256_storeu_pd(v + i, vv);
    _mm256_storeu_pd(theta + i, _mm256_sub_pd(td, upd));
  }
  for (; i < n; ++i) {
    const double td = i == keep ? theta[i] : theta[i] * s.decay;
    const double mi = s.b1 * m[i] + s.c1 * g[i];
    const double vi = s.b2 * v[i] + s.c2 * (g[i] * g[i]);
    m[i] = mi;
    v[i] = vi;
    theta[i] = td - (s.step_size * mi) / (std::sqrt(vi) / s.bias2_sqrt + s.eps);
  }
}

// A few steps of the portable update and of `update` on values of every size class (both decay
// choices, an odd length for the tail) must agree to the bit.
template <typename Update>
bool agrees_with_portable(Update update) {
  constexpr Index kN = 37;
  constexpr Index kKeep = 11;
  const double lr = 3e-3, wd = 0.02, beta1 = 0.9, beta2 = 0.999;
  for (const Index keep : {Index{-1}, kKeep, kN - 1}) {
    double ta[kN], tb[kN], ma[kN] = {}, mb[kN] = {}, va[kN] = {}, vb[kN] = {}, g[kN];
    for (int step = 0; step < 3; ++step) {
      for (Index i = 0; i < kN; ++i) {
        const double x = static_cast<double>((i * 37 + step * 11) % 23) - 11.0;
        if (step == 0) ta[i] = tb[i] = 0.37 * x * std::pow(10.0, static_cast<double>(i % 9) - 4.0);
        g[i] = (0.61 * x + 0.1) * std::pow(10.0, static_cast<double>((i + step) % 13) - 6.0);
      }
      const double t = static_cast<double>(step + 1);
      const AdamWScalars s{1.0 - lr * wd,
                           beta1,
                           1.0 - beta1,
                           beta2,
                           1.0 - beta2,
                           lr / (1.0 - std::pow(beta1, t)),
                           std::sqrt(1.0 - std::pow(beta2, t)),
                           1e-8};
      adamw_update_portable(s, ta, ma, va, g, kN, keep);
      update(s, tb, mb, vb, g, kN, keep);
    }
    if (std::memcmp(ta, tb, sizeof ta) != 0 || std::memcmp(ma, mb, sizeof ma) != 0 ||
        std::memcmp(va, vb, sizeof va) != 0) {
      return false;
    }
  }
  return true;
}

}  // namespace

bool adamw_self_check() {
  return agrees_with_portable(update_avx512);
}

bool adamw_avx2_self_check() {
  return agrees_with_portable(update_avx2);
}

void adamw_update(const AdamWScalars& s, double* theta, double* m, double* v, const double* g,
                  Index n, Index keep) {
  if (use(Family::kAdamW)) {
    update_avx512(s, theta, m, v, g, n, keep);
  } else if (use(Family::kAdamWAvx2)) {
    update_avx2(s, theta, m, v, g, n, keep);
  } else {
    adamw_update_portable(s, theta, m, v, g, n, keep);
  }
}

#else

bool adamw_self_check() {
  return false;
}

bool adamw_avx2_self_check() {
  return false;
}

void adamw_update(const AdamWScalars& s, double* theta, double* m, double* v, const double* g,
                  Index n, Index keep) {
  adamw_update_portable(s, theta, m, v, g, n, keep);
}

#endif

}  // namespace csympnet::kernels
