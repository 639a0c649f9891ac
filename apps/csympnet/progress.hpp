// A one-line training progress display on a terminal: the stage (AdamW epochs, LM or L-BFGS
// iterations), loss, validation loss, γ̂, and for AdamW the ETA.
// Prints nothing when stderr is not a terminal or when quiet. The callback stops training
// (returns false) once SIGINT or SIGTERM has arrived (interrupt.hpp).
#pragma once

#include <chrono>
#include <string>

#include "csympnet/train/trainer.hpp"

namespace csympnet::cli {

// The progress line's name of a stage ("adamw" -> "AdamW epoch", "lm" -> "Levenberg-Marquardt
// iteration", ...).
const char* stage_words(const char* stage);
// A second stage's termination message in plain words: "maximum number of iterations
// reached" -> "used the full iteration budget", Ceres' "Function tolerance reached. ..." ->
// "converged: the loss stopped changing"; other messages unchanged.
std::string ending_words(const std::string& termination);
// The summary line of an LM stage, e.g. "Levenberg-Marquardt: 300 iterations (290 accepted),
// used the full iteration budget; kept iterate 62, the best on held-out data".
std::string lm_summary_words(long iterations, long accepted, long kept_iterate,
                             const std::string& termination);
// The name of the validation residual that `train` and `fit` print (val_relative_residual):
// the held-out error as a share of what the data move.
inline constexpr const char* kHeldOutResidualWords = "held-out error relative to the motion";

class ProgressLine {
 public:
  explicit ProgressLine(bool quiet);
  ~ProgressLine();  // ends the line if one was drawn
  ProgressCallback callback();
  bool active() const { return active_; }

 private:
  bool active_;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_;
  double last_draw_ = -1.0;
};

}  // namespace csympnet::cli
