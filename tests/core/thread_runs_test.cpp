// forRuns (earshot/core/thread_runs.h): every element once, runs starting at
// multiples of the alignment, false when a body fails or throws. (Its
// threads' denormal mode is ScopedDenormalMode's, tested in
// denormals_test.cpp: POSIX threads start in their creator's mode anyway.)
#include <gtest/gtest.h>

#include <mutex>
#include <new>
#include <utility>
#include <vector>

#include "earshot/core/thread_runs.h"

namespace earshot {
namespace {

TEST(ForRuns, EveryElementOnceInRunsStartingAtTheAlignment) {
  for (size_t parts : {1, 2, 3, 7}) {
    std::vector<int> seen(100, 0);
    std::vector<std::pair<size_t, size_t>> runs;
    std::mutex m;
    const bool ok = forRuns(seen.size(), 8, parts, [&](size_t b, size_t e) {
      std::lock_guard<std::mutex> lock(m);
      runs.push_back({b, e});
      for (size_t i = b; i < e; ++i) ++seen[i];
      return true;
    });
    EXPECT_TRUE(ok);
    for (int v : seen) EXPECT_EQ(v, 1) << parts << " parts";
    EXPECT_LE(runs.size(), parts);
    for (const auto& r : runs) EXPECT_EQ(r.first % 8, 0u);
  }
}

TEST(ForRuns, FalseWhenARunFailsOrThrowsAfterEveryRunEnded) {
  std::vector<int> done(4, 0);
  EXPECT_FALSE(forRuns(4, 1, 4, [&](size_t b, size_t) {
    done[b] = 1;
    if (b == 2) throw std::bad_alloc();
    return true;
  }));
  for (int v : done) EXPECT_EQ(v, 1);
  EXPECT_FALSE(forRuns(4, 1, 2, [&](size_t b, size_t) { return b != 0; }));
}

}  // namespace
}  // namespace earshot
