#include "csympnet/core/stop.hpp"

#include <atomic>

namespace csympnet {

namespace {
std::atomic<StopPoll> g_poll{nullptr};
}  // namespace

void set_stop_poll(StopPoll poll) {
  g_poll.store(poll);
}

bool stop_requested() {
  const StopPoll poll = g_poll.load(std::memory_order_relaxed);
  return poll != nullptr && poll();
}

void throw_if_stop_requested(const std::string& what) {
  if (stop_requested()) throw StopRequested(what + " stopped on request");
}

}  // namespace csympnet
