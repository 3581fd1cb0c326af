// ThreadScratch (src/ir/spectral_synth.h): an IR's temporaries in buffers of
// the thread, reused by its next IR, distinct between nested scopes and
// threads, released when large.
#include <gtest/gtest.h>

#include <thread>
#include <vector>

#include "spectral_synth.h"

namespace earshot::detail {
namespace {

TEST(ThreadScratch, ReusedByTheNextScopeDistinctWhenNestedReleasedWhenLarge) {
  const float* first = nullptr;
  {
    ThreadScratch s(2);
    s[0].assign(96000, 1.0f);
    s[1].assign(96000, 2.0f);
    first = s[0].data();
    {
      ThreadScratch inner(1);  // the next buffer: not one of the outer two
      inner[0].assign(10, 3.0f);
      EXPECT_NE(inner[0].data(), s[0].data());
      EXPECT_NE(inner[0].data(), s[1].data());
    }
    EXPECT_EQ(s[0][95999], 1.0f);  // the inner scope left them alone
    EXPECT_EQ(s[1][0], 2.0f);
  }
  {
    ThreadScratch again(1);  // the same memory, as the last user left it
    EXPECT_EQ(again[0].data(), first);
    EXPECT_EQ(again[0].size(), 96000u);
    again[0].resize(ThreadScratch::kKeptFloats + 1);
  }
  {
    ThreadScratch after(1);  // a buffer over the limit was released
    EXPECT_EQ(after[0].capacity(), 0u);
  }
  // Another thread has buffers of its own.
  const float* other = nullptr;
  std::thread([&] {
    ThreadScratch s(1);
    s[0].assign(16, 0.0f);
    other = s[0].data();
  }).join();
  ThreadScratch mine(1);
  mine[0].assign(16, 0.0f);
  EXPECT_NE(other, nullptr);
  EXPECT_EQ(mine[0].size(), 16u);
}

}  // namespace
}  // namespace earshot::detail
