// Internal to src: the conformal factors a_j = exp(c h_j) of CSympNet-ID, to the bit as
// the portable build's Eigen expression `(c * h.array()).exp()` computes them, eight at a time
// with AVX-512 where it runs (src/kernels/scaled_exp_avx512.cpp).
#pragma once

#include "csympnet/core/types.hpp"

namespace csympnet::kernels {

// out[j] = exp(c · h[j]) for j < n, bit-identical to Eigen's evaluation of
// `Vector out = (c * h.array()).exp()` in the portable build (Eigen's packet exp on element
// pairs, std::exp on an odd last element). Returns false, writing nothing, when no such kernel
// runs now (registry.hpp).
bool scaled_exp_simd(double c, const double* h, double* out, Index n);

}  // namespace csympnet::kernels
