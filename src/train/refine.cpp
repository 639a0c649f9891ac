#include "csympnet/train/refine.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <sstream>

#include <ceres/ceres.h>

#include "csympnet/core/error.hpp"
#include "csympnet/train/levenberg_marquardt.hpp"
#include "csympnet/train/loss.hpp"
#include "csympnet/train/residual_jacobian.hpp"
#include "csympnet/train/termination_words.hpp"

namespace csympnet {

namespace {
// "'a', 'b' or 'c'"
std::string quoted_alternatives(const std::vector<std::string>& names) {
  std::string s;
  for (std::size_t i = 0; i < names.size(); ++i)
    s += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + ("'" + names[i] + "'");
  return s;
}

template <typename Enum>
Enum parse_name(const std::vector<std::string>& names, const std::string& text,
                const std::string& option) {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == text) return static_cast<Enum>(i);
  throw Error(option + " must be " + quoted_alternatives(names) + ", got '" + text + "'");
}
}  // namespace

const std::vector<std::string>& refine_method_names() {
  static const std::vector<std::string> names = {"none", "lm", "lbfgs"};
  return names;
}

const std::vector<std::string>& linear_solver_names() {
  static const std::vector<std::string> names = {"dense_qr", "dense_normal_cholesky",
                                                 "blas_normal_cholesky"};
  return names;
}

std::string to_string(RefineMethod m) {
  return refine_method_names().at(static_cast<std::size_t>(m));
}

std::string to_string(LinearSolver s) {
  return linear_solver_names().at(static_cast<std::size_t>(s));
}

RefineMethod parse_refine_method(const std::string& text, const std::string& option) {
  return parse_name<RefineMethod>(refine_method_names(), text, option);
}

LinearSolver parse_linear_solver(const std::string& text, const std::string& option) {
  return parse_name<LinearSolver>(linear_solver_names(), text, option);
}

void RefineOptions::validate() const {
  kRefineIterationsRange.check(iterations);
  auto tol_ok = [](double x) { return std::isfinite(x) && x >= 0.0; };
  require(tol_ok(function_tolerance), "refine.function_tolerance must be a finite number >= 0");
  require(tol_ok(gradient_tolerance), "refine.gradient_tolerance must be a finite number >= 0");
  require(tol_ok(parameter_tolerance), "refine.parameter_tolerance must be a finite number >= 0");
  require(lbfgs_rank >= 1,
          [&] { return "refine.lbfgs_rank must be >= 1, got " + std::to_string(lbfgs_rank); });
}

double ceres_iteration_flops(LinearSolver linear_solver, Index n_residuals, Index n_params) {
  const double m = static_cast<double>(n_residuals), n = static_cast<double>(n_params);
  return linear_solver == LinearSolver::kDenseQr ? 2.0 * m * n * n : m * n * n + n * n * n / 3.0;
}

void check_refine_fits(const RefineOptions& options, Index n_residuals, Index n_params) {
  if (options.method != RefineMethod::kLm ||
      options.linear_solver == LinearSolver::kBlasNormalCholesky)
    return;
  const double flops = ceres_iteration_flops(options.linear_solver, n_residuals, n_params);
  if (flops <= kMaxCeresIterationFlops) return;
  throw OptionError("refine_solver",
                    to_string(options.linear_solver) + " with " + std::to_string(n_params) +
                        " parameters and " + std::to_string(n_residuals) + " residuals takes " +
                        number_text(flops) +
                        " operations per LM iteration in one Ceres call that Ctrl-C cannot "
                        "stop; expected at most " +
                        number_text(kMaxCeresIterationFlops) +
                        ": use {refine_solver=blas_normal_cholesky} (csympnet's LM, which stops "
                        "promptly), or {refine=auto}");
}

