// The Hamiltonian-library map (docs/derivations.md, "The Hamiltonian-library core"): the
// damped flow of
//
//   H(q, p) = ½ pᵀ W p + V(q),   V(q) = Σ_k c_k φ_k(q)   (terms: models/potential_library.hpp),
//
// W = M⁻¹ symmetric (or diagonal), advanced over a data step h by n substeps of a composition
// of conformal Strang steps. One conformal Strang step of length τ:
//
//   p ← e^{−γτ/2} p;  p ← p − (τ/2)∇V(q);  q ← q + τ W p;  p ← p − (τ/2)∇V(q);  p ← e^{−γτ/2} p.
//
// Each part is exactly symplectic or an exact momentum scaling, so the step is conformally
// symplectic with factor e^{−γτ}; it is symmetric and of second order for the damped flow. The
// stages of a step take τ = b_s h / n with the weights b_s of Yoshida's triple jump (order 4:
// three stages; order 6: nine), which sum to 1, so the map's factor is e^{−γh} exactly, at
// every parameter value (negative weights give factors above 1 that the others cancel).
//
// A difference term's argument weighs its coordinates by fixed scales (constructor).
//
// Dissipation terms beyond γ (models/dissipation_terms.hpp: Coulomb friction and quadratic
// drag on one momentum each). Drag enters every stage of length τ as its exact flows over τ/2
// on each side of the conformal Strang step, in term order before it and in reverse order after
// it (a palindrome, so the stage stays symmetric):
//
//   F_{τ/2} = f_K ∘ … ∘ f_1 (each over τ/2),   stage = F_{τ/2}ᵀ ∘ (conformal Strang step) ∘ F_{τ/2}
//
// Coulomb friction on p_i enters each kick instead: the kick's p_i is the exact flow over τ/2 of
// ṗ_i = −∂V/∂q_i − μ_i sign(p_i) with q fixed (coulomb_kick), so that a reversal or a stop
// inside a kick is resolved exactly and the map stays second order across reversals.
//
// With them the map is no longer conformally symplectic (docs/derivations.md, "Dry friction
// and drag"); without them (none given, or all rates 0) it is the map above to the bit.
//
// Known inputs (models/inputs.hpp; docs/derivations.md, "Known inputs"): H = H₀ − qᵀB u(t), B
// d × m. The input enters each kick as a force beside −∇V, evaluated at the kick's time in the
// step (σ_s h, σ_s the stage's start as a share of h: the kicks of the Strang step are at the
// stage's two ends):
//
//   p ← p − (τ/2)(∇V(q) − B u(t₀ + σ_s h));  q ← q + τ W p;
//   p ← p − (τ/2)(∇V(q) − B u(t₀ + σ_{s+1} h))
//
// within the momentum scalings. A kick is an exact symplectic flow for every u, so the map stays
// conformally symplectic with factor e^{−γh}; the step is the Strang splitting of the extended
// phase space (t advancing with the drift), symmetric, so the composition keeps its order for the
// forced flow with the held or interpolated input. Without inputs (m = 0), or with U absent, the
// map is the free map to the bit.
//
// Layout of θ: W (d(d+1)/2 entries of the lower triangle, row by row, for "full"; d for
// "diagonal"), the coefficients c_k in term order, the wavenumbers κ of the terms that have
// one in term order (sin and cos of one argument share one, at the first of them), β
// (γ̂ = |β|, as in CSympNet-ID), and after β one θ_k per dissipation term, its rate |θ_k|.
// Without dissipation terms β is last, as in every model file written before them. After those,
// B (d × m, row by row) when the map has inputs; without inputs θ is as before them.
//
// init_params draws nothing: W = I, c = ½ on each qI^2 and 0 elsewhere, κ = its term's
// starting sign, β = beta_init, each dissipation θ_k = kDissipationInit, B = 0.
#pragma once

#include <string>
#include <vector>

#include "csympnet/models/dissipation_terms.hpp"
#include "csympnet/models/inputs.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/models/potential_library.hpp"

