// Levenberg–Marquardt on the normal equations, for dense least-squares problems with many
// more residuals than parameters (the one-step loss of a G-SympNet core: 8,000 residuals,
// 4,201 parameters on s3).
//
// Why not Ceres' DENSE_NORMAL_CHOLESKY: Ceres forms JᵀJ again for every trial step, including
// the rejected ones, with Eigen compiled for the generic x86-64 target. Here JᵀJ and Jᵀr are
// formed once per Jacobian with BLAS (dsyrk, dgemv), and each trial step costs one Cholesky
// factorisation (LAPACK dpotrf) of JᵀJ + μD. The step control is Ceres' (Nielsen's update):
//
//   (JᵀJ + μ D) δ = −Jᵀr,   D = diag(JᵀJ) clamped to [1e-6, 1e32],
//   ρ = (F(θ) − F(θ + δ)) / (F(θ) − m(δ)),  m(δ) = F + gᵀδ + ½ δᵀJᵀJδ,  F = ½‖r‖²,
//   accept if ρ > 1e-3: μ ← μ · max(1/3, 1 − (2ρ − 1)³), ν ← 2;  else μ ← μ ν, ν ← 2ν,
//
// starting from μ = 1e-4 (Ceres' initial trust region radius 1e4). Every trial step, accepted
// or not, counts as an iteration, as in Ceres. docs/identification.md measures it against Ceres.
#pragma once

#include <functional>
#include <string>

#include "csympnet/core/types.hpp"
#include "csympnet/train/callbacks.hpp"
#include "csympnet/train/residual_jacobian.hpp"

namespace csympnet {

struct LeastSquaresProblem {
  Index n_residuals = 0;
  Index n_params = 0;
  // Writes r(θ) (length n_residuals); returns false when it cannot be evaluated.
  std::function<bool(ConstParams theta, Eigen::Ref<Vector> r)> residuals;
  // Writes J(θ) = ∂r/∂θ (n_residuals × n_params, row-major).
  std::function<void(ConstParams theta, Eigen::Ref<RowMajorMatrix> jac)> jacobian;
  // Optional, instead of `jacobian`: writes JᵀJ (the lower triangle of a, n_params²) and Jᵀr
  // at θ directly, for problems whose J is formed in chunks and never held whole.
  std::function<void(ConstParams theta, Matrix& a, Vector& g)> normal_equations;
  // Optional: polled once per iteration, after each Jacobian, and between the blocks of work
  // that forming and factoring the normal equations are split into past
  // lapack::kMaxUninterruptedFlops; true stops the solver (an interrupt, or the caller's own
  // stopping rule), with the message "stopped by the caller". `jacobian` may poll it too and
  // return early, since a stop is checked before its output is used.
  std::function<bool()> should_stop;
};

struct LmSettings {
  long max_iterations = 300;
  double function_tolerance = 1e-15;   // stop when |ΔF| / F of an accepted step is below
  double gradient_tolerance = 1e-20;   // stop when ‖Jᵀr‖∞ is below
  double parameter_tolerance = 1e-15;  // stop when ‖δ‖ ≤ tol (‖θ‖ + tol)
  // Converged in the data's own measure (0: off): stop at an accepted step that was predicted
  // to lower χ² = ‖r‖² / σ̂² (σ̂² = ‖r‖² / n_residuals) by less than this, when the full
  // Gauss–Newton step from the new iterate is predicted to lower it by less than this too. That
  // fall is the step's squared length in standard errors, so below 1e-3 every parameter is
  // within √(1e-3) ≈ 0.032 standard errors of the local model's minimum (docs/derivations.md,
  // "When a Levenberg–Marquardt fit has converged").
  double chi2_tolerance = 0.0;
  // Converged in the watched parameter's own measure (watch_index < 0 or converged_se 0: off):
  // stop after three accepted steps in a row that were near Gauss–Newton's (μ ≤ 1e-2), each
  // predicted to lower χ² by at most 1, and each moving θ[watch_index] by at most converged_se
  // of its standard error (σ̂² [(A + μD)⁻¹]_bb, from the step's own factorisation): the damping
  // parameter, whose estimate is what the fit is for, has stopped moving while the others may
  // still crawl along a flat valley (the shooting fit's rule, train/shooting.hpp).
  Index watch_index = -1;
  double converged_se = 0.0;
};

struct LmReport {
  long iterations = 0;  // trial steps, accepted or not
  long accepted = 0;
  double initial_cost = 0.0;  // F = ½‖r‖²
  double final_cost = 0.0;
  std::string message;
};

// What the solver tells its caller between iterations (an IterationMonitor's rules are bound
// to these by lm_hooks(), callbacks.hpp).
struct LmHooks {
  // After every accepted step, with theta already updated and cost = ½‖r(theta)‖².
  std::function<void(long iteration, const Vector& theta, double cost)> on_accepted;
  // Before iteration `iteration` (1-based) starts: true ends the solve with the message
  // "stopped by the caller" (an interrupt, or the caller's own rule such as patience).
  std::function<bool(long iteration)> stop_before;
};

// The monitor's rules as LM hooks: each accepted step is validated and reported (its training
// loss as 2·cost, the mean loss when the residuals carry the factor 1/√N), and each iteration
// starts only if the monitor does not say stop. The monitor must outlive the hooks.
LmHooks lm_hooks(IterationMonitor& monitor);

// Minimises ½‖r(θ)‖² from theta, in place.
LmReport levenberg_marquardt(const LeastSquaresProblem& problem, Vector& theta,
                             const LmSettings& settings, const LmHooks& hooks = {});

}  // namespace csympnet
