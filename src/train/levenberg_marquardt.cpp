#include "csympnet/train/levenberg_marquardt.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "csympnet/core/error.hpp"
#include "csympnet/core/finite.hpp"
#include "lapack.hpp"

namespace csympnet {

namespace {

constexpr double kInitialMu = 1e-4;  // Ceres: initial_trust_region_radius = 1e4
constexpr double kMinMu = 1e-16;     // Ceres: max_trust_region_radius = 1e16
constexpr double kMaxMu = 1e32;      // Ceres: min_trust_region_radius = 1e-32
constexpr double kMinDiagonal = 1e-6, kMaxDiagonal = 1e32;  // Ceres: min/max_lm_diagonal
constexpr double kMinRelativeDecrease = 1e-3;               // Ceres: min_relative_decrease

// `m` as an n × n matrix of zeros, taken a block of columns at a time with `should_stop` (when
// given) polled between them: a fresh matrix's first touch maps its pages
// (kMaxUninterruptedTouch). False: stopped, `m` emptied.
bool zeros_polled(Matrix& m, Index n, const std::function<bool()>& should_stop) {
  m.resize(n, n);  // allocates; touches nothing
  const Index cols = std::max<Index>(1, lapack::kMaxUninterruptedTouch / std::max<Index>(n, 1));
  for (Index j = 0; j < n; j += cols) {
    if (should_stop && should_stop()) {
      m.resize(0, 0);
      return false;
    }
    m.middleCols(j, std::min(cols, n - j)).setZero();
  }
  return true;
}

// JᵀJ (lower triangle) and Jᵀr at the current iterate. Where one dsyrk would run past
// kMaxUninterruptedFlops, J is taken in blocks of rows with `should_stop` (when given) polled
// between them (false: stopped, a and g incomplete). The split depends on the size alone, never
// on whether a `should_stop` was given: a polled and an unpolled solve then sum the same blocks
// in the same order and agree to the bit on every CPU. (A single dsyrk and a sum of row blocks
// differ by rounding, and how much depends on the BLAS kernel the CPU gets: 4e-9 relative after
// 20 iterations of a 9000 × 400 problem on AVX2, none seen on AVX-512.)
struct GramSystem {
  Matrix a;
  Vector g;
  bool form(const RowMajorMatrix& jac, const Vector& r, const std::function<bool()>& should_stop) {
    const Index m = jac.rows(), n = jac.cols();
    // dsyrk writes the lower triangle; the upper stays 0.
    if (a.rows() != n && !zeros_polled(a, n, should_stop)) return false;
    g.resize(n);
    // A row-major m × n J is a column-major n × m Jᵀ.
    const double per_row = static_cast<double>(n) * static_cast<double>(n);
    if (static_cast<double>(m) * per_row <= lapack::kMaxUninterruptedFlops) {
      lapack::gram_from_transpose(jac.data(), n, m, a.data());
      lapack::transpose_times(jac.data(), n, m, r.data(), g.data());
      return true;
    }
    const Index rows = std::max<Index>(
        1, static_cast<Index>(lapack::kMaxUninterruptedFlops / std::max(per_row, 1.0)));
    for (Index i = 0; i < m; i += rows) {
      if (should_stop && should_stop()) return false;
      const Index k = std::min(rows, m - i);
      const double* block = jac.data() + i * n;
      if (i == 0) {
        lapack::gram_from_transpose(block, n, k, a.data());
        lapack::transpose_times(block, n, k, r.data(), g.data());
      } else {
        lapack::add_gram_from_transpose(block, n, k, a.data());
        lapack::add_transpose_times(block, n, k, r.data() + i, g.data());
      }
    }
    return true;
  }
};

// The damped system's factor: one dpotrf where that is short, else block by block polling
// `should_stop` (when given). As for the normal equations, the choice depends on the size alone.
lapack::Factor factor(Matrix& lhs, const std::function<bool()>& should_stop) {
  const double n = static_cast<double>(lhs.rows());
  if (n * n * n / 3.0 <= lapack::kMaxUninterruptedFlops)
    return lapack::cholesky(lhs.data(), lhs.rows()) ? lapack::Factor::kDone
                                                    : lapack::Factor::kNotPositiveDefinite;
  return lapack::cholesky_blocked(lhs.data(), lhs.rows(), should_stop);
}

// χ²'s fall that the full Gauss–Newton step from here predicts, m·½gᵀA⁻¹g / F (σ̂² = 2F/m),
// with a ridge of 1e-12 of A's diagonal; infinite when A cannot be factored even so, or when
// `should_stop` ends the factoring (factor(): polled as the damped system's). `work` is
// scratch space (n × n).
double gauss_newton_chi2_fall(const Matrix& a, const Vector& g, double cost, Index m, Matrix& work,
                              const std::function<bool()>& should_stop) {
  if (!(cost > 0.0)) return std::numeric_limits<double>::infinity();
  const Index n = a.rows();
  work = a;
  work.diagonal() += 1e-12 * a.diagonal().cwiseMax(kMinDiagonal);
  if (factor(work, should_stop) != lapack::Factor::kDone)
    return std::numeric_limits<double>::infinity();
  Vector x = g;
  lapack::cholesky_solve(work.data(), n, x.data());
  return static_cast<double>(m) * 0.5 * g.dot(x) / cost;
}

// The standard error of θ_b from the factored damped system L Lᵀ = A + μD: σ̂² [(A + μD)⁻¹]_bb,
// σ̂² = 2 cost / m (the residuals' variance), so the damped system's, at most the undamped's.
double damped_standard_error(const Matrix& factored, Index b, double cost, Index m) {
  Vector e = Vector::Zero(factored.rows());
  e(b) = 1.0;
  lapack::cholesky_solve(factored.data(), factored.rows(), e.data());
  return std::sqrt(std::max(0.0, 2.0 * cost * e(b) / static_cast<double>(m)));
}

}  // namespace

LmHooks lm_hooks(IterationMonitor& monitor) {
  LmHooks h;
  h.on_accepted = [&monitor](long iteration, const Vector& theta, double cost) {
    monitor.accept(iteration, theta, 2.0 * cost);  // a stop it asks for is seen by stop_before
  };
  h.stop_before = [&monitor](long iteration) { return monitor.stop_before(iteration); };
  return h;
}

LmReport levenberg_marquardt(const LeastSquaresProblem& problem, Vector& theta,
                             const LmSettings& settings, const LmHooks& hooks) {
  const Index m = problem.n_residuals, n = problem.n_params;
  require(m >= 1 && n >= 1, "levenberg_marquardt: the problem needs residuals and parameters");
  require(theta.size() == n, "levenberg_marquardt: parameter vector has the wrong size");
  require(settings.max_iterations >= 1, "levenberg_marquardt: max_iterations must be >= 1");
  const lapack::SingleThreaded one_thread;
  LmReport report;
  Vector r(m), r_trial(m);
  if (!problem.residuals(theta, r) || !r.allFinite()) {
    report.message = "the residuals at the starting point are not finite";
    return report;
  }
  double cost = 0.5 * r.squaredNorm();
  report.initial_cost = report.final_cost = cost;
  RowMajorMatrix jac;
  GramSystem ne;
  // J (or JᵀJ and Jᵀr directly) at theta; false when not finite.
  auto linearise = [&]() {
    if (problem.normal_equations) {
      problem.normal_equations(theta, ne.a, ne.g);
      return all_finite(ne.a) && all_finite(ne.g);
    }
    if (jac.rows() != m) jac.resize(m, n);
    problem.jacobian(theta, jac);
    if (problem.should_stop && problem.should_stop()) return false;  // jac may be partial
    if (!all_finite(jac)) return false;
    return ne.form(jac, r, problem.should_stop);
  };
  if (!linearise()) {
    report.message = problem.should_stop && problem.should_stop()
                         ? "stopped by the caller"
                         : "the Jacobian at the starting point is not finite";
    return report;
  }

  Matrix lhs;  // its pages mapped here, polled, not in the first iteration's copy of A
  if (!zeros_polled(lhs, n, problem.should_stop)) {
    report.message = "stopped by the caller";
    return report;
  }
  Vector diag(n), step(n), a_step(n), trial(n);
  double mu = kInitialMu, nu = 2.0;
  const Index watch =
      settings.converged_se > 0.0 && settings.watch_index >= 0 && settings.watch_index < n
          ? settings.watch_index
          : -1;
  int watch_steps = 0;  // accepted steps in a row that hardly moved θ[watch]
  report.message = "maximum number of iterations reached";
  while (report.iterations < settings.max_iterations) {
    if ((problem.should_stop && problem.should_stop()) ||
        (hooks.stop_before && hooks.stop_before(report.iterations + 1))) {
      report.message = "stopped by the caller";
      break;
    }
    if (ne.g.lpNorm<Eigen::Infinity>() <= settings.gradient_tolerance) {
      report.message = "gradient tolerance reached";
      break;
    }
    ++report.iterations;
    diag = ne.a.diagonal().cwiseMax(kMinDiagonal).cwiseMin(kMaxDiagonal);
    lhs = ne.a;  // a plain copy runs at memory speed; dpotrf reads the lower triangle only
    lhs.diagonal() += mu * diag;
    bool accepted = false;
    double rho = 0.0;
    const lapack::Factor f = factor(lhs, problem.should_stop);
    if (f == lapack::Factor::kStopped) {
      report.message = "stopped by the caller";
      break;
    }
    if (f == lapack::Factor::kDone) {
      step = -ne.g;
      lapack::cholesky_solve(lhs.data(), n, step.data());
      const double tol = settings.parameter_tolerance;
      if (step.norm() <= tol * (theta.norm() + tol)) {
        report.message = "parameter tolerance reached";
        break;
      }
      trial = theta + step;
      lapack::symmetric_times(ne.a.data(), n, step.data(), a_step.data());
      const double predicted = -(ne.g.dot(step) + 0.5 * step.dot(a_step));
      if (problem.residuals(trial, r_trial) && r_trial.allFinite() && predicted > 0.0) {
        const double new_cost = 0.5 * r_trial.squaredNorm();
        rho = (cost - new_cost) / predicted;
        accepted = rho > kMinRelativeDecrease;
        if (accepted) {
          const double relative = (cost - new_cost) / cost;
          // The step's predicted fall of χ² (2·predicted / σ̂², σ̂² = 2·cost / m): no more than
          // the Gauss–Newton step's, so only a small one calls for that test below.
          const bool small_step =
              settings.chi2_tolerance > 0.0 && cost > 0.0 &&
              static_cast<double>(m) * predicted < settings.chi2_tolerance * cost;
          if (watch >= 0) {
            const bool small_in_watch =
                mu <= 1e-2 && static_cast<double>(m) * predicted <= cost &&
                std::abs(step(watch)) <=
                    settings.converged_se * damped_standard_error(lhs, watch, cost, m);
            watch_steps = small_in_watch ? watch_steps + 1 : 0;
          }
          theta = trial;
          r.swap(r_trial);
          cost = new_cost;
          report.final_cost = cost;
          ++report.accepted;
          if (hooks.on_accepted) hooks.on_accepted(report.iterations, theta, cost);
          if (relative <= settings.function_tolerance) {
            report.message = "function tolerance reached";
            break;
          }
          if (watch_steps >= 3) {
            std::ostringstream msg;
            msg << "converged: three steps in a row each moved the damping parameter by less "
                   "than "
                << settings.converged_se << " of its standard error";
            report.message = msg.str();
            break;
          }
          if (!linearise()) {
            report.message = problem.should_stop && problem.should_stop()
                                 ? "stopped by the caller"
                                 : "the Jacobian became non-finite";
            break;
          }
          // At the new iterate: the whole decrease the local model has left.
          if (small_step && gauss_newton_chi2_fall(ne.a, ne.g, cost, m, lhs, problem.should_stop) <
                                settings.chi2_tolerance) {
            std::ostringstream msg;
            msg << "converged: the Gauss-Newton step left would lower chi-square by less than "
                << settings.chi2_tolerance;
            report.message = msg.str();
            break;
          }
        }
      }
    }
    if (accepted) {
      const double t = 2.0 * rho - 1.0;
      mu = std::max(kMinMu, mu * std::max(1.0 / 3.0, 1.0 - t * t * t));
      nu = 2.0;
    } else {
      mu *= nu;
      nu *= 2.0;
      if (mu > kMaxMu) {
        report.message = "the damping grew past 1e32 without an acceptable step";
        break;
      }
    }
  }
  return report;
}

}  // namespace csympnet
