#include "csympnet/core/thread_team.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

#include "csympnet/core/error.hpp"

namespace csympnet::testing {
namespace {

TEST(ThreadTeam, RunsEveryPartOncePerJob) {
  for (int size : {1, 2, 3, 8}) {
    ThreadTeam team(size);
    ASSERT_EQ(team.size(), size);
    for (int job = 0; job < 200; ++job) {
      std::vector<std::atomic<int>> runs(static_cast<std::size_t>(size));
      team.run([&](int part) { runs[static_cast<std::size_t>(part)].fetch_add(1); });
      for (int p = 0; p < size; ++p) ASSERT_EQ(runs[static_cast<std::size_t>(p)].load(), 1);
    }
  }
}

// A part that waits for another to finish: it can, because the other part is claimed by
// another thread of the team (or, were the worker late, by the caller once its part is done;
// here the waiting part is the caller's first claim, part 0).
TEST(ThreadTeam, PartsRunConcurrentlyOrAreTakenOver) {
  ThreadTeam team(2);
  for (int job = 0; job < 50; ++job) {
    std::atomic<bool> one_done{false};
    bool saw_one = false;
    team.run([&](int part) {
      if (part == 1) {
        one_done.store(true);
        return;
      }
      const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
      while (!one_done.load() && std::chrono::steady_clock::now() < until) {
        std::this_thread::yield();
      }
      saw_one = one_done.load();
    });
    ASSERT_TRUE(saw_one) << "job " << job;
  }
}

// run() returns only after every part has returned: the parts' writes are all visible.
TEST(ThreadTeam, ReturnsAfterAllJobsAndShowsTheirWrites) {
  ThreadTeam team(4);
  std::vector<long> sums(4, 0);
  for (int job = 1; job <= 2000; ++job) {
    team.run([&](int part) {
      long s = 0;
      for (int i = 0; i < 100 * (part + 1); ++i) s += i % 7;
      sums[static_cast<std::size_t>(part)] += s + job;
    });
  }
  for (int m = 0; m < 4; ++m) {
    long s = 0;
    for (int i = 0; i < 100 * (m + 1); ++i) s += i % 7;
    EXPECT_EQ(sums[static_cast<std::size_t>(m)], 2000 * s + 2000 * 2001 / 2);
  }
}

// Jobs far apart in time: the workers have gone to sleep and must wake for the next one.
TEST(ThreadTeam, WakesSleepingWorkers) {
  ThreadTeam team(2);
  std::atomic<int> count{0};
  for (int job = 0; job < 3; ++job) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    team.run([&](int) { count.fetch_add(1); });
  }
  EXPECT_EQ(count.load(), 6);
}

TEST(ThreadTeam, RethrowsTheLowestPartsExceptionAfterAllReturn) {
  ThreadTeam team(3);
  std::atomic<int> finished{0};
  try {
    team.run([&](int part) {
      if (part >= 1) {
        finished.fetch_add(1);
        throw std::runtime_error("part " + std::to_string(part));
      }
      finished.fetch_add(1);
    });
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "part 1");
  }
  EXPECT_EQ(finished.load(), 3);
  // The team is still usable.
  std::atomic<int> count{0};
  team.run([&](int) { count.fetch_add(1); });
  EXPECT_EQ(count.load(), 3);
}

// More threads than cores: no spinning, and still correct.
TEST(ThreadTeam, WorksWhenItOutnumbersTheCores) {
  const int size = static_cast<int>(std::thread::hardware_concurrency()) + 3;
  ThreadTeam team(size);
  std::atomic<int> count{0};
  for (int job = 0; job < 50; ++job) team.run([&](int) { count.fetch_add(1); });
  EXPECT_EQ(count.load(), 50 * size);
}

TEST(ThreadTeam, RefusesSizesOutsideItsRange) {
  EXPECT_THROW(ThreadTeam(0), Error);
  EXPECT_THROW(ThreadTeam(-2), Error);
  EXPECT_THROW(ThreadTeam(ThreadTeam::kMaxThreads + 1), Error);
}

}  // namespace
}  // namespace csympnet::testing
