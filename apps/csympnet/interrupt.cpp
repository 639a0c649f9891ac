#include "interrupt.hpp"

#include <signal.h>

#include <csignal>

#include "csympnet/core/stop.hpp"

namespace csympnet::cli {

namespace {
volatile std::sig_atomic_t g_signal = 0;

extern "C" void on_signal(int sig) {
  g_signal = sig;
}
}  // namespace

// SA_RESETHAND: a second signal terminates at once. No SA_RESTART: a blocking call (opening a
// FIFO no one writes to, reading a pipe) returns EINTR instead of waiting on, so every stage
// stops promptly; main() reports what failed after a signal as the interruption it is.
void install_interrupt_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESETHAND;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  // The library's stages without a callback (integrators, generation, file reads and parses)
  // poll the same flag.
  set_stop_poll(&interrupted);
}

bool interrupted() {
  return g_signal != 0;
}

int interrupt_exit_code() {
  return g_signal != 0 ? 128 + g_signal : 0;
}

const char* interrupt_name() {
  return g_signal == SIGINT ? "SIGINT" : g_signal == SIGTERM ? "SIGTERM" : "a signal";
}

}  // namespace csympnet::cli
