#include "csympnet/train/refine.hpp"

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
    << " s; train loss " << train_loss_before << " -> " << train_loss_after << ", validation loss "
    << val_loss_before << " -> " << val_loss_after << " (iterate " << best_iteration << "; "
    << termination << ")";
  return s.str();
}

void to_json(nlohmann::json& j, const RefineSummary& s) {
  j = {{"method", to_string(s.method)},          {"iterations", s.iterations},
       {"best_iteration", s.best_iteration},     {"train_loss_before", s.train_loss_before},
       {"train_loss_after", s.train_loss_after}, {"val_loss_before", s.val_loss_before},
       {"val_loss_after", s.val_loss_after},     {"termination", s.termination}};
}

namespace {

// The caller's stop request, remembered once seen: every optimiser below polls it before each
// evaluation and after each iteration.
class StopPoll {
 public:
  explicit StopPoll(const std::function<bool()>& should_stop) : should_stop_(should_stop) {}
  bool operator()() const {
    if (!stopped_ && should_stop_ && should_stop_()) stopped_ = true;
    return stopped_;
  }
  bool stopped() const { return stopped_; }

 private:
  const std::function<bool()>& should_stop_;
  mutable bool stopped_ = false;
};

// Residuals scaled by 1/√N, so that Ceres' cost ½‖r̃‖² is L/2.
class OneStepResiduals final : public ceres::CostFunction {
 public:
  OneStepResiduals(const OneStepMap& map, const PairSet& pairs, const StopPoll& stop)
      : map_(map), pairs_(pairs), stop_(stop) {
    set_num_residuals(static_cast<int>(pairs.size() * pairs.dim()));
    mutable_parameter_block_sizes()->push_back(static_cast<int>(map.n_params()));
    scale_ = 1.0 / std::sqrt(static_cast<double>(pairs.size()));
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    if (stop_()) return false;  // a refused evaluation ends the iteration; the callback stops
    const Eigen::Map<const Vector> theta(parameters[0], map_.n_params());
    const Vector r = one_step_residuals(map_, theta, pairs_);
    Eigen::Map<Vector>(residuals, r.size()) = scale_ * r;
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      Eigen::Map<RowMajorMatrix> jac(jacobians[0], r.size(), map_.n_params());
      residual_jacobian(map_, theta, pairs_, jac, [this] { return stop_(); });
      if (stop_()) return false;
      jac *= scale_;
    }
    return r.allFinite();
  }

 private:
  const OneStepMap& map_;
  const PairSet& pairs_;
  const StopPoll& stop_;
  double scale_ = 1.0;
};

// The one-step loss and its gradient for L-BFGS (Ceres minimises the value as given).
class OneStepLossFunction final : public ceres::FirstOrderFunction {
 public:
  OneStepLossFunction(const OneStepMap& map, const PairSet& pairs, const StopPoll& stop)
      : map_(map), pairs_(pairs), stop_(stop) {}
  bool Evaluate(const double* parameters, double* cost, double* gradient) const override {
    if (stop_()) return false;
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
  const StopPoll& stop_;
  mutable Vector grad_;
  mutable ForwardCache cache_;
};

// Validates iterates and remembers the best. `consider` reads the parameter array, which both
// optimisers update in place (Ceres writes every iterate there first, since
// update_state_every_iteration is on).
class BestValidation {
 public:
  BestValidation(const OneStepMap& map, const PairSet& val, const double* params,
                 const Vector& start, double start_loss)
      : map_(map), val_(val), params_(params), best_(start), best_loss_(start_loss) {}
  void consider(long iteration) {
    const Eigen::Map<const Vector> theta(params_, best_.size());
    const double loss = one_step_loss(map_, theta, val_);
    if (loss < best_loss_) {
      best_loss_ = loss;
      best_ = theta;
      best_iteration_ = iteration;
    }
  }
  const Vector& best() const { return best_; }
  double best_loss() const { return best_loss_; }
  long best_iteration() const { return best_iteration_; }

 private:
  const OneStepMap& map_;
  const PairSet& val_;
  const double* params_;
  Vector best_;
  double best_loss_;
  long best_iteration_ = 0;
};

// Hands Ceres' accepted iterates to BestValidation, and ends the solve once a stop is asked.
class CeresBestValidation final : public ceres::IterationCallback {
 public:
  CeresBestValidation(BestValidation& best, const StopPoll& stop) : best_(best), stop_(stop) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& it) override {
    if (stop_()) return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    if (it.iteration != 0 && it.step_is_successful) best_.consider(it.iteration);
    return ceres::SOLVER_CONTINUE;
  }

