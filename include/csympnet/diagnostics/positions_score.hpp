// Scores of a csympnet model against observed positions alone (`csympnet evaluate --data
// positions.csv`, Python `Model.score(q, t, observed="positions")`): a free-run forecast from a
// start state fitted to a warm-up window, scored on the samples after it. The benchmarks of
// system identification score so: the warm-up window estimates the hidden state, and it is left
// out of the score.
//
// For each trajectory of n positions q_0 … q_{n−1} (d × n) at times t_0 < … < t_{n−1}, with a
// warm-up of N samples:
//   state       ẑ_{N−1} = the state at t_{N−1} fitted to q_0 … q_{N−1} with the model
//               (checked_state_from_positions: no gap in the window, a fit that explains it)
//   forecast    ẑ_{k+1} = Φ̂_{h_k}(ẑ_k), h_k = t_{k+1} − t_k, k = N−1 … n−2 (one map step per
//               sample interval, as every rollout of evaluate)
//   errors      e_{i,k} = (P_q ẑ_k)_i − q_{i,k}, k = N … n−1 (the n − N scored samples)
// and over all trajectories, S scored samples in all, in the data's units:
//   rmse_i      ( Σ_k e_{i,k}² / S )^{1/2}                       per coordinate i
//   rmse        ( Σ_i Σ_k e_{i,k}² / (d S) )^{1/2}                 every coordinate
//   spread_i    ( Σ_k (q_{i,k} − q̄_i)² / S )^{1/2}, q̄_i the mean of the trajectory's scored
//               samples: the scale the errors compare with (a forecast of the mean scores it)
//   nrmse       rmse / spread (spread over every coordinate, as rmse)
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/options.hpp"
#include "csympnet/core/types.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/models/model.hpp"

namespace csympnet {

// The warm-up's samples: at least 3, one more than the 2 that determine the 2d hidden unknowns
// exactly (d positions a sample), so that a fit that does not explain its window shows in the
// residual (check_state_fit).
inline constexpr OptionRange kWarmupRange{
    .key = "warmup",
    .lo = 3,
    .hi = 1e8,
    .whole = true,
    .why =
        "the 2d unknowns of the start state need 2 samples, and a third shows whether the "
        "model explains them"};

// The default warm-up of a trajectory of n samples: a tenth of them, rounded up, at least
// kWarmupDefaultMin (the shortest shooting segment `fit` uses) and at most kWarmupDefaultMax
// (its longest: over longer windows a model's state fit may not converge).
inline constexpr long kWarmupDefaultMin = 10;
inline constexpr long kWarmupDefaultMax = 80;
long default_warmup(long samples);

// Per step k of samples first … first + steps − 1 of a record's inputs u (m × n): the input at
// its start, then at its end (2m × steps; empty when u is).
Matrix step_inputs(const Matrix& u, Index first, Index steps);

// The map's free run from z over `steps`, driven by the step inputs `u` (2m × steps, as
// step_inputs gives them): 2d × (steps + 1), z first. Stops on a stop request.
Matrix driven_rollout(const OneStepMap& map, ConstParams theta, const Vector& z,
                      const Vector& steps, const Matrix& u);

struct PositionsScoreOptions {
  // Samples of the warm-up window, per trajectory (kWarmupRange); empty: default_warmup.
  std::optional<long> warmup;
  // Names the data in messages ("positions.csv", "data").
  std::string where = "positions";
};

struct PositionsTrajectoryScore {
  Index samples = 0;           // n
  Index warmup = 0;            // N
  Index scored = 0;            // n − N
  double t_start = 0.0;        // t_{N−1}, the time of the fitted state
  double state_fit_rms = 0.0;  // the rms position residual of the state fit on the warm-up
  double rmse = 0.0;
  Vector rmse_per_coordinate;  // d
  double spread = 0.0;
  // How long after t_start the running rms error of the forecast stays within
  // kValidTimeTolerance of the scored positions' spread (observed.hpp's definition, on q).
  double valid_time = 0.0;
  double span = 0.0;   // t_{n−1} − t_start: the forecast's length
  bool finite = true;  // false when the forecast left the finite numbers
};

struct PositionsScores {
  Index trajectories = 0;
  std::optional<long> warmup;  // as given; empty: the default, per trajectory
  Index samples_scored = 0;    // S
  double rmse = 0.0;
  Vector rmse_per_coordinate;  // d
  double spread = 0.0;
  Vector spread_per_coordinate;  // d
  double nrmse = 0.0;            // NaN when the scored positions do not move
  double valid_time_mean = 0.0;  // over the trajectories
  bool rollout_finite = true;
  std::vector<PositionsTrajectoryScore> per_trajectory;
  std::vector<Matrix> rollouts;  // per trajectory, 2d × (n − N + 1): the fitted state, then
                                 // the forecast at each scored sample
};
// Scalars and the per-trajectory scores (the rollouts go to Python); a non-finite number is
// null.
void to_json(nlohmann::json& j, const PositionsScores& s);

// `data` holds positions (each Trajectory's z is d × n). Refuses (Error naming options.where)
// a model that is not a csympnet one-step map, positions of another d, a value that is not
// finite or beyond 1e150 in magnitude, times that do not increase, a trajectory not longer than
// its warm-up, a warm-up window with a gap, and a state fit that does not explain its window;
// a warm-up out of kWarmupRange is an OptionError. Polls the stop request (core/stop.hpp).
PositionsScores score_positions(const Model& model, const Vector& theta,
                                const std::vector<Trajectory>& data,
                                const PositionsScoreOptions& options = {});

}  // namespace csympnet
