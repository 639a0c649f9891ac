#include "csympnet/core/thread_team.hpp"

#include <chrono>
#include <string>

#include "csympnet/core/error.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace csympnet {

namespace {

// How long a wait spins before it sleeps: longer than the serial part of an epoch (loss,
// AdamW, a validation pass) on the presets, short enough to hand a core back soon.
constexpr auto kSpin = std::chrono::microseconds(500);

inline void relax() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#else
  std::this_thread::yield();
#endif
}

// Returns once `value` no longer holds `old` (and returns what it holds): spins for up to kSpin
// if `spin`, then sleeps on the atomic. `sleepers` counts the sleepers, so that a notifier
// makes the wake-up call only when someone sleeps. The sleeper registers before it checks
// the value a last time, and the notifier changes the value before it reads `sleepers`
// (both sequentially consistent), so no wake-up is lost.
template <typename T>
T await_change(const std::atomic<T>& value, T old, std::atomic<int>& sleepers, bool spin) {
  T now = value.load(std::memory_order_acquire);
  if (spin) {
    const auto until = std::chrono::steady_clock::now() + kSpin;
    for (int i = 1; now == old; ++i) {
      relax();
      if (i % 256 == 0 && std::chrono::steady_clock::now() > until) break;
      now = value.load(std::memory_order_acquire);
    }
  }
  while (now == old) {
    sleepers.fetch_add(1, std::memory_order_seq_cst);
    if (value.load(std::memory_order_seq_cst) == old) value.wait(old, std::memory_order_acquire);
    sleepers.fetch_sub(1, std::memory_order_relaxed);
    now = value.load(std::memory_order_acquire);
  }
  return now;
}

}  // namespace

ThreadTeam::ThreadTeam(int threads) {
  require(threads >= 1 && threads <= kMaxThreads, [&] {
    return "threads = " + std::to_string(threads) + ", expected 1 to " +
           std::to_string(kMaxThreads);
  });
  const unsigned cores = std::thread::hardware_concurrency();
  spin_ = cores == 0 || static_cast<unsigned>(threads) <= cores;
  errors_.resize(static_cast<std::size_t>(threads));
  claims_ = std::vector<std::atomic<std::uint64_t>>(static_cast<std::size_t>(threads));
  for (auto& c : claims_) c.store(0, std::memory_order_relaxed);  // job 0: none
  workers_.reserve(static_cast<std::size_t>(threads - 1));
  for (int i = 1; i < threads; ++i) workers_.emplace_back([this, i] { work(i); });
}

ThreadTeam::~ThreadTeam() {
  stop_.store(true, std::memory_order_relaxed);
  generation_.fetch_add(1, std::memory_order_seq_cst);
  generation_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void ThreadTeam::run_parts(int first, std::uint64_t generation) {
  const int parts = size();
  for (int k = 0; k < parts; ++k) {
    const int i = (first + k) % parts;
    // A part is claimed for job g by raising its stamp to g. A thread that woke late, for a job
    // already done, finds every stamp at that job or later and claims nothing.
    auto& claim = claims_[static_cast<std::size_t>(i)];
    std::uint64_t stamp = claim.load(std::memory_order_relaxed);
    bool mine = false;
    while (stamp < generation && !mine) {
      mine = claim.compare_exchange_weak(stamp, generation, std::memory_order_acq_rel);
    }
    if (!mine) continue;
    try {
      (*job_)(i);
    } catch (...) {
      errors_[static_cast<std::size_t>(i)] = std::current_exception();
    }
    if (done_.fetch_add(1, std::memory_order_seq_cst) + 1 == parts &&
        sleepers_.load(std::memory_order_seq_cst) > 0) {
      done_.notify_all();
    }
  }
}

void ThreadTeam::run(const std::function<void(int)>& job) {
  const int parts = size();
  for (std::exception_ptr& e : errors_) e = nullptr;
  job_ = &job;
  done_.store(0, std::memory_order_relaxed);
  // Publishes job_ (a worker reads it after seeing the new generation) and wakes the workers.
  const std::uint64_t generation = generation_.fetch_add(1, std::memory_order_seq_cst) + 1;
  if (sleepers_.load(std::memory_order_seq_cst) > 0) generation_.notify_all();
  run_parts(0, generation);
  // Parts claimed by workers may still be running.
  for (int done = done_.load(std::memory_order_acquire); done != parts;) {
    done = await_change(done_, done, sleepers_, spin_);
  }
  job_ = nullptr;
  for (const std::exception_ptr& e : errors_) {
    if (e) std::rethrow_exception(e);
  }
}

void ThreadTeam::work(int thread) {
  std::uint64_t seen = 0;
  for (;;) {
    seen = await_change(generation_, seen, sleepers_, spin_);
    if (stop_.load(std::memory_order_relaxed)) return;
    // Woken late, this finds the job done and claims nothing; the next wait returns at once
    // if the next job has begun.
    run_parts(thread, seen);
  }
}

}  // namespace csympnet
