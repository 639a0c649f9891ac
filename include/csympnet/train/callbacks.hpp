// What every optimiser in train/ does between its iterations, written once: AdamW
// (trainer.hpp), csympnet's Levenberg–Marquardt and Ceres' LM and L-BFGS (refine.hpp), and
// identification's LM on windows (identify/identify.hpp) all hand their iterates to one
// IterationMonitor, which
//   - keeps the iterate with the lowest validation loss (the paper's checkpoint rule: strict
//     '<', so the earliest of equal losses is kept and runs are reproducible),
//   - reports progress to the caller's ProgressCallback, which may end the run,
//   - polls the caller's stop request (an interrupt) and remembers it once seen,
//   - and, when asked, ends a run whose validation loss has not improved for `patience`
//     iterations.
// The optimisers keep only their update rule; the rules above cannot drift apart between them.
#pragma once

#include <chrono>
#include <functional>
#include <limits>
#include <optional>
#include <string>

#include "csympnet/core/types.hpp"

namespace csympnet {

// What a progress callback sees after each validated iterate.
struct TrainProgress {
  const char* stage = "adamw";  // the optimiser: "adamw", "lm" or "lbfgs"
  long epoch = 0;               // epochs (AdamW) or iterations (LM, L-BFGS) done
  long epochs = 0;              // the budget in the same unit
  double train_loss = 0.0;      // AdamW: at the parameters before this epoch's step; LM, L-BFGS:
                                // at the new iterate (NaN where the optimiser does not say)
  double val_loss = 0.0;        // validation loss of the new iterate
  double best_val_loss = 0.0;
  double gamma_hat = 0.0;  // NaN for models without a damping rate
  double seconds = 0.0;    // wall time of this stage so far
};

// Returns false to stop the run; the best iterate so far is kept.
using ProgressCallback = std::function<bool(const TrainProgress&)>;

// What a caller hands to an optimiser. Every member is optional.
struct IterationCallbacks {
  ProgressCallback progress;          // after every validated iterate
  std::function<bool()> should_stop;  // polled often (before each evaluation where it can be)
  long patience = 0;  // > 0: end after this many iterations without a better validation loss
};

// Why a monitored run ended early; kNone while it goes on (or when its budget ran out).
enum class StopCause { kNone, kInterrupt, kCallback, kPatience };

class IterationMonitor {
 public:
  using Validation = std::function<double(const Vector& theta)>;
  using DampingRate = std::function<std::optional<double>(const Vector& theta)>;

  // Validates `start` (iteration 0) as the first best. `stage` names the optimiser in progress
  // reports, `budget` its iteration budget; `damping_rate`, when given, fills gamma_hat.
  IterationMonitor(const char* stage, long budget, Validation validation, const Vector& start,
                   const IterationCallbacks& callbacks, DampingRate damping_rate = {});

  // After iteration `iteration` (1-based) produced `theta`: validates it, keeps it when its loss
  // is strictly below the best, and reports progress. Returns false when the progress callback
  // asked to stop (cause() then says kCallback).
  bool accept(long iteration, const Vector& theta,
              double train_loss = std::numeric_limits<double>::quiet_NaN());
  // Polled before iteration `iteration` (1-based) starts: true once interrupted, or when
  // patience is set and `iteration` comes more than `patience` iterations after the best.
  bool stop_before(long iteration);
  // Polled anywhere, also inside an iteration: true once the caller asked to stop (sticky, so
  // a stop request is never forgotten by a later poll).
  bool interrupted() const;

  StopCause cause() const { return cause_; }
  const Vector& best() const { return best_; }
  double best_loss() const { return best_loss_; }
  double start_loss() const { return start_loss_; }
  long best_iteration() const { return best_iteration_; }
  double seconds() const;

 private:
  const char* stage_;
  long budget_;
  Validation validation_;
  DampingRate damping_rate_;
  const IterationCallbacks& callbacks_;
  std::chrono::steady_clock::time_point start_time_;
  Vector best_;
  double start_loss_;
  double best_loss_;
  long best_iteration_ = 0;
  mutable StopCause cause_ = StopCause::kNone;
};

}  // namespace csympnet
