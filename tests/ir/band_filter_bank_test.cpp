#include <gtest/gtest.h>

#include <cmath>

#include "earshot/ir/band_filter_bank.h"

namespace earshot {

TEST(BandFilterBank, WeightsSumToOneEverywhereAndStayInUnitRange) {
  for (double hz = 0.0; hz < 30000.0; hz += 3.7) {
    BandArrayD w = bandWeights(hz);
    double sum = 0;
    for (double x : w) {
      EXPECT_GE(x, 0.0);
      EXPECT_LE(x, 1.0);
      sum += x;
    }
    ASSERT_NEAR(sum, 1.0, 1e-12) << hz;
  }
}

TEST(BandFilterBank, EachBandIsWholeAtItsCentreAndAbsentTwoOctavesAway) {
  for (int b = 0; b < kNumBands; ++b) {
    EXPECT_NEAR(bandWeight(b, kBandCentersHz[b]), 1.0, 1e-12);
    if (b >= 2) {
      EXPECT_EQ(bandWeight(b, kBandCentersHz[b] / 4), 0.0);
    }
    if (b + 2 < kNumBands) {
      EXPECT_EQ(bandWeight(b, kBandCentersHz[b] * 4), 0.0);
    }
  }
  // The edge bands extend to DC and to Nyquist.
  EXPECT_EQ(bandWeight(0, 10.0), 1.0);
  EXPECT_EQ(bandWeight(kNumBands - 1, 20000.0), 1.0);
}

}  // namespace earshot
