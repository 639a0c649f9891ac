// The dissipation terms of the Hamiltonian-library core beside its conformal factor γ
// (docs/derivations.md, "Dry friction and drag"): forces on one momentum p_i with q held fixed,
// each with its exact flow over a time τ in closed form. The library map runs Coulomb friction
// inside its kicks (coulomb_kick, below) and drag beside them (dissipation_flow).
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

// The exact flow over τ of a kick with Coulomb friction on one momentum, q held fixed:
//   ṗ = f − μ sign(p)   (f the force −∂V/∂q_i, plus an input's, constant while q is fixed),
// in Filippov's sense: p moves at the constant rate f − μ sign(p); where it reaches 0 it stays
// there while |f| ≤ μ (the set-valued force f − μ[−1, 1] contains 0) and otherwise goes on
// with the other sign. τ < 0 is the flow backward in time (there friction feeds |p|, and p
// crosses 0 without sticking). At rate 0 it is the plain kick p + f τ to the bit. The
// library map runs its kicks through it for each coordinate with Coulomb friction
// (docs/derivations.md, "Dry friction and drag": second order across reversals, exact at rest).
// Derivatives of the new p by the start p, by f and by μ; all 0 where the flow ends stuck.
struct KickStep {
  double p = 0.0;
  double dp = 1.0;      // ∂p_new/∂p
  double dforce = 0.0;  // ∂p_new/∂f
  double drate = 0.0;   // ∂p_new/∂μ
};
KickStep coulomb_kick(double p, double force, double rate, double tau);

}  // namespace csympnet
