#include "csympnet/diagnostics/diagnostics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"

namespace csympnet {

Matrix rollout(const LearnedMap& map, const Vector& z0, const Vector& steps) {
  Matrix out(z0.size(), steps.size() + 1);
  out.col(0) = z0;
  for (Index n = 0; n < steps.size(); ++n) {
    // Between steps too (the maps poll within a long step): a rollout of millions of cheap
    // steps ends on Ctrl-C.
    if (n % 1024 == 1023) throw_if_stop_requested("rollout");
    try {
      out.col(n + 1) = map.step(out.col(n), steps(n));
    } catch (const StopRequested&) {
      throw;  // a stop request is not a failure of the map
    } catch (const Error&) {
      // The learned dynamics left the finite numbers (e.g. a blown-up vector field): the
      // rest of the rollout is infinitely wrong, which the L2 error then says.
      out.rightCols(steps.size() - n).setConstant(std::numeric_limits<double>::infinity());
      break;
    }
  }
  return out;
}

StructureAt structure_at(const Matrix& m, double lambda_star, std::optional<double> lambda_own) {
  const Matrix j = canonical_j(m.rows() / 2);
  const Matrix w = m.transpose() * j * m;
  StructureAt s;
  s.residual = (w - lambda_star * j).norm();
  s.lambda_hat = (w.array() * j.array()).sum() / j.squaredNorm();
  s.self_residual = (w - lambda_own.value_or(s.lambda_hat) * j).norm();
  return s;
}

void to_json(nlohmann::json& j, const Diagnostics& d) {
  j = {{"l2_error", d.l2_error},
       {"residual_mean", d.residual_mean},
       {"residual_max", d.residual_max},
       {"lambda_hat_mean", d.lambda_hat_mean},
       {"lambda_abs_err_mean", d.lambda_abs_err_mean},
       {"lambda_star", d.lambda_star},
       {"structure_residual_mean", d.structure_residual_mean},
       {"structure_residual_max", d.structure_residual_max},
       {"jacobian_points", d.n_points},
       {"rollout_finite", d.finite}};
  j["gamma_hat"] = d.gamma_hat ? nlohmann::json(*d.gamma_hat) : nlohmann::json(nullptr);
  j["gamma_abs_err"] = d.gamma_abs_err ? nlohmann::json(*d.gamma_abs_err) : nlohmann::json(nullptr);
}

Diagnostics evaluate(const LearnedMap& map, const System& sys, const std::vector<Trajectory>& tests,
                     double h_test) {
  require(!tests.empty(), "evaluate: no test trajectories");
  require(std::isfinite(h_test) && h_test > 0.0, "evaluate: h_test must be > 0");
  Diagnostics d;
  d.lambda_star = std::exp(-sys.gamma() * h_test);
  d.gamma_hat = map.gamma_hat;
  if (map.gamma_hat) d.gamma_abs_err = std::abs(*map.gamma_hat - sys.gamma());

  double sq = 0.0;
  double r_sum = 0.0, lam_sum = 0.0, lam_err_sum = 0.0, self_sum = 0.0;
  std::optional<double> lambda_own;
  if (map.gamma_hat) lambda_own = std::exp(-*map.gamma_hat * h_test);
  for (const Trajectory& traj : tests) {
    require(traj.z.rows() == sys.dim(), "evaluate: test trajectory dimension mismatch");
    const Vector steps = traj.t.tail(traj.t.size() - 1) - traj.t.head(traj.t.size() - 1);
    Matrix pred = rollout(map, traj.z.col(0), steps);
    for (Index n = 1; n < pred.cols(); ++n)
      sq += (traj.z.col(n) - pred.col(n)).squaredNorm() * steps(n - 1);
    d.finite = d.finite && pred.allFinite();

    Vector e_pred(pred.cols()), e_ref(pred.cols());
    for (Index n = 0; n < pred.cols(); ++n) {
      e_pred(n) = sys.energy(pred.col(n));
      e_ref(n) = sys.energy(traj.z.col(n));
    }
    for (Index n = 0; map.jacobian && n < traj.z.cols(); ++n) {
      StructureAt s;
      try {
        s = structure_at(map.jacobian(traj.z.col(n), h_test), d.lambda_star, lambda_own);
      } catch (const StopRequested&) {
        throw;  // a stop request is not a failure of the map
      } catch (const Error&) {
        const double inf = std::numeric_limits<double>::infinity();
        s = {inf, inf, inf};  // the induced map does not exist at this point
      }
      r_sum += s.residual;
      self_sum += s.self_residual;
      d.structure_residual_max = std::max(d.structure_residual_max, s.self_residual);
      lam_sum += s.lambda_hat;
      lam_err_sum += std::abs(s.lambda_hat - d.lambda_star);
      d.residual_max = std::max(d.residual_max, s.residual);
      if (std::isnan(s.residual)) d.residual_max = s.residual;
      ++d.n_points;
    }
    d.rollouts.push_back(std::move(pred));
    d.energy_pred.push_back(std::move(e_pred));
    d.energy_ref.push_back(std::move(e_ref));
  }
  d.l2_error = std::sqrt(sq);
  if (d.n_points == 0) {  // no Jacobian: structure diagnostics not taken
    const double nan = std::numeric_limits<double>::quiet_NaN();
    d.residual_mean = d.residual_max = d.structure_residual_mean = d.structure_residual_max = nan;
    d.lambda_hat_mean = d.lambda_abs_err_mean = nan;
    return d;
  }
  const double np = static_cast<double>(d.n_points);
  d.residual_mean = r_sum / np;
  d.structure_residual_mean = self_sum / np;
  d.lambda_hat_mean = lam_sum / np;
  d.lambda_abs_err_mean = lam_err_sum / np;
  return d;
}

}  // namespace csympnet
