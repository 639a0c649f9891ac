// LaSympNet::scalar_simd_in_use(): whether the d = 1 sweeps run the AVX-512 kernels of
// la_scalar_sweep.cpp. They are used only if, on this machine, they reproduce the portable code
// to the bit on random values (as exact_sigmoid.cpp and exact_product.cpp check themselves):
// a compiler or a CPU that evaluated some operation differently must cost speed, not results.
#include <cmath>
#include <cstring>
#include <random>

#include "csympnet/models/la_sympnet.hpp"
#include "la_scalar_sweep.hpp"

namespace csympnet {

bool LaSympNet::scalar_simd_in_use() {
  static const bool agree = [] {
    if (!detail::la_scalar_simd_supported()) return false;
    // Once per process, on random values, both sweeps with and without step polynomials: the
    // kernels must reproduce the portable code on this machine, else they are not used.
    std::mt19937_64 gen(20261123);
    std::normal_distribution<double> normal;
    auto fill = [&](double* x, Index n, double scale) {
      for (Index i = 0; i < n; ++i) x[i] = scale * normal(gen);
    };
    auto same = [](const Matrix& a, const Matrix& b) {
      return a.size() == b.size() &&
             std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<std::size_t>(a.size())) ==
                 0;
    };
    constexpr Index kN = 91;  // one full block and an odd remainder
    for (const Index terms : {Index{1}, Index{2}}) {
      const LaSympNet net(1, 3, 5, terms);
      Vector theta(net.n_params()), h(kN);
      fill(theta.data(), theta.size(), 0.5);
      for (Index j = 0; j < kN; ++j) h(j) = 0.05 + 0.3 * std::abs(normal(gen));
      Matrix q(1, kN), p(1, kN), gq(1, kN), gp(1, kN);
      fill(q.data(), kN, 1.0);
      fill(p.data(), kN, 1.0);
      fill(gq.data(), kN, 1.0);
      fill(gp.data(), kN, 1.0);
      Matrix q2 = q, p2 = p, gq2 = gq, gp2 = gp;
      ForwardCache c1, c2;
      reserve_slots(c2, net.cache_slots());
      net.flow_scalar_portable(theta, q, p, h, &c1, 0);
      if (!detail::la_scalar_flow_simd(net.scalar_core(), theta.data(), q2.data(), p2.data(),
                                       h.data(), kN, &c2.mats, 0) ||
          !same(q, q2) || !same(p, p2) || c1.mats.size() != c2.mats.size()) {
        return false;
      }
      for (std::size_t i = 0; i < c1.mats.size(); ++i) {
        if (!same(c1.mats[i], c2.mats[i])) return false;
      }
      Vector g1 = Vector::Constant(net.n_params(), 0.25), g2 = g1;
      net.flow_backward_scalar_portable(theta, c1, 0, h, gq, gp, g1);
      if (!detail::la_scalar_backward_simd(net.scalar_core(), theta.data(), c1.mats, 0, h.data(),
                                           kN, gq2.data(), gp2.data(), g2.data()) ||
          !same(gq, gq2) || !same(gp, gp2) || !same(g1, g2)) {
        return false;
      }
    }
    return true;
  }();
  return agree;
}

}  // namespace csympnet
