// Second-stage optimisers for map models on the one-step loss, run after AdamW
// (docs/identification.md). The one-step loss is a badly conditioned nonlinear least-squares
// problem; a trust-region Gauss–Newton method (Levenberg–Marquardt, Ceres' or our own on
// BLAS) reaches its floor where first-order methods stall. L-BFGS (Ceres' GradientProblemSolver)
// needs only the loss and its gradient, for models whose residual Jacobian is too large to hold.
//
// Checkpointing: the stage extends the best-validation rule (IterationMonitor, callbacks.hpp).
// Its starting point (AdamW's checkpoint) and every iterate are validated, and the one with the
// lowest validation loss is kept, so a second stage can never return parameters that validate
// worse than it got.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/core/options.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/train/callbacks.hpp"

namespace csympnet {

// The second stage: none (the paper's recipe: AdamW only), lm (Levenberg–Marquardt on the
// residuals with their exact Jacobian) or lbfgs (L-BFGS with a Wolfe line search on the loss).
enum class RefineMethod { kNone, kLm, kLbfgs };
// LM's linear solver: Ceres' dense_qr (the better conditioned) or dense_normal_cholesky (forms
// JᵀJ; faster for many residuals, squares the condition), or blas_normal_cholesky: csympnet's
// LM (train/levenberg_marquardt.hpp), JᵀJ formed once per Jacobian with BLAS; the fastest for
// thousands of parameters.
enum class LinearSolver { kDenseQr, kDenseNormalCholesky, kBlasNormalCholesky };

// The one spelling of each value ("none", "lm", "lbfgs"; "dense_qr", "dense_normal_cholesky",
// "blas_normal_cholesky"), in reports, model files, the CLI and Python; the names lists are in
// enum order.
std::string to_string(RefineMethod m);
std::string to_string(LinearSolver s);
const std::vector<std::string>& refine_method_names();
const std::vector<std::string>& linear_solver_names();
// The value spelt `text`; anything else is refused with an Error naming `option` and the
// accepted spellings.
RefineMethod parse_refine_method(const std::string& text,
                                 const std::string& option = "refine.method (--refine)");
LinearSolver parse_linear_solver(
    const std::string& text, const std::string& option = "refine.linear_solver (--refine-solver)");

// The range of the second stage's iteration budget as the front ends give it.
inline constexpr OptionRange kRefineIterationsRange{
    .key = "refine_iterations", .lo = 1, .hi = 1e8, .whole = true};

struct RefineOptions {
  RefineMethod method = RefineMethod::kNone;
  // Iteration budget (trial steps, accepted or not, for lm; gradient iterations for lbfgs).
  long iterations = 300;
  LinearSolver linear_solver = LinearSolver::kDenseQr;  // lm only
  // Stop when the relative change of the loss falls below this (Ceres function_tolerance).
  double function_tolerance = 1e-15;
  // Stop when the max-norm of the gradient falls below this (Ceres gradient_tolerance).
  double gradient_tolerance = 1e-20;
  // Stop when the relative step falls below this (Ceres parameter_tolerance).
  double parameter_tolerance = 1e-15;
  // L-BFGS history length (Ceres max_lbfgs_rank).
  int lbfgs_rank = 20;
  // Keep the iterate with the lowest validation loss (true) or the last one (false).
  bool keep_best_validation = true;
  void validate() const;
};
void to_json(nlohmann::json& j, const RefineOptions& o);
void from_json(const nlohmann::json& j, RefineOptions& o);

struct RefineSummary {
  RefineMethod method = RefineMethod::kNone;
  long iterations = 0;             // iterations the optimiser ran
  long best_iteration = 0;         // iterate kept (0 = the starting point)
  double train_loss_before = 0.0;  // one-step loss (mean over pairs) on the training pairs
  double train_loss_after = 0.0;   // ... at the kept parameters
  double val_loss_before = 0.0;
  double val_loss_after = 0.0;
  double seconds = 0.0;
  std::string termination;  // the optimiser's termination message
  bool stopped = false;     // ended early because the caller asked (an interrupt)
  std::string brief_report() const;
};
// Every field but the wall time, so that reports stay bit-identical run to run.
void to_json(nlohmann::json& j, const RefineSummary& s);

// The most floating-point work one Ceres LM iteration may take (3e9, about 0.3 s on one core
// here): Ceres factors the whole Jacobian in one call that cannot be interrupted, so a larger
// problem would not stop within a second of Ctrl-C. csympnet's own LM
// (blas_normal_cholesky) polls between blocks of its work and has no such limit.
inline constexpr double kMaxCeresIterationFlops = 3e9;
// The work of one LM iteration with Ceres' `linear_solver` on an m × n Jacobian: 2mn² for
// dense_qr, mn² + n³/3 for dense_normal_cholesky.
double ceres_iteration_flops(LinearSolver linear_solver, Index n_residuals, Index n_params);
// Refuses a Ceres linear solver for a problem past kMaxCeresIterationFlops with an
// OptionError for refine_solver naming the solver that fits; call before training, so no work
// is lost.
void check_refine_fits(const RefineOptions& options, Index n_residuals, Index n_params);

// Refines theta in place. With method "none", returns a summary of zero iterations.
// `callbacks` (callbacks.hpp): `progress` sees every accepted iterate (stage "lm" or "lbfgs")
// and may end the stage; `should_stop` is polled before every residual or loss evaluation and
// after every iteration, and once it returns true the optimiser ends at the next poll
// (evaluations are refused, so a Ceres iteration in progress ends early); `patience` ends the
// stage after that many iterations without a better validation loss (a normal end, like a
// tolerance: termination "no better validation loss in N iterations"). However it ends, the best
// iterate so far is kept as usual; an interrupt or a callback's stop sets `stopped`, with
// termination "interrupted" or "stopped by the progress callback".
RefineSummary refine_one_step_map(const OneStepMap& map, Vector& theta, const PairSet& train,
                                  const PairSet& val, const RefineOptions& options,
                                  const IterationCallbacks& callbacks = {});

}  // namespace csympnet
