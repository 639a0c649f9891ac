// The vector-field baselines of the paper (docs/protocol.md, "Baselines"); built by
// make_vector_field_model(). With n = 2d, w the width, H and D scalar MLPs n → w → w → 1:
//
//   "ode"    f = MLP(z), an MLP n → w → w → n
//   "dhnn"   f = J_θ ∇H + ∇D
//   "dhnn2"  f = J_θ ∇H + (0, −γ̂ p)
//   "phnn"   f = (J_θ − L Lᵀ) ∇H
//   "phnn2"  f = (J_θ − γ̂ diag(0, I)) ∇H,     γ̂ = |β| in dhnn2 and phnn2.
//
// Layout of θ (docs/baselines.md):
//   ode:    [MLP]
//   dhnn:   [θ_H | θ_D | J_θ]
//   dhnn2:  [θ_H | J_θ | β]        phnn2: same
//   phnn:   [θ_H | J_θ | L]
// with J_θ and L n x n, column-major. β is the last entry (damping_param_index()).
// Derivations of field_backward and field_jacobian: docs/derivations.md.
#pragma once

#include <string>

#include "csympnet/models/vector_field_model.hpp"
#include "mlp.hpp"

namespace csympnet {

class OdeField final : public VectorFieldModel {
 public:
  // Throws Error unless d, width >= 1.
  OdeField(Index d, Index width);

  std::string type() const override { return "ode"; }
  Index dim() const override { return 2 * d_; }
  Index n_params() const override { return net_.n_params(); }
  void init_params(Rng& rng, ParamsRef theta) const override;

  Matrix field(ConstParams theta, const Matrix& Z) const override;
  void field_backward(ConstParams theta, const Matrix& Z, const Matrix& G,
                      ParamsRef grad) const override;
  Matrix field_jacobian(ConstParams theta, const Vector& z) const override;
  nlohmann::json hyperparams() const override;

 private:
  Index d_;
  Index width_;
  Mlp net_;
};

// How the non-conservative part of an H-based field is built.
enum class Dissipation {
  kNetwork,          // "dhnn":  + ∇D, D a second scalar MLP
  kMomentumDamping,  // "dhnn2": + (0, −γ̂ p)
  kPortMatrix,       // "phnn":  − L Lᵀ ∇H
  kPortDamping,      // "phnn2": − γ̂ diag(0, I) ∇H
};

// The four H-based models. J_θ is a trainable n x n block of θ initialised to the canonical
// J; with freeze_structure the field uses the canonical J and ignores those entries (they
// stay in θ so that the parameter count does not change, and their gradient is exactly 0).
class HamiltonianField final : public VectorFieldModel {
 public:
  static constexpr double kDefaultBetaInit = 0.1;
  // L ~ N(0, kPortInitStd²) entrywise: small (R = LLᵀ ≈ 1e-4 at the start) but not 0,
  // where ∂(LLᵀ)/∂L vanishes and L would never train.
  static constexpr double kPortInitStd = 0.01;

  // Throws Error unless d, width >= 1 and, for the γ̂ models, beta_init is finite and ≠ 0.
  HamiltonianField(Dissipation kind, Index d, Index width, double beta_init = kDefaultBetaInit,
                   bool freeze_structure = false);

  std::string type() const override;
  Index dim() const override { return 2 * d_; }
  Index n_params() const override { return n_params_; }
  void init_params(Rng& rng, ParamsRef theta) const override;

  Matrix field(ConstParams theta, const Matrix& Z) const override;
  void field_backward(ConstParams theta, const Matrix& Z, const Matrix& G,
                      ParamsRef grad) const override;
  Matrix field_jacobian(ConstParams theta, const Vector& z) const override;

  std::optional<double> damping_rate(ConstParams theta) const override;
  std::optional<Index> damping_param_index() const override;
  nlohmann::json hyperparams() const override;

  Dissipation kind() const { return kind_; }
  bool freeze_structure() const { return freeze_structure_; }
  // Offsets of the blocks of θ (see the layout above); -1 when the model has no such block.
  Index h_offset() const { return 0; }
  Index d_offset() const { return kind_ == Dissipation::kNetwork ? h_.n_params() : -1; }
  Index structure_offset() const { return structure_offset_; }
  Index port_offset() const;
  Index beta_offset() const;

 private:
  bool has_beta() const;
  // The structure matrix the field uses: J_θ from θ, or the canonical J when frozen.
  Eigen::Map<const Matrix> structure(ConstParams theta) const;
  // M with f = M ∇H (+ ∇D or (0, −γ̂p)): J_θ, J_θ − LLᵀ, or J_θ − γ̂ diag(0, I).
  Matrix effective_structure(ConstParams theta) const;

  Dissipation kind_;
  Index d_;
  Index width_;
  double beta_init_;
  bool freeze_structure_;
  Mlp h_;  // H, and D too (same shape) for dhnn
  Index structure_offset_;
  Index n_params_;
  Matrix canonical_;
};

}  // namespace csympnet
