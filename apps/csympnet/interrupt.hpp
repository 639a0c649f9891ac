// SIGINT and SIGTERM end long commands cleanly: the handler only records the signal; training
// loops poll `interrupted()` through their progress callback, stop at the next validation,
// keep their best checkpoint, and the command exits with 128 + the signal number (130 for
// Ctrl-C, 143 for SIGTERM) after saying what it saved. A second signal kills as usual.
#pragma once

#include <stdexcept>
#include <string>

namespace csympnet::cli {

void install_interrupt_handlers();
bool interrupted();
int interrupt_exit_code();  // 128 + signal, or 0 if none arrived
const char* interrupt_name();

// Thrown by a command after it has saved what it could; main() prints it and exits with
// interrupt_exit_code().
class Interrupted : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Thrown by `fit` after it has written its report when the data do not identify γ; main()
// prints it and exits with kNotIdentifiedExitCode.
class NotIdentified : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
constexpr int kNotIdentifiedExitCode = 4;

// Thrown by `fit` after it has written its report when a check of the model's assumptions
// fails (the data break the model: energy gain, amplitude-dependent or mode-dependent damping,
// structured residuals); main() prints it and exits with kModelRejectedExitCode.
class ModelRejected : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
constexpr int kModelRejectedExitCode = 5;
}  // namespace csympnet::cli