namespace csympnet {

namespace library_detail {
class TangentStep;  // hamiltonian_library_tangents.cpp
}  // namespace library_detail

class HamiltonianLibraryMap final : public OneStepMap {
 public:
  // Throws Error on d < 1, no terms, a term out of range or repeated, an order other than
  // 2, 4, 6, substeps < 1, or a zero or non-finite beta_init.
  // `scales` (d positive values, empty: all 1) weigh the coordinates in a difference term:
  // its argument is s_i q_i − s_j q_j. The identification passes the normalisation's q scales
  // over their geometric mean, so that a difference of the user's coordinates stays one.
  // `dissipation`: terms repeated are refused, as are coordinates out of range.
  HamiltonianLibraryMap(Index d, std::vector<LibraryTerm> terms, int order, Index substeps,
                        bool full_mass, double beta_init, Vector scales = {},
                        std::vector<DissipationTerm> dissipation = {}, InputSpec inputs = {},
                        bool coulomb_in_kicks = true);

  // A dissipation rate's start (init_params): nonzero, since |θ| has no slope at 0.
  static constexpr double kDissipationInit = 1e-3;

  std::string type() const override { return "csympnet"; }
  Index dim() const override { return 2 * d_; }
  Index n_params() const override {
    return beta_index_ + 1 + static_cast<Index>(dissipation_.size()) + d_ * inputs_.m;
  }
  void init_params(Rng& rng, ParamsRef theta) const override;

  Matrix forward(ConstParams theta, const Matrix& Z, const Vector& h,
                 ForwardCache* cache) const override;
  void backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout, ParamsRef grad,
                Matrix* dZin) const override;
  Matrix jacobian(ConstParams theta, const Vector& z, double h) const override;
  Index n_inputs() const override { return inputs_.m; }
  Matrix forward_driven(ConstParams theta, const Matrix& Z, const Vector& h, const Matrix& U,
                        ForwardCache* cache) const override;
  Matrix jacobian_driven(ConstParams theta, const Vector& z, double h,
                         const Vector& u) const override;
  // Forward-mode step sensitivities (hamiltonian_library_tangents.cpp), dissipation terms and
  // inputs included.
  bool has_step_tangents() const override { return true; }
  void step_tangents(ConstParams theta, double h, const double* u, double* z, Matrix& t,
                     Index n_theta) const override;
  std::optional<double> damping_rate(ConstParams theta) const override;
  std::optional<Index> damping_param_index() const override { return beta_index_; }
  nlohmann::json hyperparams() const override;

  Index d() const { return d_; }
  const std::vector<LibraryTerm>& terms() const { return terms_; }
  const Vector& coordinate_scales() const { return scales_; }
  // The argument u of term k at q, and its gradient weights: ∂u/∂q_i, ∂u/∂q_j.
  double argument(Index k, const double* q) const;
  bool full_mass() const { return full_mass_; }
  Index substeps() const { return substeps_; }
  int order() const { return order_; }
  // Offsets into θ.
  Index mass_offset() const { return 0; }
  Index mass_size() const { return full_mass_ ? d_ * (d_ + 1) / 2 : d_; }
  Index coefficient_index(Index k) const { return mass_size() + k; }
  // −1 for a term without a wavenumber.
  Index wavenumber_index(Index k) const { return kappa_index_[static_cast<std::size_t>(k)]; }
  // W = M⁻¹ from θ (d x d, symmetric).
  Matrix inverse_mass(ConstParams theta) const;
  // Throws Error, naming `where` and the entries of θ, unless W is positive definite (a
  // kinetic energy ½ pᵀWp > 0 for every p ≠ 0): a model file's θ comes from outside, and a
  // zero or negative mass would roll out without a word.
  void check_inverse_mass(ConstParams theta, const std::string& where) const;
  // V(q) and ∇V(q) at θ.
  double potential(ConstParams theta, const double* q) const;
  // ∇V(q) at θ into g (d values).
  void gradient(ConstParams theta, const double* q, double* g) const;
  const std::vector<DissipationTerm>& dissipation() const { return dissipation_; }
  // θ's entry of dissipation term k (its rate is |θ|).
  Index dissipation_index(Index k) const { return beta_index_ + 1 + k; }
  const InputSpec& inputs() const { return inputs_; }
  // θ's entry of B(r, j) (r < d, j < m).
  Index input_index(Index r, Index j) const {
    return beta_index_ + 1 + static_cast<Index>(dissipation_.size()) + r * inputs_.m + j;
  }
  // B (d × m) from θ.
  Matrix input_matrix(ConstParams theta) const;
  // The stage weights b_s of one substep (they sum to 1).
  const std::vector<double>& stage_weights() const { return weights_; }
  // Whether Coulomb friction runs inside the kicks (core key "friction": "in_kicks", the
  // default) or as separate flows beside them, as drag ("split": model files written before
  // 2026-11-29, which carry no key, run so).
  bool coulomb_in_kicks() const { return coulomb_in_kicks_; }

