// A small team of threads that runs one job at a time, split into as many parts as the team
// has threads (the column-split training epoch: column_split.hpp).
//
// Why not a general pool: an epoch of the paper's presets takes 0.1 to 10 ms and meets the
// team three times, so what matters is the cost of a meeting. Every wait (a worker's for the
// next job, the caller's for the last part) spins for a while (half a millisecond), so
// back-to-back epochs never pay for a sleep and a wake-up, and then sleeps on the atomic it
// waits for (a futex), woken only if someone sleeps. A team larger than the machine's core
// count does not spin at all: a spinning thread would take the core its partner needs.
//
// Parts are claimed, not assigned: thread t first claims part t (so that, when every thread
// is on time, a part runs where the same part of the previous job ran and its data are in
// that core's cache), then any part still unclaimed. On a busy machine, where a worker may not
// be scheduled for milliseconds, the caller then does the worker's part too, and the job runs
// as fast as one thread would instead of waiting for the worker. What a part computes must
// therefore not depend on which thread runs it.
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
  // A team of `threads` threads: the calling thread and threads − 1 workers. Throws Error
  // unless 1 <= threads <= kMaxThreads.
  explicit ThreadTeam(int threads);
  ~ThreadTeam();
  ThreadTeam(const ThreadTeam&) = delete;
  ThreadTeam& operator=(const ThreadTeam&) = delete;

  static constexpr int kMaxThreads = 256;

  // Threads, and parts of every job.
  int size() const { return static_cast<int>(workers_.size()) + 1; }

  // Runs job(i) once for every part i in [0, size()), each on whichever of the team's threads
  // claims it (the caller included), and returns when all have returned. If parts throw, the
  // exception of the lowest such part is rethrown here after all have returned. Not
  // reentrant: one run() at a time.
  void run(const std::function<void(int)>& job);

 private:
  void work(int thread);
  // Claims and runs parts of job `generation`, part `first` first, until none is left.
  void run_parts(int first, std::uint64_t generation);

  std::vector<std::thread> workers_;
  std::vector<std::exception_ptr> errors_;  // per part
  const std::function<void(int)>* job_ = nullptr;
  std::atomic<std::uint64_t> generation_{0};        // bumped once per job (and once to stop)
  std::vector<std::atomic<std::uint64_t>> claims_;  // per part: the last job that claimed it
  std::atomic<int> done_{0};                        // parts finished
  std::atomic<int> sleepers_{0};                    // threads asleep (or about to be) in a wait
  std::atomic<bool> stop_{false};
  bool spin_ = true;  // false when the team outnumbers the cores
};

}  // namespace csympnet
