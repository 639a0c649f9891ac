#include "csympnet/train/callbacks.hpp"

#include <limits>
#include <utility>

namespace csympnet {

IterationMonitor::IterationMonitor(const char* stage, long budget, Validation validation,
                                   const Vector& start, const IterationCallbacks& callbacks,
                                   DampingRate damping_rate)
    : stage_(stage),
      budget_(budget),
      validation_(std::move(validation)),
      damping_rate_(std::move(damping_rate)),
      callbacks_(callbacks),
      start_time_(std::chrono::steady_clock::now()),
      best_(start) {
  start_loss_ = best_loss_ = validation_(start);
}

bool IterationMonitor::accept(long iteration, const Vector& theta, double train_loss) {
  const double loss = validation_(theta);
  // Losses are >= 0 or not finite; NaN and +inf are never below a best, so a non-finite
  // iterate is never kept.
  if (loss < best_loss_) {
    best_loss_ = loss;
    best_ = theta;
    best_iteration_ = iteration;
  }
  if (!callbacks_.progress) return true;
  TrainProgress p;
  p.stage = stage_;
  p.epoch = iteration;
  p.epochs = budget_;
  p.train_loss = train_loss;
  p.val_loss = loss;
  p.best_val_loss = best_loss_;
  const auto gamma = damping_rate_ ? damping_rate_(theta) : std::nullopt;
  p.gamma_hat = gamma.value_or(std::numeric_limits<double>::quiet_NaN());
  p.seconds = seconds();
  if (callbacks_.progress(p)) return true;
  // A front end's callback also says no once interrupted: name the interrupt when it is one.
  if (!interrupted()) cause_ = StopCause::kCallback;
  return false;
}

bool IterationMonitor::stop_before(long iteration) {
  if (cause_ != StopCause::kNone || interrupted()) return true;
  if (callbacks_.patience > 0 && iteration - best_iteration_ > callbacks_.patience) {
    cause_ = StopCause::kPatience;
    return true;
  }
  return false;
}

bool IterationMonitor::interrupted() const {
  if (cause_ == StopCause::kInterrupt) return true;
  if (callbacks_.should_stop && callbacks_.should_stop()) {
    cause_ = StopCause::kInterrupt;
    return true;
  }
  return false;
}

double IterationMonitor::seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time_).count();
}

}  // namespace csympnet
