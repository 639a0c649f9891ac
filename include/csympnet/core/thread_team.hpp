// A small team of threads that runs one job at a time on every member, for work split into a
// fixed number of parts (the column-split training epoch: column_split.hpp).
//
// Why not a general pool: an epoch of the paper's presets takes 0.1 to 10 ms and meets the
// team three times, so what matters is the cost of a meeting. Every wait (a worker's for the
// next job, the caller's for the workers) spins for a while (half a millisecond), so
// back-to-back epochs never pay for a sleep and a wake-up, and then sleeps on the atomic it
// waits for (a futex), woken only if someone sleeps. A team larger than the machine's core
// count does not spin at all: a spinning thread would take the core its partner needs.
#pragma once

#include <atomic>
#include <cstdint>
#include <exception>
#include <functional>
#include <thread>
#include <vector>

namespace csympnet {

class ThreadTeam {
 public:
  // A team of `threads` members: the calling thread and threads − 1 workers. Throws Error
  // unless 1 <= threads <= kMaxThreads.
  explicit ThreadTeam(int threads);
  ~ThreadTeam();
  ThreadTeam(const ThreadTeam&) = delete;
  ThreadTeam& operator=(const ThreadTeam&) = delete;

  static constexpr int kMaxThreads = 256;

  int size() const { return static_cast<int>(workers_.size()) + 1; }

  // Runs job(i) for every member i in [0, size()), member 0 on the calling thread, and returns
  // when all have returned. If jobs throw, the first member's exception (by index) is rethrown
  // here after all have returned. Not reentrant: one run() at a time.
  void run(const std::function<void(int)>& job);

 private:
  void work(int member);

  std::vector<std::thread> workers_;
  std::vector<std::exception_ptr> errors_;
  const std::function<void(int)>* job_ = nullptr;
  std::atomic<std::uint64_t> generation_{0};  // bumped once per job (and once to stop)
  std::atomic<int> pending_{0};               // workers still running the current job
  std::atomic<int> sleepers_{0};              // threads asleep (or about to be) in a wait
  std::atomic<bool> stop_{false};
  bool spin_ = true;  // false when the team outnumbers the cores
};

}  // namespace csympnet
