// Internal to src: σ over a contiguous array, to
// the bit as the portable build's Eigen evaluation (src/models/activation.hpp, sigmoid_to)
// computes it, eight elements per instruction (sigmoid_avx512.cpp) or four (sigmoid_avx2.cpp).
#pragma once

#include "csympnet/core/types.hpp"

namespace csympnet::kernels {

// σ of the n contiguous values at x into out, bit-identical to the portable Eigen path.
// Returns false (writing nothing) when the kernel does not run now (registry.hpp).
bool sigmoid_simd(const double* x, double* out, Index n);

// The same without asking the registry, for kernels built on it (the d = 1 forward sweep) and
// for self-checks; only where the sigmoid family (Family::kSigmoid, or kSigmoidAvx2 for the
// second) is available().
void sigmoid_kernel(const double* x, double* out, Index n);
void sigmoid_kernel_avx2(const double* x, double* out, Index n);

// σ of the element pairs [i, i + count) with Eigen's own SSE2 packets: the portable code, to
// which both kernels hand the pairs they do not reproduce themselves (count even).
void sigmoid_pairs_eigen(const double* x, double* out, Index i, Index count);

}  // namespace csympnet::kernels
