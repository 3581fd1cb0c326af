#include <gtest/gtest.h>

#include <atomic>
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

}  // namespace earshot
