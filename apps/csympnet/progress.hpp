// A one-line training progress display on a terminal: the stage (AdamW epochs, LM or L-BFGS
// iterations), loss, validation loss, γ̂, and for AdamW the ETA.
// Prints nothing when stderr is not a terminal or when quiet. The callback stops training
// (returns false) once SIGINT or SIGTERM has arrived (interrupt.hpp).
#pragma once

#include <chrono>

#include "csympnet/train/trainer.hpp"

namespace csympnet::cli {

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
