#include <gtest/gtest.h>

#include <atomic>
#include <new>
#include <stdexcept>
#include <vector>

#include "earshot/core/thread_pool.h"

namespace earshot {

TEST(ThreadPool, RunsEveryTaskExactlyOnce) {
  for (unsigned threads : {1u, 2u, 4u}) {
    ThreadPool pool(threads);
    EXPECT_EQ(pool.threadCount(), threads);
    for (int rep = 0; rep < 20; ++rep) {
      std::vector<std::atomic<int>> hits(1000);
      pool.parallelFor(hits.size(), [&](size_t i, unsigned w) {
        ASSERT_LT(w, threads);
        hits[i]++;
      });
      for (auto& h : hits) ASSERT_EQ(h.load(), 1);
    }
  }
}

TEST(ThreadPool, ZeroTasksReturnsAtOnce) {
  ThreadPool pool(2);
  bool called = false;
  pool.parallelFor(0, [&](size_t, unsigned) { called = true; });
  EXPECT_FALSE(called);
}

// A task that throws (an allocation that failed, on any thread) stops the
// hand-out and reaches parallelFor's caller, once the running tasks are
// done, instead of terminating the process; the pool works on afterwards.
TEST(ThreadPool, ATasksExceptionReachesTheCaller) {
  for (unsigned threads : {1u, 2u, 4u}) {
    ThreadPool pool(threads);
    std::atomic<int> ran{0};
    EXPECT_THROW(pool.parallelFor(10000,
                                  [&](size_t i, unsigned) {
                                    ++ran;
                                    if (i == 3) throw std::bad_alloc();
                                  }),
                 std::bad_alloc);
    if (threads == 1) {
      EXPECT_EQ(ran.load(), 4) << "no task starts after the exception";
    }
    // Every thread throws: the first exception, one only.
    EXPECT_THROW(pool.parallelFor(100, [&](size_t, unsigned) { throw std::runtime_error("task"); }),
                 std::runtime_error);
    std::vector<std::atomic<int>> hits(1000);
    pool.parallelFor(hits.size(), [&](size_t i, unsigned) { hits[i]++; });
    for (auto& h : hits) ASSERT_EQ(h.load(), 1);
  }
}

}  // namespace earshot
