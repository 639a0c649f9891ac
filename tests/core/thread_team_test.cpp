#include "csympnet/core/thread_team.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

#include "csympnet/core/error.hpp"

namespace csympnet::testing {
namespace {

TEST(ThreadTeam, RunsEveryMemberOnceOnItsOwnThreadPerJob) {
  for (int size : {1, 2, 3, 8}) {
    ThreadTeam team(size);
    ASSERT_EQ(team.size(), size);
    for (int job = 0; job < 200; ++job) {
      std::vector<int> runs(static_cast<std::size_t>(size), 0);
      std::vector<std::thread::id> ids(static_cast<std::size_t>(size));
      team.run([&](int member) {
        ++runs[static_cast<std::size_t>(member)];
        ids[static_cast<std::size_t>(member)] = std::this_thread::get_id();
      });
      for (int m = 0; m < size; ++m) ASSERT_EQ(runs[static_cast<std::size_t>(m)], 1);
      EXPECT_EQ(ids[0], std::this_thread::get_id());  // member 0 is the caller
      for (int m = 1; m < size; ++m) EXPECT_NE(ids[static_cast<std::size_t>(m)], ids[0]);
    }
  }
}

// run() returns only after every member's job has returned: a job's writes are all visible.
TEST(ThreadTeam, ReturnsAfterAllJobsAndShowsTheirWrites) {
  ThreadTeam team(4);
  std::vector<long> sums(4, 0);
  for (int job = 1; job <= 2000; ++job) {
    team.run([&](int member) {
      long s = 0;
      for (int i = 0; i < 100 * (member + 1); ++i) s += i % 7;
      sums[static_cast<std::size_t>(member)] += s + job;
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

TEST(ThreadTeam, RethrowsTheFirstMembersExceptionAfterAllReturn) {
  ThreadTeam team(3);
  std::atomic<int> finished{0};
  try {
    team.run([&](int member) {
      if (member >= 1) {
        finished.fetch_add(1);
        throw std::runtime_error("member " + std::to_string(member));
      }
      finished.fetch_add(1);
    });
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "member 1");
  }
  EXPECT_EQ(finished.load(), 3);
  // The team is still usable.
  std::atomic<int> count{0};
  team.run([&](int) { count.fetch_add(1); });
  EXPECT_EQ(count.load(), 3);
}

// More members than cores: no spinning, and still correct.
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