  struct Context final : ForwardContext {
    const char* owner() const override { return "hamiltonian library"; }
    Vector h;
    // Per column, stages + 1 records of 3d + 2K values each (K dissipation terms), column
    // after column: per stage q, p as the conformal Strang step starts (after the opening
    // dissipation flows), ∇V(q), and the p_i each dissipation flow started from (the K opening
    // flows in order, then the K closing ones in order of application); the last record holds
    // the end state.
    std::vector<double> states;
    Matrix u;  // the inputs driving the pass (2m × N), or empty (no inputs: a free pass)
  };

 private:
  // One step_tangents call's stages (hamiltonian_library_tangents.cpp).
  friend class library_detail::TangentStep;

  // out += H(q) v, H = ∇²V.
  void hessian_times(ConstParams theta, const double* q, const double* v, double* out) const;
  // grad(θ_V) += s · ∂(∇V(q)·v)/∂θ_V.
  void add_gradient_params(ConstParams theta, const double* q, const double* v, double s,
                           ParamsRef grad) const;
  // W x into out.
  void mass_times(ConstParams theta, const double* x, double* out) const;
  Index stages_per_step() const { return substeps_ * static_cast<Index>(weights_.size()); }
  Index record_size() const { return 3 * d_ + 2 * static_cast<Index>(dissipation_.size()); }
  // Whether dissipation term k runs inside the kicks.
  bool in_kicks(Index k) const {
    return coulomb_of_[static_cast<std::size_t>(dissipation_[static_cast<std::size_t>(k)].i)] == k;
  }
  // μ_i of coordinate i's Coulomb friction when it runs inside the kicks, else 0.
  double coulomb_rate(ConstParams theta, Index i) const {
    const Index k = coulomb_of_[static_cast<std::size_t>(i)];
    return k < 0 ? 0.0 : std::abs(theta(dissipation_index(k)));
  }
  // The dissipation flows over τ/2 opening a stage (closing: false, the reverse order), on p;
  // `starts` (K values, may be null) receives the p_i each flow started from.
  void dissipate(ConstParams theta, double half_tau, bool closing, double* p, double* starts) const;
  // Their reverse mode: pb (the adjoint of p after them) becomes the adjoint before, grad
  // collects the rates' parameters.
  void dissipate_backward(ConstParams theta, double half_tau, bool closing, const double* starts,
                          double* pb, ParamsRef grad) const;

