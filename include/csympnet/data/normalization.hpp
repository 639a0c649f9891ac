// Units and offsets of a user's data, removed before fitting and put back after
// (docs/derivations.md, "Normalisation that keeps the structure").
//
// A state z = (q, p) becomes ẑ = ((q − s) / α, p / β) with per-degree-of-freedom scales such
// that α_i β_i = c for every i, and a step h becomes ĥ = h / τ. The linear part N = diag(1/α,
// 1/β) satisfies Nᵀ J N = J / c, so N conjugates a conformally symplectic map into one with
// the same factor, and a shift of q changes no Jacobian: the model fitted to ẑ, mapped back,
// is exactly conformally symplectic in the user's coordinates, and γ = γ̂_normalised / τ.
// Scaling every q by one constant and every p by another, shifting q, or scaling time leaves
// ẑ and ĥ unchanged up to rounding, so the fit does not depend on them.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/types.hpp"
#include "csympnet/data/dataset.hpp"

namespace csympnet {

struct Normalization {
  Vector q_shift;           // s, length d
  Vector q_scale;           // α, length d
  Vector p_scale;           // β = c / α, length d
  double time_scale = 1.0;  // τ
  Index d() const { return q_shift.size(); }
  // Throws Error (prefixed by `where`) unless all scales are positive and finite, the shifts
  // finite, and α_i β_i equal to within 1e-12 relative for every i.
  void validate(const std::string& where = "normalization") const;
  Matrix to_normal(const Matrix& z) const;     // 2d × N, user units → normalised
  Matrix from_normal(const Matrix& zn) const;  // the inverse
  // The diagonal of N⁻¹ (α then β), 2d: user-unit change per normalised unit.
  Vector unit() const;
};
void to_json(nlohmann::json& j, const Normalization& n);
void from_json(const nlohmann::json& j, Normalization& n);

// The identity for d degrees of freedom.
Normalization identity_normalization(Index d);

// From the states of trajectories (all their points) and the steps between them: s = the
// mean of q; per dof i with spreads σ_qi, σ_pi (standard deviations), α_i = √(c σ_qi / σ_pi)
// and β_i = c / α_i with c = the geometric mean of σ_qi σ_pi, so that the normalised q_i and
// p_i have the same spread √(σ_qi σ_pi / c); τ = the median step. Throws Error naming the
// coordinate that does not vary.
Normalization fit_normalization(const std::vector<Trajectory>& trajs);
// The same from pairs (their z0 and z1 as states, their h as steps).
Normalization fit_normalization(const PairSet& pairs);

std::vector<Trajectory> normalize(const Normalization& n, const std::vector<Trajectory>& trajs);
PairSet normalize(const Normalization& n, const PairSet& pairs);

}  // namespace csympnet
