// Internal to src: the conformal factors a_j = exp(c h_j) of CSympNet-ID, to the bit as
// the portable build's Eigen expression `(c * h.array()).exp()` computes them, eight at a time
// with AVX-512 where it runs (src/kernels/scaled_exp_avx512.cpp), four at a time with AVX2 where
// AVX-512 does not (scaled_exp_avx2.cpp).
#pragma once

#include "csympnet/core/types.hpp"

namespace csympnet::kernels {

// out[j] = exp(c · h[j]) for j < n, bit-identical to Eigen's evaluation of
// `Vector out = (c * h.array()).exp()` in the portable build (Eigen's packet exp on element
// pairs, std::exp on an odd last element). Returns false, writing nothing, when no such kernel
// runs now (registry.hpp).
bool scaled_exp_simd(double c, const double* h, double* out, Index n);

// The AVX2 form of scaled_exp_simd() without asking the registry (only where
// Family::kScaledExpAvx2 is available()).
void scaled_exp_kernel_avx2(double c, const double* h, double* out, Index n);

// exp(c h) for the element pairs [i, i + count) with Eigen's own SSE2 packets (count even): the
// portable code, to which both kernels hand the pairs they do not reproduce themselves.
void scaled_exp_pairs_eigen(double c, const double* h, double* out, Index i, Index count);

}  // namespace csympnet::kernels