void to_json(nlohmann::json& j, const RefineOptions& o) {
  j = {{"method", to_string(o.method)},
       {"iterations", o.iterations},
       {"linear_solver", to_string(o.linear_solver)},
       {"function_tolerance", o.function_tolerance},
       {"gradient_tolerance", o.gradient_tolerance},
       {"parameter_tolerance", o.parameter_tolerance},
       {"lbfgs_rank", o.lbfgs_rank},
       {"keep_best_validation", o.keep_best_validation}};
}

void from_json(const nlohmann::json& j, RefineOptions& o) {
  if (j.contains("method")) o.method = parse_refine_method(j.at("method").get<std::string>());
  o.iterations = j.value("iterations", o.iterations);
  if (j.contains("linear_solver"))
    o.linear_solver = parse_linear_solver(j.at("linear_solver").get<std::string>());
  o.function_tolerance = j.value("function_tolerance", o.function_tolerance);
  o.gradient_tolerance = j.value("gradient_tolerance", o.gradient_tolerance);
  o.parameter_tolerance = j.value("parameter_tolerance", o.parameter_tolerance);
  o.lbfgs_rank = j.value("lbfgs_rank", o.lbfgs_rank);
  o.keep_best_validation = j.value("keep_best_validation", o.keep_best_validation);
}

std::string RefineSummary::brief_report() const {
  std::ostringstream s;
  s << "refine " << to_string(method) << ": " << iterations << " iterations in " << seconds
    << " s, " << termination_words(termination) << "; kept iterate " << best_iteration
    << "; train loss " << train_loss_before << " -> " << train_loss_after << ", validation loss "
    << val_loss_before << " -> " << val_loss_after;
  return s.str();
}

void to_json(nlohmann::json& j, const RefineSummary& s) {
  j = {{"method", to_string(s.method)},          {"iterations", s.iterations},
       {"best_iteration", s.best_iteration},     {"train_loss_before", s.train_loss_before},
       {"train_loss_after", s.train_loss_after}, {"val_loss_before", s.val_loss_before},
       {"val_loss_after", s.val_loss_after},     {"termination", s.termination}};
}

namespace {

// The one-step residuals r(θ) and their Jacobian, scaled by 1/√N so that ½‖r‖² is L/2. The one
// definition of the residuals that both LM solvers minimise: csympnet's directly, Ceres' through
// CeresResiduals. Evaluations are refused once the monitor says the caller wants to stop.
LeastSquaresProblem one_step_problem(const OneStepMap& map, const PairSet& pairs,
                                     const IterationMonitor& monitor) {
  LeastSquaresProblem p;
  p.n_residuals = pairs.size() * pairs.dim();
  p.n_params = map.n_params();
  const double scale = 1.0 / std::sqrt(static_cast<double>(pairs.size()));
  p.residuals = [&map, &pairs, scale, &monitor](ConstParams theta, Eigen::Ref<Vector> r) {
    if (monitor.interrupted()) return false;  // a refused trial step; the loop then stops
    r = scale * one_step_residuals(map, theta, pairs);
    return r.allFinite();
  };
  p.jacobian = [&map, &pairs, scale, &monitor](ConstParams theta, Eigen::Ref<RowMajorMatrix> jac) {
    residual_jacobian(map, theta, pairs, jac, [&monitor] { return monitor.interrupted(); });
    // Scaled in blocks of rows, polled between them (6,400 × 4,111 entries took 0.5 s under the
    // sanitizers); when stopped, the solver sees the stop before it uses jac.
    constexpr Index kRows = 256;
    for (Index i = 0; i < jac.rows(); i += kRows) {
      if (monitor.interrupted()) return;
      jac.middleRows(i, std::min(kRows, jac.rows() - i)) *= scale;
    }
  };
  p.should_stop = [&monitor] { return monitor.interrupted(); };
  return p;
}

// A LeastSquaresProblem as a Ceres cost function (one residual block over all of θ).
class CeresResiduals final : public ceres::CostFunction {
 public:
  explicit CeresResiduals(const LeastSquaresProblem& problem) : problem_(problem) {
    set_num_residuals(static_cast<int>(problem.n_residuals));
    mutable_parameter_block_sizes()->push_back(static_cast<int>(problem.n_params));
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Map<const Vector> theta(parameters[0], problem_.n_params);
    Eigen::Map<Vector> r(residuals, problem_.n_residuals);
    if (!problem_.residuals(theta, r)) return false;  // not finite, or stopped
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      Eigen::Map<RowMajorMatrix> jac(jacobians[0], problem_.n_residuals, problem_.n_params);
      problem_.jacobian(theta, jac);
      // A refused evaluation ends the iteration; the iteration callback then ends the solve.
      if (problem_.should_stop()) return false;
    }
    return true;
  }

