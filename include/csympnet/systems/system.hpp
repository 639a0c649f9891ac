// Linearly damped separable Hamiltonian systems  dq/dt = ∂H/∂p,  dp/dt = -∂H/∂q - γ p,
// with H(q, p) = ½‖p‖² + V(q).  State z = (q, p), q first.
//
// Kinds (docs/protocol.md, "Systems"):
//   "oscillator"  V = ½ω²‖q‖²                                   (s1 with d = 1)
//   "chain"       V = (k/2) Σ_{i<d} (q_{i+1} − q_i)², free ends  (s2, s2-100)
//   "cubic"       V = ½ω²‖q‖² + α (Σ q_i)³                      (s3, s3-100)
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "csympnet/core/types.hpp"

namespace csympnet {

struct SystemSpec {
  std::string kind = "oscillator";  // "oscillator", "chain" or "cubic"
  int d = 1;                        // degrees of freedom; phase space is 2d
  double gamma = 0.05;              // damping rate γ ≥ 0
  double omega = 1.0;               // frequency ω (oscillator, cubic)
  double k = 1.0;                   // spring stiffness k (chain)
  double alpha = 0.005;             // cubic coefficient α (cubic)

  // Throws csympnet::Error naming the bad field and the expected range:
  // kind ∈ {oscillator, chain, cubic}; d ≥ 1; γ finite ≥ 0; ω, k, α finite;
  // ω > 0 for oscillator and cubic; k ≥ 0.
  void validate() const;
};

// JSON object {"kind", "d", "gamma", "omega", "k", "alpha"}. to_json writes every key.
// from_json requires "kind" and "d"; the constants are optional and keep their defaults when
// absent. Ill-typed values and unknown keys are rejected (a typo must not silently become a
// default), and the result is validated.
void to_json(nlohmann::json& j, const SystemSpec& s);
void from_json(const nlohmann::json& j, SystemSpec& s);

class System {
 public:
  explicit System(SystemSpec spec);  // validates

  const SystemSpec& spec() const { return spec_; }
  Index d() const { return spec_.d; }
  Index dim() const { return 2 * static_cast<Index>(spec_.d); }
  double gamma() const { return spec_.gamma; }

  // Potential V(q), its gradient and Hessian (q has length d).
  double potential(const Vector& q) const;
  Vector grad_potential(const Vector& q) const;
  Matrix hess_potential(const Vector& q) const;
  // Batched ∇V on the columns of Q (d x N); used by the reference integrator. Each column is
  // computed with the same operations in the same order as grad_potential, whatever N is, so
  // batched and one-at-a-time results agree to the bit.
  Matrix grad_potential_batch(const Matrix& Q) const;
  // ∇²V(q) X for a d x m matrix X, without forming the Hessian (O(d m) for every kind); used to
  // propagate tangents through the splitting.
  Matrix hess_potential_times(const Vector& q, const Matrix& X) const;

  // Full Hamiltonian H(z) = ½‖p‖² + V(q), ∇H and ∇²H in z = (q, p) (length 2d).
  double energy(const Vector& z) const;
  Vector grad_energy(const Vector& z) const;
  Matrix hess_energy(const Vector& z) const;

  // The damped vector field f(z) = J ∇H(z) − diag(0, γI) z.
  Vector vector_field(const Vector& z) const;
  // Its Jacobian J ∇²H(z) − diag(0, γI).
  Matrix vector_field_jacobian(const Vector& z) const;

  // True when f is linear (oscillator, chain): then f(z) = A z with A = linear_generator().
  bool is_linear() const;
  Matrix linear_generator() const;  // throws for nonlinear systems

 private:
  SystemSpec spec_;
};

}  // namespace csympnet