 private:
  BestValidation& best_;
  const StopPoll& stop_;
};

// The one-step residuals and their Jacobian, scaled by 1/√N like OneStepResiduals.
LeastSquaresProblem one_step_problem(const OneStepMap& map, const PairSet& pairs,
                                     const StopPoll& stop) {
  LeastSquaresProblem p;
  p.n_residuals = pairs.size() * pairs.dim();
  p.n_params = map.n_params();
  const double scale = 1.0 / std::sqrt(static_cast<double>(pairs.size()));
  p.residuals = [&map, &pairs, scale, &stop](ConstParams theta, Eigen::Ref<Vector> r) {
    if (stop()) return false;  // a refused trial step; the loop then stops
    r = scale * one_step_residuals(map, theta, pairs);
    return r.allFinite();
  };
  p.jacobian = [&map, &pairs, scale, &stop](ConstParams theta, Eigen::Ref<RowMajorMatrix> jac) {
    residual_jacobian(map, theta, pairs, jac, [&stop] { return stop(); });
    jac *= scale;  // when stopped, the solver sees the stop before it uses jac
  };
  return p;
}

// What Ceres' LM and L-BFGS options share: the budget and tolerances, silence, and the
// best-validation callback, which needs the iterate after every step.
template <class SolverOptions>
void set_common_options(SolverOptions& so, const RefineOptions& options,
                        CeresBestValidation& callback) {
  so.max_num_iterations = static_cast<int>(options.iterations);
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.update_state_every_iteration = true;
  so.callbacks.push_back(&callback);
}

}  // namespace

RefineSummary refine_one_step_map(const OneStepMap& map, Vector& theta, const PairSet& train,
                                  const PairSet& val, const RefineOptions& options,
                                  const std::function<bool()>& should_stop) {
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
  s.val_loss_before = one_step_loss(map, theta, val);
  if (options.method == RefineMethod::kNone) {
    s.train_loss_after = s.train_loss_before;
    s.val_loss_after = s.val_loss_before;
    s.termination = "no second stage";
    return s;
  }

  const Vector initial = theta;
  BestValidation best(map, val, theta.data(), initial, s.val_loss_before);
  const StopPoll stop(should_stop);
  if (options.method == RefineMethod::kLm &&
      options.linear_solver == LinearSolver::kBlasNormalCholesky) {
    LmSettings ls;
    ls.max_iterations = options.iterations;
    ls.function_tolerance = options.function_tolerance;
    ls.gradient_tolerance = options.gradient_tolerance;
    ls.parameter_tolerance = options.parameter_tolerance;
    LeastSquaresProblem problem = one_step_problem(map, train, stop);
    problem.should_stop = [&stop] { return stop(); };
    const LmReport lr =
        levenberg_marquardt(problem, theta, ls, [&best](long it) { best.consider(it); });
    s.iterations = lr.iterations;
    s.termination = lr.message;
  } else if (options.method == RefineMethod::kLm) {
    ceres::Problem::Options po;
    po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(po);
    OneStepResiduals residuals(map, train, stop);
    problem.AddResidualBlock(&residuals, nullptr, theta.data());
    ceres::Solver::Options so;
    so.minimizer_type = ceres::TRUST_REGION;
    so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    so.linear_solver_type = options.linear_solver == LinearSolver::kDenseQr
                                ? ceres::DENSE_QR
                                : ceres::DENSE_NORMAL_CHOLESKY;
    so.num_threads = 1;  // same seed, same bits
    CeresBestValidation callback(best, stop);
    set_common_options(so, options, callback);
    ceres::Solver::Summary cs;
    ceres::Solve(so, &problem, &cs);
    s.iterations = static_cast<long>(cs.iterations.size()) - 1;
    s.termination = cs.message;
  } else {
    ceres::GradientProblem problem(new OneStepLossFunction(map, train, stop));
    ceres::GradientProblemSolver::Options so;
    so.line_search_direction_type = ceres::LBFGS;
    so.line_search_type = ceres::WOLFE;
    so.max_lbfgs_rank = options.lbfgs_rank;
    CeresBestValidation callback(best, stop);
    set_common_options(so, options, callback);
    ceres::GradientProblemSolver::Summary cs;
    ceres::Solve(so, problem, theta.data(), &cs);
    s.iterations = static_cast<long>(cs.iterations.size()) - 1;
    s.termination = cs.message;
  }
  if (stop.stopped()) {
    s.stopped = true;
    s.termination = "interrupted";
  }
  if (options.keep_best_validation) {
    theta = best.best();
    s.best_iteration = best.best_iteration();
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
