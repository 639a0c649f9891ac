// An interval for γ̂ from one linearisation at the fit, for any model size
// (docs/derivations.md, "The interval for γ̂").
//
// With A = JᵀJ and the block scores s_b = Σ_{i∈b} J_iᵀ r_i of the (scaled) training residuals at
// θ̂ (window_normal_equations), a perturbation of the data moves θ̂ by −A⁻¹ Σ_b s_b, so γ̂ moves
// by −Σ_b uᵀ s_b with u = A⁻¹ ∇γ̂. The blocks (whole trajectories or segments of one) are
// treated as independent and everything inside a block as arbitrarily dependent, so serial
// correlation, noise of any kind and a misfit that varies from block to block all enter
// through the scores themselves (a cluster-robust "sandwich" variance):
//
//   var(γ̂) = B/(B − 1) Σ_b (uᵀ s_b − mean)²,
//
// and the interval is γ̂ ± t_{B−1} · √var. A is rank-deficient for an over-parametrised core,
// so u solves (A + μ D) u = ∇γ̂ with D = diag A and a small μ; the interval is computed at μ
// and at 100 μ, and if they disagree by more than a factor 2 the damping rate is not
// separated from the core's parameters by these data (`stable` false). The remaining Newton
// step uᵀ g (the optimiser's unfinished work) and the rounding of the data are added in
// quadrature, so the interval never has zero width.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/types.hpp"

namespace csympnet {

struct SandwichInterval {
  double gamma = 0.0;  // γ̂
  double low = 0.0;
  double high = 0.0;
  double level = 0.95;
  double std_error = 0.0;     // the total standard error (all components)
  double sandwich = 0.0;      // √ of the block variance alone
  double model_based = 0.0;   // the classical σ̂ √(u_β) (independent residuals): reported only
  double optimisation = 0.0;  // |uᵀ g|: how far the unfinished Newton step would move γ̂
  double rounding = 0.0;      // the data's rounding, propagated
  double integrator = 0.0;  // a library core's: |γ̂ at twice the substeps − γ̂| (add_integrator)
  double dof = 0.0;         // degrees of freedom of the t quantile
  // (Σ w_b)² / Σ w_b², w_b = uᵀ I_b u the share of block b in the information on the estimate,
  // when the blocks' information is given (else 0): the blocks the interval rests on.
  double effective_blocks = 0.0;
  double quantile = 0.0;  // t_{dof}((1 + level)/2)
  long blocks = 0;
  double regularisation_ratio = 1.0;  // std error at 100 μ over that at μ
  bool stable = true;
  double heldout_inflation = 1.0;  // factor applied to the standard error (inflate_interval)
  std::string method;
};
void to_json(nlohmann::json& j, const SandwichInterval& s);

// a: A (lower triangle, P × P); g: Jᵀr; scores: P × B; gamma_index: the damping parameter and
// gamma_sign = dγ̂/dβ there; n_residuals and cost = ½‖r‖² (scaled like A) for the model-based
// error; data_scale: the rms of the data, in the units of the residuals, for the rounding term.
//
// block_information (optional, one P × P matrix per block: the information its rows add to the
// rest, shooting_block_equations): the t quantile then takes (Σ w_b)² / Σ w_b² − 1 degrees of
// freedom instead of B − 1, w_b = uᵀ I_b u (Satterthwaite's approximation for a sum of B
// squares whose expectations are in proportion to w_b). A record whose information sits in a
// few blocks (motion that stops, a decay into the noise) has a variance estimated from those
// few, and its interval says so.
SandwichInterval sandwich_interval(const Matrix& a, const Vector& g, const Matrix& scores,
                                   Index gamma_index, double gamma, double gamma_sign,
                                   Index n_residuals, double cost, double residual_scale,
                                   double data_scale, double level,
                                   const std::vector<Matrix>* block_information = nullptr);

// The same interval for any smooth function f(θ̂) of the parameters, given its value and
// gradient ∇f (u = (A + μD)⁻¹ ∇f): the modal frequencies and damping ratios. `gamma` of the
// result holds f(θ̂).
SandwichInterval sandwich_interval_of(const Matrix& a, const Vector& g, const Matrix& scores,
                                      const Vector& gradient, double value, Index n_residuals,
                                      double cost, double residual_scale, double data_scale,
                                      double level,
                                      const std::vector<Matrix>* block_information = nullptr);

// Scales the standard error and the half-widths by `factor` (≥ 1), keeping the centre, and
// records it: the held-out inflation of identify() (training residuals understate the error).
void inflate_interval(SandwichInterval& s, double factor);

// Adds `change` (how far γ̂ moves when the library core's integrator takes twice the
// substeps: its discretisation and rounding, which the residuals of a clean fit do not show)
// in quadrature to the standard error, keeping the centre and the quantile.
void add_integrator(SandwichInterval& s, double change);

// Quantiles: the standard normal's and Student's t with dof degrees of freedom (dof ≥ 1).
double normal_quantile(double p);
double student_t_quantile(double p, double dof);
// Fisher's F with (d1, d2) degrees of freedom (both > 0), by bisection on its CDF (the
// regularised incomplete beta function).
double f_quantile(double p, double d1, double d2);
// Hotelling's T² point for k parameters whose covariance is estimated from `blocks` (> k)
// independent blocks: k(B − 1)/(B − k) · F_p(k, B − k). For k = 1 it is the square of the
// two-sided t_{B−1} point at the same level, the interval's quantile.
double hotelling_limit(double p, Index k, Index blocks);

// χ² with n degrees of freedom (n > 0), by Wilson–Hilferty's cube-root normal approximation:
// at the 95% point within 1% of the tables for n ≥ 2.
double chi_square_quantile(double p, double n);

// The reference a joint Wald statistic is compared with: Hotelling's point for a covariance
// estimated from B blocks (the test at its level), or χ²_k's, as if it were known (stricter:
// over 40 simulated blocks it refused truly negligible sets two to three times as often as its
// level, tests/train/gamma_sandwich_test.cpp).
enum class WaldReference { kHotelling, kChiSquare };

// The joint Wald test that parameters are zero together, with the interval's cluster-robust
// covariance C = A⁻¹ (B/(B−1) Σ_b s̃_b s̃_bᵀ) A⁻¹ (s̃_b the block scores less their mean; A with a
// 1e-10 ridge on its diagonal, as a core's A may be singular). `at`: parameters, the most
// negligible first. `count`: the largest n ≥ 2 (and below B) whose first n values θ_S have
// θ_Sᵀ C_SS⁻¹ θ_S within the `reference` distribution's `level` point (Hotelling's T² for B
// blocks, hotelling_limit, or χ²_n's), and `statistic` its value; 0 when no such n (or A does not
// factor, or fewer than three blocks). Parameters each with a small t-ratio can be needed together,
// as two nearly collinear regressors whose sum the data fix.
struct JointWald {
  Index count = 0;
  double statistic = 0.0;
};
JointWald negligible_together(const Matrix& a, const Matrix& scores, const Vector& theta,
                              const std::vector<Index>& at, double level = 0.95,
                              WaldReference reference = WaldReference::kHotelling);

}  // namespace csympnet
