// The self-check of the d = 1 sweep kernels (src/kernels/d1_sweeps.hpp), which la_sympnet.cpp
// supplies to the kernels registry: the kernels are used only if, on this machine, they
// reproduce LA-SympNet's own d = 1 loops to the bit on random values, so that a compiler or a
// CPU that evaluated some operation differently costs speed, not results.
#include <cmath>
#include <cstring>
#include <random>

#include "../kernels/d1_sweeps.hpp"
#include "../kernels/registry.hpp"
#include "la_sympnet.hpp"

namespace csympnet::detail {

bool la_d1_kernels_agree() {
  return la_d1_form_agrees(kernels::Family::kD1Sweeps);
}

bool la_d1_avx2_kernels_agree() {
  return la_d1_form_agrees(kernels::Family::kD1SweepsAvx2);
}

bool la_d1_form_agrees(kernels::Family form) {
  const bool avx2 = form == kernels::Family::kD1SweepsAvx2;
  const auto flow = avx2 ? kernels::d1_flow_kernel_avx2 : kernels::d1_flow_kernel;
  const auto backward = avx2 ? kernels::d1_backward_kernel_avx2 : kernels::d1_backward_kernel;
  // σ's kernel of the same instruction set is part of the forward sweep: without it the sweeps
  // do not run.
  if (!kernels::available(avx2 ? kernels::Family::kSigmoidAvx2 : kernels::Family::kSigmoid)) {
    return false;
  }
  // On random values, both sweeps with and without step polynomials.
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
    LaSympNet::FlowContext c1, c2;
    c1.steps.resize(net.recorded_steps());
    c2.steps.resize(net.recorded_steps());
    net.flow_d1_rows(theta, q, p, h, &c1);
    if (!flow(net.d1_core(), theta.data(), q2.data(), p2.data(), h.data(), kN, c2.steps.data()) ||
        !same(q, q2) || !same(p, p2)) {
      return false;
    }
    for (std::size_t i = 0; i < c1.steps.size(); ++i) {
      if (!same(c1.steps[i], c2.steps[i])) return false;
    }
    Vector g1 = Vector::Constant(net.n_params(), 0.25), g2 = g1;
    net.flow_backward_d1_rows(theta, c1, h, gq, gp, g1);
    if (!backward(net.d1_core(), theta.data(), c1.steps.data(), h.data(), kN, gq2.data(),
                  gp2.data(), g2.data()) ||
        !same(gq, gq2) || !same(gp, gp2) || !same(g1, g2)) {
      return false;
    }
  }
  return true;
}

}  // namespace csympnet::detail
