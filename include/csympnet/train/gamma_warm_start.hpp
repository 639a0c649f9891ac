// A closed-form estimate γ₀ of the damping rate from the data alone, used as CSympNet-ID's
// initial β (docs/identification.md, "Closed-form warm start").
//
// For dz/dt = J∇H(z) − γ (0, p), the divergence of the field is −dγ at every z, so
//   (a) the flow map Φ_h is conformally symplectic: det DΦ_h = λ^d, λ = e^{−γh};
//   (b) tr Df = −dγ everywhere.
// Two least-squares estimators follow:
//   "det":      per group of pairs sharing one step h, fit z1 ≈ A z0 + c; then
//               log det A = −dγh, combined over groups by least squares in h.
//               Exact (up to rounding) for linear systems, whose flow is affine.
//   "midpoint": fit (z1 − z0)/h ≈ M (z0 + z1)/2 + c over all pairs, any steps; then
//               γ₀ = −tr M / d. Biased by O(h²) (the midpoint rule) and, for nonlinear
//               fields, by the gap between the least-squares slope and the mean Jacobian.
// Both are biased upwards by noise in z0 (errors in variables shrink the fitted slope).
#pragma once

#include <string>
#include <vector>

#include "csympnet/data/dataset.hpp"

namespace csympnet {

// The estimator: kAuto (kDet when at least 90% of the pairs fall in equal-step groups of at
// least 2(2d + 1) pairs each, else kMidpoint), kDet or kMidpoint. Spelt "auto", "det",
// "midpoint" (reports write the one used).
enum class WarmStartMethod { kAuto, kDet, kMidpoint };
std::string to_string(WarmStartMethod m);
const std::vector<std::string>& warm_start_method_names();  // in enum order
// Refuses any other text with an OptionError for `key` naming the accepted spellings.
WarmStartMethod parse_warm_start_method(const std::string& text,
                                        const char* key = "warm_start_method");

struct GammaWarmStart {
  double gamma = 0.0;  // γ₀ (may be ≤ 0 on data with no visible damping)
  WarmStartMethod method = WarmStartMethod::kDet;  // the one used: kDet or kMidpoint
  Index groups = 0;  // step-size groups used by kDet (0 for kMidpoint)
};

// Throws Error naming the method if it cannot be applied (too few pairs, singular fit).
GammaWarmStart gamma_warm_start(const PairSet& pairs,
                                WarmStartMethod method = WarmStartMethod::kAuto);

}  // namespace csympnet
