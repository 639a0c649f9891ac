#include "csympnet/diagnostics/positions_score.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/diagnostics/diagnostics.hpp"
#include "csympnet/diagnostics/learned_map.hpp"
#include "csympnet/diagnostics/observed.hpp"
#include "csympnet/io/json_text.hpp"
#include "csympnet/train/positions_state.hpp"

namespace csympnet {

namespace {

nlohmann::json numbers(const Vector& v) {
  nlohmann::json out = nlohmann::json::array();
  for (Index i = 0; i < v.size(); ++i) out.push_back(finite_or_null(v(i)));
  return out;
}

// A value whose square overflows double would make every error infinite.
constexpr double kMaxMagnitude = 1e150;

// The data's own refusals, before any fit: shape, values, times, length against the warm-up.
void check_trajectory(const Trajectory& tr, Index d, std::size_t k, std::size_t count, long warmup,
                      bool warmup_given, const std::string& where) {
  const std::string which =
      where + ": trajectory " + std::to_string(k + 1) + " of " + std::to_string(count);
  require(tr.z.rows() == d, [&] {
    return which + " has " + std::to_string(tr.z.rows()) +
           " positions per sample; expected d = " + std::to_string(d) + " like the model";
  });
  require(tr.z.cols() == tr.t.size(), [&] {
    return which + " has " + std::to_string(tr.z.cols()) + " samples but " +
           std::to_string(tr.t.size()) + " times; expected one time per sample";
  });
  for (Index n = 0; n < tr.t.size(); ++n) {
    require(std::isfinite(tr.t(n)) && (n == 0 || tr.t(n) > tr.t(n - 1)), [&] {
      return which + ": t[" + std::to_string(n) + "] = " + number_text(tr.t(n)) +
             (n == 0 ? std::string() : " after " + number_text(tr.t(n - 1))) +
             "; expected finite, strictly increasing times";
    });
    for (Index i = 0; i < d; ++i)
      require(std::isfinite(tr.z(i, n)) && std::abs(tr.z(i, n)) <= kMaxMagnitude, [&] {
        return which + ": q" + std::to_string(i + 1) + " at sample " + std::to_string(n) + " is " +
               number_text(tr.z(i, n)) + "; expected a finite position of magnitude at most 1e150";
      });
  }
  const Index n = tr.t.size();
  if (n <= warmup) {
    const std::string problem =
        which + " has " + std::to_string(n) + " samples, and " +
        (warmup_given ? "a warm-up of " + std::to_string(warmup)
                      : "the default warm-up (a tenth of the samples, at least " +
                            std::to_string(kWarmupDefaultMin) + ")") +
        " leaves none to score; expected a trajectory of more than " + std::to_string(warmup) +
        " samples" +
        (n > static_cast<Index>(kWarmupRange.lo)
             ? ", or a warm-up from " + number_text(kWarmupRange.lo) + " to " +
                   std::to_string(n - 1)
             : std::string(" (a warm-up needs at least ") + number_text(kWarmupRange.lo) +
                   " samples, and one more is scored)");
    throw OptionError(kWarmupRange.key, problem);
  }
}

}  // namespace

namespace {

// The last time after t_start at which the running rms of the errors (d × S, at times t) was
// still within kValidTimeTolerance of `spread`; the whole span when it never left it.
double valid_time(const Matrix& err, const Vector& t, double t_start, double spread) {
  double sq = 0.0;
  for (Index i = 0; i < err.cols(); ++i) {
    sq += err.col(i).squaredNorm();
    const double rms = std::sqrt(sq / static_cast<double>((i + 1) * err.rows()));
    if (!(rms <= kValidTimeTolerance * spread)) return i == 0 ? 0.0 : t(i - 1) - t_start;
  }
  return err.cols() > 0 ? t(err.cols() - 1) - t_start : 0.0;
}

}  // namespace

Matrix step_inputs(const Matrix& u, Index first, Index steps) {
  if (u.rows() == 0) return Matrix();
  Matrix out(2 * u.rows(), steps);
  out.topRows(u.rows()) = u.middleCols(first, steps);
  out.bottomRows(u.rows()) = u.middleCols(first + 1, steps);
  return out;
}

Matrix driven_rollout(const OneStepMap& map, ConstParams theta, const Vector& z,
                      const Vector& steps, const Matrix& u) {
  require(u.cols() == steps.size() && u.rows() == 2 * map.n_inputs(),
          "driven rollout: expected the inputs at the start and end of every step");
  Matrix out(z.size(), steps.size() + 1);
  out.col(0) = z;
  Vector h(1);
  for (Index k = 0; k < steps.size(); ++k) {
    if (k % 4096 == 4095) throw_if_stop_requested("the driven rollout");
    h(0) = steps(k);
    out.col(k + 1) = map.forward_driven(theta, out.col(k), h, u.col(k), nullptr);
  }
  return out;
}

long default_warmup(long samples) {
  const long tenth = (samples + 9) / 10;
  return std::clamp(tenth, kWarmupDefaultMin, kWarmupDefaultMax);
}

void to_json(nlohmann::json& j, const PositionsScores& s) {
  j = {{"trajectories", s.trajectories},
       {"warmup", s.warmup ? nlohmann::json(*s.warmup) : nlohmann::json(nullptr)},
       {"samples_scored", s.samples_scored},
       {"rmse", finite_or_null(s.rmse)},
       {"rmse_per_coordinate", numbers(s.rmse_per_coordinate)},
       {"spread", s.spread},
       {"spread_per_coordinate", numbers(s.spread_per_coordinate)},
       {"nrmse", finite_or_null(s.nrmse)},
       {"valid_time_mean", s.valid_time_mean},
       {"valid_time_tolerance", kValidTimeTolerance},
       {"rollout_finite", s.rollout_finite}};
  nlohmann::json per = nlohmann::json::array();
  for (const PositionsTrajectoryScore& t : s.per_trajectory)
    per.push_back({{"samples", t.samples},
                   {"warmup", t.warmup},
                   {"scored", t.scored},
                   {"t_start", t.t_start},
                   {"state_fit_rms", t.state_fit_rms},
                   {"rmse", finite_or_null(t.rmse)},
                   {"rmse_per_coordinate", numbers(t.rmse_per_coordinate)},
                   {"spread", t.spread},
                   {"valid_time", t.valid_time},
                   {"span", t.span},
                   {"rollout_finite", t.finite}});
  j["per_trajectory"] = per;
}

PositionsScores score_positions(const Model& model, const Vector& theta,
                                const std::vector<Trajectory>& data,
                                const PositionsScoreOptions& options) {
  const std::string& where = options.where;
  // The momenta are hidden states of the map's own units: only a map with a damping rate,
  // as `fit` writes it, is fitted to positions (as rollout --from-positions).
  require(model.is_map() && model.type() == "csympnet", [&] {
    return where +
           ": scoring positions needs a csympnet model (a one-step map with a damping rate, "
           "as fit writes it); the model is of type '" +
           model.type() + "'";
  });
  require(!data.empty(), [&] { return where + ": no trajectories; expected at least one"; });
  if (options.warmup) kWarmupRange.check(*options.warmup);
  const Index d = model.dim() / 2;
  const Index m = model.map->n_inputs();
  for (std::size_t k = 0; k < data.size(); ++k) {
    require(data[k].u.rows() == m, [&] {
      return where + ": trajectory " + std::to_string(k + 1) + " has " +
             std::to_string(data[k].u.rows()) + " input columns (u1..um); the model is driven by " +
             std::to_string(m) + (m == 0 ? " (a free model: expected no u columns)" : "");
    });
    const long n = static_cast<long>(data[k].t.size());
    check_trajectory(data[k], d, k, data.size(), options.warmup.value_or(default_warmup(n)),
                     options.warmup.has_value(), where);
  }

  PositionsScores s;
  s.trajectories = static_cast<Index>(data.size());
  s.warmup = options.warmup;
  Vector err_sq = Vector::Zero(d), spread_sq = Vector::Zero(d);
  const LearnedMap map = learned_map(model, theta);
  for (std::size_t k = 0; k < data.size(); ++k) {
    throw_if_stop_requested("the score of the positions");
    const Trajectory& tr = data[k];
    const Index n = tr.t.size();
    const Index warm = options.warmup.value_or(default_warmup(static_cast<long>(n)));
    PositionsTrajectoryScore ts;
    ts.samples = n;
    ts.warmup = warm;
    ts.scored = n - warm;
    ts.t_start = tr.t(warm - 1);
    const std::string what = where + ": trajectory " + std::to_string(k + 1) +
                             ", its warm-up (the first " + std::to_string(warm) + " samples)";
    const Vector z =
        checked_state_from_positions(*model.map, theta, tr.z.leftCols(warm), tr.t.head(warm),
                                     &ts.state_fit_rms, what, step_inputs(tr.u, 0, warm - 1));
    const Vector steps = tr.t.tail(ts.scored) - tr.t.segment(warm - 1, ts.scored);
    Matrix pred = m == 0 ? rollout(map, z, steps)
                         : driven_rollout(*model.map, theta, z, steps,
                                          step_inputs(tr.u, warm - 1, ts.scored));
    const Matrix observed = tr.z.rightCols(ts.scored);
    const Matrix err = pred.bottomRightCorner(2 * d, ts.scored).topRows(d) - observed;
    const Vector t_err = err.rowwise().squaredNorm();
    const Vector mean = observed.rowwise().mean();
    const Vector t_spread = (observed.colwise() - mean).rowwise().squaredNorm();
    const double count = static_cast<double>(ts.scored);
    ts.rmse_per_coordinate = (t_err / count).cwiseSqrt();
    ts.rmse = std::sqrt(t_err.sum() / (count * static_cast<double>(d)));
    ts.spread = std::sqrt(t_spread.sum() / (count * static_cast<double>(d)));
    ts.finite = pred.allFinite();
    ts.span = tr.t(n - 1) - ts.t_start;
    ts.valid_time = valid_time(err, tr.t.tail(ts.scored), ts.t_start, ts.spread);
    s.valid_time_mean += ts.valid_time / static_cast<double>(data.size());
    err_sq += t_err;
    spread_sq += t_spread;
    s.samples_scored += ts.scored;
    s.rollout_finite = s.rollout_finite && ts.finite;
    s.per_trajectory.push_back(std::move(ts));
    s.rollouts.push_back(std::move(pred));
  }
  const double count = static_cast<double>(s.samples_scored);
  s.rmse_per_coordinate = (err_sq / count).cwiseSqrt();
  s.spread_per_coordinate = (spread_sq / count).cwiseSqrt();
  s.rmse = std::sqrt(err_sq.sum() / (count * static_cast<double>(d)));
  s.spread = std::sqrt(spread_sq.sum() / (count * static_cast<double>(d)));
  s.nrmse = s.spread > 0.0 ? s.rmse / s.spread : std::numeric_limits<double>::quiet_NaN();
  return s;
}

}  // namespace csympnet
