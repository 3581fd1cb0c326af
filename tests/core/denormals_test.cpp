// The denormal guard flushes subnormal results to zero inside its scope and
// restores the previous mode after it (x86 MXCSR FTZ/DAZ; ARM FPCR/FPSCR FZ).
#include <gtest/gtest.h>

#include <cfloat>
#include <thread>
#include <utility>

#include "earshot/core/denormals.h"

namespace earshot {

TEST(Denormals, FlushedInsideTheScopeRestoredAfter) {
  volatile float small = FLT_MIN;  // the smallest normal float
  volatile float half = 0.5f;
  const float before = small * half;  // subnormal
  EXPECT_GT(before, 0.0f);
  {
    ScopedFlushDenormals ftz;
    const float inside = small * half;
    EXPECT_EQ(inside, 0.0f);
  }
  const float after = small * half;
  EXPECT_GT(after, 0.0f);
}

// A helper thread takes on the mode it is given (its caller's: a late
// noise's bands made on two threads are then the bands one thread makes),
// whatever it started with, and gets its own back after. (POSIX threads
// start with their creator's mode; other systems need not.)
TEST(Denormals, AThreadTakesOnTheModeItIsGivenAndGetsItsOwnBack) {
  volatile float small = FLT_MIN;
  volatile float half = 0.5f;
  const uint32_t plain = currentDenormalMode();
  uint32_t flushing = 0;
  auto inThread = [&](uint32_t mode) {
    float given = -1.0f, own = -1.0f;
    std::thread([&] {
      {
        ScopedDenormalMode same(mode);
        given = small * half;
      }
      own = small * half;
    }).join();
    return std::make_pair(given, own);
  };
  std::pair<float, float> plainFromFlushing, flushingFromPlain;
  {
    ScopedFlushDenormals ftz;
    flushing = currentDenormalMode();
    plainFromFlushing = inThread(plain);
  }
  flushingFromPlain = inThread(flushing);
  EXPECT_NE(flushing, plain);
  EXPECT_EQ(currentDenormalMode(), plain);
  EXPECT_GT(plainFromFlushing.first, 0.0f);    // given: not flushing
  EXPECT_EQ(flushingFromPlain.first, 0.0f);    // given: flushing
  EXPECT_EQ(flushingFromPlain.second, small * half);  // its own again
}

}  // namespace earshot