 private:
  const LeastSquaresProblem& problem_;
};

// The one-step loss and its gradient for L-BFGS (Ceres minimises the value as given).
class OneStepLossFunction final : public ceres::FirstOrderFunction {
 public:
  OneStepLossFunction(const OneStepMap& map, const PairSet& pairs, const IterationMonitor& monitor)
      : map_(map), pairs_(pairs), monitor_(monitor) {}
  bool Evaluate(const double* parameters, double* cost, double* gradient) const override {
    if (monitor_.interrupted()) return false;
    const Eigen::Map<const Vector> theta(parameters, map_.n_params());
    if (gradient == nullptr) {
      *cost = one_step_loss(map_, theta, pairs_);
      return std::isfinite(*cost);
    }
    *cost = one_step_loss(map_, theta, pairs_, &grad_, &cache_);
    Eigen::Map<Vector>(gradient, map_.n_params()) = grad_;
    return std::isfinite(*cost) && grad_.allFinite();
  }
  int NumParameters() const override { return static_cast<int>(map_.n_params()); }

 private:
  const OneStepMap& map_;
  const PairSet& pairs_;
  const IterationMonitor& monitor_;
  mutable Vector grad_;
  mutable ForwardCache cache_;
};

// Hands each of Ceres' successful iterates to the monitor, and ends the solve when the monitor
// says stop. Ceres gives a callback no parameters: it reads `theta`, the parameter block itself,
// which holds the current iterate only because update_state_every_iteration is on;
// set_common_options sets that in the same place as it registers this callback.
class CeresMonitor final : public ceres::IterationCallback {
 public:
  CeresMonitor(IterationMonitor& monitor, const Vector& theta) : monitor_(monitor), theta_(theta) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& it) override {
    if (it.iteration != 0 && it.step_is_successful)
      monitor_.accept(it.iteration, theta_, 2.0 * it.cost);  // Ceres' cost is L/2
    if (monitor_.stop_before(it.iteration + 1)) return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    return ceres::SOLVER_CONTINUE;
  }

 private:
  IterationMonitor& monitor_;
  const Vector& theta_;
};

// What Ceres' LM and L-BFGS options share: the budget and tolerances, silence, and the monitor,
// which needs the iterate in the parameter block after every step.
template <class SolverOptions>
void set_common_options(SolverOptions& so, const RefineOptions& options, CeresMonitor& monitor) {
  so.max_num_iterations = static_cast<int>(options.iterations);
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.update_state_every_iteration = true;
  so.callbacks.push_back(&monitor);
}

}  // namespace

