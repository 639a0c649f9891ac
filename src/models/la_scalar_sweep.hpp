// Internal to src/models: LA-SympNet's d = 1 sweeps (LaSympNet::flow_scalar and
// flow_backward_scalar) as AVX-512 kernels that give the portable code's results to the bit.
//
// Why they can: at d = 1 every unit of the sweep is an elementwise update of 1 x N rows (kick
// p += (s q) τ, drift, bias, activation), and the portable code evaluates each element with
// separate IEEE multiplies and adds (SSE2, no FMA). The kernels perform the same operations in
// the same order, eight samples per instruction, holding the whole row of q and p (or of their
// gradients) in registers across units. The parameter gradients that the portable code sums
// sequentially over the samples (the shears' 2 Σ_j g_j h_j src_j, the biases' and the
// amplitudes') are summed in the same order, but four sums per instruction: the sweep writes
// the products, four columns are transposed so that one register holds four columns at one
// sample, and the running sums advance one sample at a time (column_sums.hpp).
//
// Files: la_scalar_sweep.cpp (the forward sweep and la_scalar_simd_supported()),
// la_scalar_backward.cpp (the backward sweep), la_scalar_block.hpp (what both share),
// la_scalar_check.cpp (LaSympNet::scalar_simd_in_use(), the check against the portable code).
#pragma once

#include <cstddef>
#include <vector>

#include "csympnet/core/types.hpp"

namespace csympnet::detail {

// An LA(layers, sublayers) core at d = 1 with θ in la_sympnet.hpp's layout: module k starts at
// k (sublayers + 3) with its sublayers' A, then b_p, b_q and (k < layers − 1) the activation
// amplitude; with step polynomials (poly), the coefficients follow at coef0 (linear sublayers
// module-major, then the activation modules).
struct LaScalarCore {
  Index layers = 0;
  Index sublayers = 0;
  bool poly = false;
  Index coef0 = 0;
};

// True when the kernels run on this machine (AVX-512F and VL and the portable SSE2 build, with
// sigmoid_simd's kernel usable too). LaSympNet also checks them against its portable code once.
bool la_scalar_simd_supported();

// Ψ_h in place on the rows q, p (n values each, step h_j for sample j). When mats is not null,
// mats[slot0 + u] (resized to 1 x n) receives the input of every linear sublayer and σ of every
// activation module, in application order, as LaSympNet::flow records them. Returns false,
// writing nothing, unless la_scalar_simd_supported() and n >= 1.
bool la_scalar_flow_simd(const LaScalarCore& core, const double* theta, double* q, double* p,
                         const double* h, Index n, std::vector<Matrix>* mats, std::size_t slot0);

// Reverse mode of la_scalar_flow_simd() from what it recorded: gq, gp (n values each) hold
// dL/d(q_out, p_out) on entry and dL/d(q_in, p_in) on exit; grad += dL/dθ. Same conditions.
bool la_scalar_backward_simd(const LaScalarCore& core, const double* theta,
                             const std::vector<Matrix>& mats, std::size_t slot0, const double* h,
                             Index n, double* gq, double* gp, double* grad);

}  // namespace csympnet::detail
