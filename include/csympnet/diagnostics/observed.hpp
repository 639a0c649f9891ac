// Scores of a learned map against observed trajectories, with no system known: what a user
// with their own measurements can check (`csympnet evaluate --model M --data traj.csv`,
// Python `Model.score`). Nothing here needs γ or the true dynamics.
//
// Over every consecutive pair (z_n, z_{n+1}) with step h_n = t_{n+1} − t_n:
//   one-step RMSE        ( Σ ‖Φ̂_{h_n}(z_n) − z_{n+1}‖² / (2d · pairs) )^{1/2}
//   one-step relative    ( Σ ‖Φ̂_{h_n}(z_n) − z_{n+1}‖² / Σ ‖z_{n+1} − z_n‖² )^{1/2}
//   one-step R²          1 − Σ ‖Φ̂_{h_n}(z_n) − z_{n+1}‖² / Σ ‖Δz_n − mean Δz‖²
// The relative error and R² compare with the increments, which is what a one-step model must
// explain: at small steps every model's states are close to the data's.
// Over each trajectory's rollout ẑ from its first state at its own steps:
//   rollout RMSE         ( Σ_n≥1 ‖ẑ_n − z_n‖² / (2d · Σ steps) )^{1/2}
//   rollout NRMSE        ( Σ_n≥1 ‖ẑ_n − z_n‖² / Σ_n≥1 ‖z_n − z̄‖² )^{1/2}, z̄ the trajectory's mean
//   L2 error             ( Σ_m Σ_n≥1 ‖ẑ_n − z_n‖² h_{n−1} )^{1/2}, the paper's rollout error
//   valid time           the time from t_0 until the RMS error so far,
//                        ( mean_{1≤i≤n} ‖ẑ_i − z_i‖² )^{1/2}, first exceeds 10% of the
//                        trajectory's RMS spread ( mean_n ‖z_n − z̄‖² )^{1/2} (its whole span
//                        when it never does). The error so far, not the pointwise one, so
//                        that one noisy sample does not end it; on data whose noise alone
//                        exceeds the tolerance it is 0.
// and the self structure residual S (diagnostics.hpp) at every observed state with the step
// that follows it, for maps with a Jacobian.
#pragma once

#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/data/dataset.hpp"
#include "csympnet/diagnostics/diagnostics.hpp"

namespace csympnet {

// The fraction of the RMS spread at which a rollout stops being valid.
inline constexpr double kValidTimeTolerance = 0.1;

struct TrajectoryScore {
  Index pairs = 0;
  double one_step_rmse = 0.0;
  double one_step_relative = 0.0;
  double rollout_rmse = 0.0;
  double rollout_nrmse = 0.0;
  double valid_time = 0.0;  // from the trajectory's first time
  double span = 0.0;        // t_last − t_0
  bool finite = true;
};

struct ObservedScores {
  Index trajectories = 0;
  Index pairs = 0;
  double one_step_rmse = 0.0;
  double one_step_relative = 0.0;
  double one_step_r2 = 0.0;
  double rollout_rmse = 0.0;
  double rollout_nrmse = 0.0;
  double l2_error = 0.0;
  double valid_time_mean = 0.0;
  double valid_fraction_mean = 0.0;  // valid time over span, averaged over trajectories
  bool rollout_finite = true;
  double structure_residual_mean = 0.0;  // NaN without a Jacobian
  double structure_residual_max = 0.0;
  std::optional<double> gamma_hat;
  std::vector<TrajectoryScore> per_trajectory;
  std::vector<Matrix> rollouts;  // one per trajectory, 2d x (n+1)
};
// Scalars and the per-trajectory scores (rollouts go to CSV or Python).
void to_json(nlohmann::json& j, const ObservedScores& s);

// Requires every trajectory to have the map's dimension and at least two points; the
// increments must not all be equal (R² is undefined otherwise), an Error says which.
ObservedScores score_observed(const LearnedMap& map, const std::vector<Trajectory>& data);

}  // namespace csympnet
