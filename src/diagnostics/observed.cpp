#include "csympnet/diagnostics/observed.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/io/json_text.hpp"

namespace csympnet {

void to_json(nlohmann::json& j, const ObservedScores& s) {
  j = {{"trajectories", s.trajectories},
       {"pairs", s.pairs},
       {"one_step_rmse", s.one_step_rmse},
       {"one_step_relative", s.one_step_relative},
       {"one_step_r2", s.one_step_r2},
       {"rollout_rmse", finite_or_null(s.rollout_rmse)},
       {"rollout_nrmse", finite_or_null(s.rollout_nrmse)},
       {"l2_error", finite_or_null(s.l2_error)},
       {"valid_time_mean", s.valid_time_mean},
       {"valid_fraction_mean", s.valid_fraction_mean},
       {"valid_time_tolerance", kValidTimeTolerance},
       {"rollout_finite", s.rollout_finite},
       {"structure_residual_mean", finite_or_null(s.structure_residual_mean)},
       {"structure_residual_max", finite_or_null(s.structure_residual_max)}};
  j["gamma_hat"] = s.gamma_hat ? nlohmann::json(*s.gamma_hat) : nlohmann::json(nullptr);
  nlohmann::json per = nlohmann::json::array();
  for (const TrajectoryScore& t : s.per_trajectory)
    per.push_back({{"pairs", t.pairs},
                   {"one_step_rmse", t.one_step_rmse},
                   {"one_step_relative", finite_or_null(t.one_step_relative)},
                   {"rollout_rmse", finite_or_null(t.rollout_rmse)},
                   {"rollout_nrmse", finite_or_null(t.rollout_nrmse)},
                   {"valid_time", t.valid_time},
                   {"span", t.span},
                   {"rollout_finite", t.finite}});
  j["per_trajectory"] = per;
}

ObservedScores score_observed(const LearnedMap& map, const std::vector<Trajectory>& data) {
  require(!data.empty(), "score: no trajectories");
  const Index dim = data.front().z.rows();
  ObservedScores s;
  s.trajectories = static_cast<Index>(data.size());
  s.gamma_hat = map.gamma_hat;
  const double inf = std::numeric_limits<double>::infinity();

  // One step: the errors, and the increments' sums for the relative error and R².
  double err_sq = 0.0, inc_sq = 0.0;
  Vector inc_sum = Vector::Zero(dim);
  double roll_sq = 0.0, spread_sq = 0.0, l2_sq = 0.0;
  Index roll_count = 0;
  double self_sum = 0.0;
  Index self_points = 0;
  s.structure_residual_max = 0.0;
  for (std::size_t k = 0; k < data.size(); ++k) {
    const Trajectory& tr = data[k];
    require(tr.z.rows() == dim, [&] {
      return "score: trajectory " + std::to_string(k + 1) + " has " + std::to_string(tr.z.rows()) +
             " state components; expected " + std::to_string(dim);
    });
    require(tr.steps() >= 1, [&] {
      return "score: trajectory " + std::to_string(k + 1) +
             " has a single point; expected at least two";
    });
    const Index n = tr.steps();
    const Vector steps = tr.t.tail(n) - tr.t.head(n);
    TrajectoryScore ts;
    ts.pairs = n;
    ts.span = tr.t(n) - tr.t(0);
    double t_err = 0.0, t_inc = 0.0;
    for (Index i = 0; i < n; ++i) {
      Vector next;
      try {
        next = map.step(tr.z.col(i), steps(i));
      } catch (const StopRequested&) {
        throw;  // a stop request is not a failure of the map
      } catch (const Error&) {
        next = Vector::Constant(dim, inf);  // the map does not exist there: infinitely wrong
      }
      const Vector inc = tr.z.col(i + 1) - tr.z.col(i);
      t_err += (next - tr.z.col(i + 1)).squaredNorm();
      t_inc += inc.squaredNorm();
      inc_sum += inc;
    }
    ts.one_step_rmse = std::sqrt(t_err / static_cast<double>(dim * n));
    ts.one_step_relative = std::sqrt(t_err / t_inc);
    err_sq += t_err;
    inc_sq += t_inc;
    s.pairs += n;

    // The rollout from the first state, against the whole trajectory.
    Matrix pred = rollout(map, tr.z.col(0), steps);
    const Vector mean = tr.z.rowwise().mean();
    const double spread = std::sqrt((tr.z.colwise() - mean).colwise().squaredNorm().mean());
    double r_sq = 0.0, r_spread = 0.0;
    ts.valid_time = ts.span;
    bool valid = true;
    for (Index i = 1; i <= n; ++i) {
      const double e = (pred.col(i) - tr.z.col(i)).squaredNorm();
      r_sq += e;
      r_spread += (tr.z.col(i) - mean).squaredNorm();
      l2_sq += e * steps(i - 1);
      if (valid && !(std::sqrt(r_sq / static_cast<double>(i)) <= kValidTimeTolerance * spread)) {
        valid = false;
        ts.valid_time = tr.t(i - 1) - tr.t(0);  // the last time it was still within tolerance
      }
    }
    ts.finite = pred.allFinite();
    ts.rollout_rmse = std::sqrt(r_sq / static_cast<double>(dim * n));
    ts.rollout_nrmse = std::sqrt(r_sq / r_spread);
    roll_sq += r_sq;
    spread_sq += r_spread;
    roll_count += dim * n;
    s.rollout_finite = s.rollout_finite && ts.finite;
    s.valid_time_mean += ts.valid_time;
    s.valid_fraction_mean += ts.span > 0.0 ? ts.valid_time / ts.span : 1.0;

    // Structure at the observed states, with the step that follows each.
    for (Index i = 0; map.jacobian && i < n; ++i) {
      double self = inf;
      try {
        const std::optional<double> own =
            map.gamma_hat ? std::optional<double>(std::exp(-*map.gamma_hat * steps(i)))
                          : std::nullopt;
        self = structure_at(map.jacobian(tr.z.col(i), steps(i)), 0.0, own).self_residual;
      } catch (const StopRequested&) {
        throw;  // a stop request is not a failure of the map
      } catch (const Error&) {
      }
      self_sum += self;
      s.structure_residual_max = std::max(s.structure_residual_max, self);
      ++self_points;
    }
    s.per_trajectory.push_back(ts);
    s.rollouts.push_back(std::move(pred));
  }
  const double pairs = static_cast<double>(s.pairs);
  const Vector inc_mean = inc_sum / pairs;
  double inc_var = 0.0;  // Σ‖Δz − mean Δz‖², in a second pass (no cancellation)
  for (const Trajectory& tr : data)
    for (Index i = 0; i < tr.steps(); ++i)
      inc_var += (tr.z.col(i + 1) - tr.z.col(i) - inc_mean).squaredNorm();
  require(inc_var > 0.0,
          "score: the observed states change by the same increment at every step, so R² is "
          "undefined; expected trajectories whose increments vary");
  s.one_step_rmse = std::sqrt(err_sq / (static_cast<double>(dim) * pairs));
  s.one_step_relative = std::sqrt(err_sq / inc_sq);
  s.one_step_r2 = 1.0 - err_sq / inc_var;
  s.rollout_rmse = std::sqrt(roll_sq / static_cast<double>(roll_count));
  s.rollout_nrmse = std::sqrt(roll_sq / spread_sq);
  s.l2_error = std::sqrt(l2_sq);
  s.valid_time_mean /= static_cast<double>(data.size());
  s.valid_fraction_mean /= static_cast<double>(data.size());
  if (self_points > 0) {
    s.structure_residual_mean = self_sum / static_cast<double>(self_points);
  } else {
    s.structure_residual_mean = s.structure_residual_max = std::numeric_limits<double>::quiet_NaN();
  }
  return s;
}

}  // namespace csympnet
