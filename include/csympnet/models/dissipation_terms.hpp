// The dissipation terms of the Hamiltonian-library core beside its conformal factor γ
// (docs/derivations.md, "Dry friction and drag"): forces on one momentum p_i with q held fixed,
// each with its exact flow over a time τ in closed form.
//
//   coulomb(pI)   ṗ_i = −μ sign(p_i)      p ← sign(p)·max(|p| − μτ, 0)
//   drag(pI)      ṗ_i = −c p_i |p_i|      p ← p / (1 + c|p|τ)
//
// The rate (μ or c) is |θ_k| of the map's parameter, as γ = |β|: positive for every θ, and
// exactly 0 at θ_k = 0, where each flow is the identity to the bit.
#pragma once

#include <string>
#include <vector>

#include "csympnet/core/types.hpp"

namespace csympnet {

enum class DissipationKind { kCoulomb, kDrag };

struct DissipationTerm {
  DissipationKind kind = DissipationKind::kCoulomb;
  Index i = 0;  // the coordinate whose momentum it acts on, 0-based
  bool operator==(const DissipationTerm&) const = default;
};

// "coulomb(p1)", "drag(p2)": 1-based, as users number coordinates.
std::string dissipation_name(const DissipationTerm& t);
// "coulomb" or "drag".
std::string dissipation_kind_name(DissipationKind kind);
// The inverse of dissipation_name() for d coordinates; throws Error naming `where`, the text
// and the accepted forms.
DissipationTerm parse_dissipation(const std::string& name, Index d, const std::string& where);

// One exact flow of a term over τ (τ < 0: the flow backward in time, as the negative stage
// weights of a triple jump need) from p, at rate r ≥ 0: the new p and its derivatives by p and
// by r. Coulomb in the stick set |p| ≤ rτ (τ > 0) gives p = 0 with both derivatives 0 (the
// clamp is flat there; at the kink |p| = rτ the stick side is taken). Drag backward in time
// blows up at 1 + r|p|τ = 0: past it the result is NaN, which the fit's LM rejects as it
// rejects any non-finite trial.
struct FlowStep {
  double p = 0.0;
  double dp = 1.0;     // ∂p_new/∂p
  double drate = 0.0;  // ∂p_new/∂r
};
FlowStep dissipation_flow(DissipationKind kind, double p, double rate, double tau);

}  // namespace csympnet
