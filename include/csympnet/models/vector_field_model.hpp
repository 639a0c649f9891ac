// A learned vector field  dz/dt ≈ f_θ(z)  with a flat parameter vector θ. Its one-step map is
// induced by integrating f (integrators/dopri5.hpp). Trained on the midpoint loss
//   L(θ) = (1/N) Σ_i ‖(z1_i − z0_i)/h_i − f_θ((z0_i + z1_i)/2)‖²  (train/midpoint_loss.hpp).
//
// Models (docs/protocol.md, "Baselines"): "ode" (MLP field), "dhnn" (J_θ∇H + ∇D), "dhnn2"
// (J_θ∇H + (0, −γ̂p)), "phnn" ((J_θ − LLᵀ)∇H), "phnn2" ((J_θ − γ̂ diag(0, I))∇H).
#pragma once

#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "csympnet/core/rng.hpp"
#include "csympnet/core/types.hpp"

namespace csympnet {

class VectorFieldModel {
 public:
  virtual ~VectorFieldModel() = default;

  virtual std::string type() const = 0;  // "ode", "dhnn", "dhnn2", "phnn", "phnn2"
  virtual Index dim() const = 0;         // 2d
  virtual Index n_params() const = 0;
  virtual void init_params(Rng& rng, ParamsRef theta) const = 0;

  // f_θ at every column of Z (2d x N).
  virtual Matrix field(ConstParams theta, const Matrix& Z) const = 0;
  // grad += ∂/∂θ ⟨G, f_θ(Z)⟩ for an upstream G (2d x N). For the H-based models this needs
  // ∂θ ∇z H, computed by reverse mode through a forward-mode tangent pass.
  virtual void field_backward(ConstParams theta, const Matrix& Z, const Matrix& G,
                              ParamsRef grad) const = 0;
  // Df_θ(z), 2d x 2d (used by the variational equation of the induced map).
  virtual Matrix field_jacobian(ConstParams theta, const Vector& z) const = 0;

  // γ̂ for DHNN2 and pHNN2 (γ̂ = |β|), and the position of β in θ.
  virtual std::optional<double> damping_rate(ConstParams /*theta*/) const { return std::nullopt; }
  virtual std::optional<Index> damping_param_index() const { return std::nullopt; }

  // Rebuilds the architecture through make_vector_field_model().
  virtual nlohmann::json hyperparams() const = 0;
};

// From hyperparams JSON, e.g. {"type": "dhnn2", "d": 1, "width": 32, "beta_init": 0.1,
// "freeze_structure": false}. Throws Error naming a bad or missing key.
std::unique_ptr<VectorFieldModel> make_vector_field_model(const nlohmann::json& spec);

}  // namespace csympnet
