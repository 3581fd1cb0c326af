// The denormal guard flushes subnormal results to zero inside its scope and
// restores the previous mode after it (x86 MXCSR FTZ/DAZ; ARM FPCR/FPSCR FZ).
#include <gtest/gtest.h>

#include <cfloat>

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

}  // namespace earshot
