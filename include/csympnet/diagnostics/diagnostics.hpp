// Evaluation of a learned map against reference test trajectories (docs/protocol.md,
// "Metrics").
//
//   L2 rollout error  E = ( Σ_m Σ_{n≥1} ‖z_m(t_n) − ẑ_m(t_n)‖² h_n )^{1/2}
//   R(z)    = ‖DΦ̂ᵀ J DΦ̂ − λ* J‖_F,         λ* = exp(−γ h_test)
//   λ̂(z)    = ⟨DΦ̂ᵀ J DΦ̂, J⟩_F / ‖J‖_F²
// R and λ̂ are taken at every reference state of every test trajectory.
//
// R measures distance to the *true* law, so for CSympNet-ID it is bounded below by
// √(2d)·|exp(−γ̂h) − exp(−γh)|: it reflects the damping error, not the structure. The
// structure itself is measured by the self residual
//   S(z) = ‖DΦ̂ᵀ J DΦ̂ − λ_own J‖_F,  λ_own = exp(−γ̂ h) for models with γ̂, else λ̂(z),
// which is zero in exact arithmetic for every conformally symplectic map.
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/types.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/systems/system.hpp"

namespace csympnet {

// A learned map as the diagnostics see it: one step of size h, and its Jacobian.
struct LearnedMap {
  std::function<Vector(const Vector& z, double h)> step;
  std::function<Matrix(const Vector& z, double h)> jacobian;
  std::optional<double> gamma_hat;
};

// Iterates the map from z0 over `steps`. Returns 2d x (n+1). If a step throws Error (the
// learned dynamics blew up), that state and all later ones are +inf.
Matrix rollout(const LearnedMap& map, const Vector& z0, const Vector& steps);

// Conformal-law residual of one Jacobian M against factor lambda_star, and its projection λ̂.
struct StructureAt {
  double residual = 0.0;       // R against lambda_star
  double lambda_hat = 0.0;     // λ̂
  double self_residual = 0.0;  // S against lambda_own (λ̂ when lambda_own is empty)
};
StructureAt structure_at(const Matrix& m, double lambda_star,
                         std::optional<double> lambda_own = std::nullopt);

struct Diagnostics {
  double l2_error = 0.0;
  double residual_mean = 0.0;
  double residual_max = 0.0;
  double lambda_hat_mean = 0.0;
  double lambda_abs_err_mean = 0.0;
  double lambda_star = 0.0;
  double structure_residual_mean = 0.0;  // mean S
  double structure_residual_max = 0.0;   // max S
  std::optional<double> gamma_hat;
  std::optional<double> gamma_abs_err;
  Index n_points = 0;               // Jacobian evaluation points
  bool finite = true;               // false if any rollout left the finite numbers
  std::vector<Matrix> rollouts;     // one per test trajectory, 2d x (n+1)
  std::vector<Vector> energy_pred;  // H along each rollout
  std::vector<Vector> energy_ref;   // H along each reference trajectory
};
// Scalar fields only (rollouts and energies go to CSV).
void to_json(nlohmann::json& j, const Diagnostics& d);

// Rolls the map out on every test trajectory (at that trajectory's own steps), then takes the
// structure diagnostics at every reference state with step h_test and λ* = exp(−γ h_test).
// A map without a `jacobian` gets the rollout metrics only; its structure metrics are NaN.
Diagnostics evaluate(const LearnedMap& map, const System& sys, const std::vector<Trajectory>& tests,
                     double h_test);

}  // namespace csympnet
