// SympNet: the symplectic core Ψ_h used on its own as a learned one-step map (the paper's
// structure-preserving but non-dissipative baseline).
//
// The cores (LaSympNet, GSympNet) already are OneStepMaps with type() "la" / "g". SympNet is a
// thin owner of one core that only renames it: type() "sympnet" and hyperparams
// {"type": "sympnet", "d": d, "core": {...}}, so that model files say which role the core
// plays. θ, its layout and its initialisation are exactly the core's.
#pragma once

#include <memory>

#include "symplectic_core.hpp"

namespace csympnet {

class SympNet final : public OneStepMap {
 public:
  // Throws Error if core is null.
  explicit SympNet(std::unique_ptr<SymplecticCore> core);

  const SymplecticCore& core() const { return *core_; }

  std::string type() const override { return "sympnet"; }
  Index dim() const override { return core_->dim(); }
  Index n_params() const override { return core_->n_params(); }
  void init_params(Rng& rng, ParamsRef theta) const override { core_->init_params(rng, theta); }
  Matrix forward(ConstParams theta, const Matrix& Z, const Vector& h,
                 ForwardCache* cache) const override {
    return core_->forward(theta, Z, h, cache);
  }
  void backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout, ParamsRef grad,
                Matrix* dZin) const override {
    core_->backward(theta, cache, dZout, grad, dZin);
  }
  Matrix jacobian(ConstParams theta, const Vector& z, double h) const override {
    return core_->jacobian(theta, z, h);
  }
  nlohmann::json hyperparams() const override;

 private:
  std::unique_ptr<SymplecticCore> core_;
};

}  // namespace csympnet
