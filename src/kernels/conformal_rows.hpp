// Internal to src: CSympNet-ID's elementwise passes over the rows of a d = 1 batch, with
// AVX-512 where it runs (src/kernels/conformal_rows_avx512.cpp), AVX2 where AVX-512 does not
// (conformal_rows_avx2.cpp). Each output element is one
// copy or the same IEEE products and sums, in the same order, as the portable loops of
// csympnet_id.cpp, so results are bit-identical; only the number of elements per instruction
// changes. Each returns false, writing nothing, when the kernels do not run here.
#pragma once

#include "csympnet/core/types.hpp"

namespace csympnet::kernels {

// z is 2 x n (column-major): q_j = z(0, j), p_j = z(1, j) · a_j and, if p_raw is not null,
// p_raw_j = z(1, j).
bool split_scaled_rows_simd(const double* z, Index n, const double* a, double* q, double* p,
                            double* p_raw);

// out is 2 x n (column-major): out(0, j) = q_j, out(1, j) = p_j · a_j.
bool join_scaled_rows_simd(const double* q, const double* p, const double* a, Index n, double* out);

// The terms of the β gradient, dz 2 x n (column-major):
//   terms_j = ((dz(1, j) · p_core_j + gp_j · p_in_j) · h_j) · a_j.
bool damping_terms_simd(const double* dz, const double* p_core, const double* gp,
                        const double* p_in, const double* h, const double* a, Index n,
                        double* terms);

// The AVX2 forms of the three, without asking the registry (only where
// Family::kConformalRowsAvx2 is available()).
void split_scaled_rows_avx2(const double* z, Index n, const double* a, double* q, double* p,
                            double* p_raw);
void join_scaled_rows_avx2(const double* q, const double* p, const double* a, Index n, double* out);
void damping_terms_avx2(const double* dz, const double* p_core, const double* gp,
                        const double* p_in, const double* h, const double* a, Index n,
                        double* terms);

}  // namespace csympnet::kernels
