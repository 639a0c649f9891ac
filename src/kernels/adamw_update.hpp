// Internal to src: AdamW's elementwise update (src/train/adamw.cpp), one pass over θ, m, v, g,
// through an AVX-512 kernel where it runs (registry.hpp) and Eigen's expressions elsewhere, to
// the same bits.
#pragma once

#include "csympnet/core/types.hpp"

namespace csympnet::kernels {

// The step's scalars, formed once per step by the optimiser.
struct AdamWScalars {
  double decay;       // 1 − lr wd
  double b1, c1;      // β1, 1 − β1
  double b2, c2;      // β2, 1 − β2
  double step_size;   // lr / (1 − β1ᵗ)
  double bias2_sqrt;  // √(1 − β2ᵗ)
  double eps;
};

// Per element i < n, in this order (θ_keep is not decayed; keep = −1: every element is):
//   θ ← θ decay,  m ← b1 m + c1 g,  v ← b2 v + c2 (g g),
//   θ ← θ − (step_size m) / (√v / bias2_sqrt + eps).
void adamw_update(const AdamWScalars& s, double* theta, double* m, double* v, const double* g,
                  Index n, Index keep);

// The same through Eigen's expressions only, whatever runs: the reference of the self-check.
void adamw_update_portable(const AdamWScalars& s, double* theta, double* m, double* v,
                           const double* g, Index n, Index keep);

}  // namespace csympnet::kernels
