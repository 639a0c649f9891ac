// Internal to src: LA-SympNet's d = 1 sweeps (what LaSympNet::flow and flow_backward run at
// d = 1) as AVX-512 or AVX2 kernels that give the portable code's results to the bit.
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
// The AVX2 forms do the same four samples per instruction, for machines without AVX-512.
//
// Files: d1_forward_avx512.cpp and d1_forward_avx2.cpp (the forward sweep),
// d1_backward_avx512.cpp and d1_backward_avx2.cpp (the backward sweep), d1_block.hpp (what they
// share); src/models/la_d1_check.cpp supplies each form's self-check against LA-SympNet's
// portable d = 1 loops.
#pragma once

#include "csympnet/core/types.hpp"

namespace csympnet::kernels {

// An LA(layers, sublayers) core at d = 1 with θ in la_sympnet.hpp's layout: module k starts at
// k (sublayers + 3) with its sublayers' A, then b_p, b_q and (k < layers − 1) the activation
// amplitude; with step polynomials (poly), the coefficients follow at coef0 (linear sublayers
// module-major, then the activation modules).
struct D1Core {
  Index layers = 0;
  Index sublayers = 0;
  bool poly = false;
  Index coef0 = 0;
};

// Ψ_h in place on the rows q, p (n values each, step h_j for sample j). When `steps` is not
// null it points to an array of one Matrix per recorded unit (layers · sublayers + layers − 1),
// which receive (resized to 1 x n) the input of every linear sublayer and σ of every activation
// module, in application order, as LaSympNet::flow records them. Returns false, writing
// nothing, unless a d1_sweeps form runs now (registry.hpp; AVX-512 first, then AVX2) and n >= 1.
bool d1_flow_simd(const D1Core& core, const double* theta, double* q, double* p, const double* h,
                  Index n, Matrix* steps);

// Reverse mode of d1_flow_simd() from the rows it recorded in `steps`: gq, gp (n values each)
// hold dL/d(q_out, p_out) on entry and dL/d(q_in, p_in) on exit; grad += dL/dθ. Same
// conditions.
bool d1_backward_simd(const D1Core& core, const double* theta, const Matrix* steps, const double* h,
                      Index n, double* gq, double* gp, double* grad);

// The same two without asking the registry, for the family's self-check (which the model
// supplies: the reference is its own portable loops). Only where the CPU has AVX-512F and VL
// and the sigmoid family is available; false where not built.
bool d1_flow_kernel(const D1Core& core, const double* theta, double* q, double* p, const double* h,
                    Index n, Matrix* steps);
bool d1_backward_kernel(const D1Core& core, const double* theta, const Matrix* steps,
                        const double* h, Index n, double* gq, double* gp, double* grad);

// The AVX2 forms of the two, likewise for the AVX2 form's self-check: only where the CPU has AVX2
// and Family::kSigmoidAvx2 is available; false where not built.
bool d1_flow_kernel_avx2(const D1Core& core, const double* theta, double* q, double* p,
                         const double* h, Index n, Matrix* steps);
bool d1_backward_kernel_avx2(const D1Core& core, const double* theta, const Matrix* steps,
                             const double* h, Index n, double* gq, double* gp, double* grad);

}  // namespace csympnet::kernels
