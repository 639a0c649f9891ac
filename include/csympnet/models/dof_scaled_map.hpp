// A map with learned per-degree-of-freedom momentum scales, for data with velocities (or any
// per-dof units of p) instead of canonical momenta: Φ(z) = D⁻¹ Φ̂(D z), D = diag(1 on q,
// μ_i on p_i), μ_1 = 1 and μ_i = e^{ν_i} learned (d − 1 parameters after the wrapped map's).
//
// If z = (q, v) with v_i = p_i / m_i, the canonical map is conformally symplectic and the map in
// (q, v) is D_m⁻¹ Φ_p D_m with D_m = diag(1, m): exactly this family, with μ_i = m_i / m_1. It is
// conformally symplectic for the form Dᵀ J D (Σ μ_i dq_i ∧ dv_i) with the same factor e^{−γh};
// S_a commutes with D, so Φ = S_a ∘ (D⁻¹ Ψ D) ∘ S_a with D⁻¹ Ψ D symplectic for that form.
// docs/derivations.md, "Velocities instead of momenta".
#pragma once

#include <memory>

#include "csympnet/models/one_step_map.hpp"

namespace csympnet {

class DofScaledMap final : public OneStepMap {
 public:
  explicit DofScaledMap(std::unique_ptr<OneStepMap> inner);

  std::string type() const override { return inner_->type(); }
  Index dim() const override { return inner_->dim(); }
  Index n_params() const override { return inner_->n_params() + d_ - 1; }
  void init_params(Rng& rng, ParamsRef theta) const override;
  // What forward() keeps for backward(): the wrapped map's cache and the scaled p rows.
  struct Context final : ForwardContext {
    const char* owner() const override { return "dof-scaled map"; }
    ForwardCache inner;  // the wrapped map's context
    Matrix p_scaled;     // μ ⊙ p of the input, as the wrapped map read it (d x N)
    Matrix p_out;        // the p rows of the output, after the division by μ (d x N)
  };

  Matrix forward(ConstParams theta, const Matrix& Z, const Vector& h,
                 ForwardCache* cache) const override;
  void backward(ConstParams theta, const ForwardCache& cache, const Matrix& dZout, ParamsRef grad,
                Matrix* dZin) const override;
  Matrix jacobian(ConstParams theta, const Vector& z, double h) const override;
  std::optional<double> damping_rate(ConstParams theta) const override {
    return inner_->damping_rate(theta.head(inner_->n_params()));
  }
  std::optional<Index> damping_param_index() const override {
    return inner_->damping_param_index();
  }
  // The wrapped map's spec with "dof_scales": "learned".
  nlohmann::json hyperparams() const override;

  // μ (length d, μ_1 = 1) at θ.
  Vector scales(ConstParams theta) const;
  // The wrapped map; its parameters are the first inner().n_params() of θ.
  const OneStepMap& inner() const { return *inner_; }

 private:
  std::unique_ptr<OneStepMap> inner_;
  Index d_;
};

}  // namespace csympnet
