// A one-step map in the user's units: Φ(z, h) = N⁻¹ Φ̂(N z, h / τ), with Φ̂ a map fitted to
// normalised data and N the affine change of units of data/normalization.hpp. Because
// Nᵀ J N = J / c, Φ is exactly as conformally symplectic as Φ̂, with γ = γ̂ / τ. Model files
// carry the normalisation as the spec key "normalization" beside the inner model's keys.
#pragma once

#include <memory>

#include "csympnet/data/normalization.hpp"
#include "csympnet/models/one_step_map.hpp"

namespace csympnet {

class NormalizedMap final : public OneStepMap {
 public:
  NormalizedMap(std::unique_ptr<OneStepMap> inner, Normalization normalization);

  std::string type() const override { return inner_->type(); }
  Index dim() const override { return inner_->dim(); }
  Index n_params() const override { return inner_->n_params(); }
  void init_params(Rng& rng, ParamsRef theta) const override { inner_->init_params(rng, theta); }
  Matrix forward(ConstParams theta, const Matrix& Z, const Vector& h,
                 ForwardCache* cache) const override;
  void backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout, ParamsRef grad,
                Matrix* dZin) const override;
  Matrix jacobian(ConstParams theta, const Vector& z, double h) const override;
  // Inputs pass through unchanged: they are in the user's units, which the inner map's B
  // absorbs (B_user = diag(β) B̂ / τ).
  Index n_inputs() const override { return inner_->n_inputs(); }
  Matrix forward_driven(ConstParams theta, const Matrix& Z, const Vector& h, const Matrix& U,
                        ForwardCache* cache) const override;
  Matrix jacobian_driven(ConstParams theta, const Vector& z, double h,
                         const Vector& u) const override;
  std::optional<double> damping_rate(ConstParams theta) const override;
  std::optional<Index> damping_param_index() const override {
    return inner_->damping_param_index();
  }
  // The inner model's spec with "normalization" added.
  nlohmann::json hyperparams() const override;

  const OneStepMap& inner() const { return *inner_; }
  const Normalization& normalization() const { return norm_; }

 private:
  std::unique_ptr<OneStepMap> inner_;
  Normalization norm_;
  Vector unit_;  // diag N⁻¹
};

}  // namespace csympnet