RefineSummary refine_one_step_map(const OneStepMap& map, Vector& theta, const PairSet& train,
                                  const PairSet& val, const RefineOptions& options,
                                  const IterationCallbacks& callbacks) {
  options.validate();
  train.validate("training pairs");
  val.validate("validation pairs");
  require(train.dim() == map.dim() && val.dim() == map.dim(),
          "refine: data dimension does not match the model's phase-space dimension");
  require(theta.size() == map.n_params(), "refine: parameter vector has the wrong size");
  check_refine_fits(options, train.size() * train.dim(), map.n_params());
  const auto start = std::chrono::steady_clock::now();

  RefineSummary s;
  s.method = options.method;
  s.train_loss_before = one_step_loss(map, theta, train);
  if (options.method == RefineMethod::kNone) {
    s.val_loss_before = s.val_loss_after = one_step_loss(map, theta, val);
    s.train_loss_after = s.train_loss_before;
    s.termination = "no second stage";
    return s;
  }

  const Vector initial = theta;
  IterationMonitor monitor(
      options.method == RefineMethod::kLm ? "lm" : "lbfgs", options.iterations,
      [&map, &val](const Vector& t) { return one_step_loss(map, t, val); }, theta, callbacks,
      [&map](const Vector& t) { return map.damping_rate(t); });
  s.val_loss_before = monitor.start_loss();
  if (options.method == RefineMethod::kLm &&
      options.linear_solver == LinearSolver::kBlasNormalCholesky) {
    // The paper's second stage: its tolerances and budget only. `fit`'s ends (χ² settled,
    // LmSettings::chi2_tolerance; γ̂ settled within a share of its standard error,
    // watch_index) are left off on purpose: `train` reproduces the paper's recipe, so that its
    // iterations and losses stay comparable with the paper's tables.
    LmSettings ls;
    ls.max_iterations = options.iterations;
    ls.function_tolerance = options.function_tolerance;
    ls.gradient_tolerance = options.gradient_tolerance;
    ls.parameter_tolerance = options.parameter_tolerance;
    const LmReport lr =
        levenberg_marquardt(one_step_problem(map, train, monitor), theta, ls, lm_hooks(monitor));
    s.iterations = lr.iterations;
    s.termination = lr.message;
  } else if (options.method == RefineMethod::kLm) {
    const LeastSquaresProblem lsp = one_step_problem(map, train, monitor);
    CeresResiduals residuals(lsp);
    ceres::Problem::Options po;
    po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(po);
    problem.AddResidualBlock(&residuals, nullptr, theta.data());
    ceres::Solver::Options so;
    so.minimizer_type = ceres::TRUST_REGION;
    so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    so.linear_solver_type = options.linear_solver == LinearSolver::kDenseQr
                                ? ceres::DENSE_QR
                                : ceres::DENSE_NORMAL_CHOLESKY;
    so.num_threads = 1;  // same seed, same bits
    CeresMonitor callback(monitor, theta);
    set_common_options(so, options, callback);
    ceres::Solver::Summary cs;
    ceres::Solve(so, &problem, &cs);
    s.iterations = static_cast<long>(cs.iterations.size()) - 1;
    s.termination = cs.message;
  } else {
    ceres::GradientProblem problem(new OneStepLossFunction(map, train, monitor));
    ceres::GradientProblemSolver::Options so;
    so.line_search_direction_type = ceres::LBFGS;
    so.line_search_type = ceres::WOLFE;
    so.max_lbfgs_rank = options.lbfgs_rank;
    CeresMonitor callback(monitor, theta);
    set_common_options(so, options, callback);
    ceres::GradientProblemSolver::Summary cs;
    ceres::Solve(so, problem, theta.data(), &cs);
    s.iterations = static_cast<long>(cs.iterations.size()) - 1;
    s.termination = cs.message;
  }
  switch (monitor.cause()) {
    case StopCause::kNone:
      break;
    case StopCause::kPatience:  // a normal end, like a tolerance
      s.termination =
          "no better validation loss in " + std::to_string(callbacks.patience) + " iterations";
      break;
    case StopCause::kInterrupt:
      s.stopped = true;
      s.termination = "interrupted";
      break;
    case StopCause::kCallback:
      s.stopped = true;
      s.termination = "stopped by the progress callback";
      break;
  }
  if (options.keep_best_validation) {
    theta = monitor.best();
    s.best_iteration = monitor.best_iteration();
  } else {
    s.best_iteration = s.iterations;
  }
  // Ceres leaves the final (or best-cost) iterate in theta; a failed evaluation could leave a
  // non-finite one, which is never kept.
  if (!theta.allFinite()) theta = initial;
  s.train_loss_after = one_step_loss(map, theta, train);
  s.val_loss_after = one_step_loss(map, theta, val);
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return s;
}

}  // namespace csympnet
