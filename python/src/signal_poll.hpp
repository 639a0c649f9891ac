// How often the module takes the GIL to look for Python's pending signals (Ctrl-C) while the
// library computes without it. Taking the GIL while another Python thread runs waits for
// that thread's switch interval (5 ms by default): polled every 2 ms, 20,000 s1 epochs took
// 4.5-13 s beside a busy Python thread instead of 0.42 s alone. Every 50 ms bounds that wait
// to about a tenth of the time and adds at most 50 ms to a Ctrl-C.
#pragma once

#include <chrono>

namespace csympnet::py_binding {

inline constexpr std::chrono::milliseconds kSignalPollInterval{50};

// True when the last poll that returned true was at least kSignalPollInterval ago (and on the
// first call). One clock per polling site; not thread-safe (each site polls from one thread).
class SignalPollClock {
 public:
  bool due() {
    const auto now = std::chrono::steady_clock::now();
    if (polled_ && now - last_ < kSignalPollInterval) return false;
    polled_ = true;
    last_ = now;
    return true;
  }

 private:
  bool polled_ = false;
  std::chrono::steady_clock::time_point last_{};
};

}  // namespace csympnet::py_binding