  // Work space of kick_backward.
  struct KickScratch {
    KickScratch(Index d, Index m)
        : plain(static_cast<std::size_t>(d)),
          force(static_cast<std::size_t>(d)),
          tmp(static_cast<std::size_t>(d)),
          work(static_cast<std::size_t>(m)) {}
    std::vector<double> plain, force, tmp, work;
  };
  // The reverse mode of one kick at q (time σ of the step, input column ucol or null): pb, the
  // adjoint of p after it, becomes the adjoint before it; qb and grad collect the force's
  // (∇V(q) and B u) and, with `fused`, each Coulomb rate's. `kicks` are the kicks' coulomb_kick
  // results on the coordinates with friction (the others are plain kicks of τ/2).
  void kick_backward(ConstParams theta, const std::vector<KickStep>& kicks, bool fused,
                     const double* q, double sigma, const double* ucol, double tau, double* pb,
                     double* qb, KickScratch& w, ParamsRef grad) const;
  // g −= B u(t₀ + σh) for one step's input column `u` (2m values); `work` holds m values.
  void add_force(ConstParams theta, const double* u, double sigma, double* g, double* work) const;
  // grad(B) += s · v u(t₀ + σh)ᵀ.
  void add_input_gradient(const double* u, double sigma, const double* v, double s, double* work,
                          ParamsRef grad) const;
  void check_inputs(const Matrix& U, Index n) const;

  Index d_;
  std::vector<LibraryTerm> terms_;
  int order_;
  Index substeps_;
  bool full_mass_;
  double beta_init_;
  std::vector<Index> kappa_index_;
  Index beta_index_;
  std::vector<double> weights_;
  Vector scales_;
  // Per term: ∂u/∂q_i and ∂u/∂q_j (0 for a single coordinate).
  std::vector<double> wi_, wj_;
  // The terms grouped by their argument (one coordinate, or one difference q_i − q_j): ∇²V is
  // Σ over the groups of (Σ of the group's c_k φ_k'') e eᵀ, e = ∂u/∂q, so the tangent step
  // takes one pass along its columns per group, not per term (hamiltonian_library_tangents.cpp).
  struct ArgumentGroup {
    Index i = 0, j = -1;
    double wi = 1.0, wj = 0.0;
  };
  std::vector<ArgumentGroup> groups_;
  std::vector<Index> group_of_;  // per term, its group in groups_
  std::vector<DissipationTerm> dissipation_;
  bool coulomb_in_kicks_ = true;
  // Per coordinate: the index k of its Coulomb term in dissipation_, or −1.
  std::vector<Index> coulomb_of_;
  InputSpec inputs_;
  // Per stage boundary s = 0 … stages of one step: its time as a share σ_s of h (σ_0 = 0,
  // σ_stages = 1); a stage of weight b runs from σ_s to σ_{s+1} = σ_s + b/n. Computed, not
  // stored: a model file may ask for millions of substeps (a table of them took 288 MB and
  // seconds to build and free at 4,000,000).
  double sigma(Index s) const;
  std::vector<double> within_;  // the weights' running sums within one substep, in order
};

// The core spec {"type": "library", "terms": [...], "order": 4, "substeps": n, "mass":
// "full"|"diagonal", "coordinate_scales": [...], "dissipation": [...]} read and checked for d
// coordinates: the one reading of it, by model files (make_model) and by the identification's given
// core. Throws Error naming `where`, the key and what was expected. "terms" may be absent (terms
// empty: the identification selects them; a model needs them).
struct LibrarySpec {
  std::vector<LibraryTerm> terms;
  int order = 4;
  Index substeps = 1;
  bool full_mass = true;
  Vector scales;  // empty: all 1
  // "dissipation": ["coulomb(p1)", "drag(p1)", ...]; absent: none.
  std::vector<DissipationTerm> dissipation;
  // "friction": "in_kicks" | "split" (absent: "split", what files without the key ran).
  bool coulomb_in_kicks = false;
  // "inputs": {"m": m, "hold": "foh"|"zoh", "B": "row-major"}; absent: none (m = 0).
  InputSpec inputs;
};
LibrarySpec read_library_spec(const nlohmann::json& spec, Index d, const std::string& where);

// A core spec's "dissipation" (the terms' names) and, with a Coulomb term, "friction": both
// erased first, written only when there are terms (a spec without them stays as it was).
void set_dissipation_spec(nlohmann::json& core, const std::vector<DissipationTerm>& terms,
                          bool coulomb_in_kicks = true);

}  // namespace csympnet
