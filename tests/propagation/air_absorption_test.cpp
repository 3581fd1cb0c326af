#include <gtest/gtest.h>

#include "earshot/propagation/air_absorption.h"

namespace earshot {

// Independent values: ../shared/reference/shoebox_multiband/meta.json
// ("air_db_per_m", ISO 9613-1 at 20 C, 50 % RH, 101.325 kPa, computed by the
// reference's own generator, not by earshot), and the ISO 9613-1 table
// values quoted in the reference README (4.66 dB/km at 1 kHz, 105 dB/km at 8 kHz).
TEST(AirAbsorption, MatchesIso9613AtTwentyDegreesFiftyPercent) {
  const double reference[kNumBands] = {0.00043978997709849435, 0.0013097497659238589, 0.002728134134938444,
                                       0.004664731873821475,   0.009887015588697921,  0.029665528426392616,
                                       0.10529092572360696};
  BandArrayD a = airAttenuationDbPerMeter(AirConditions{});
  for (int b = 0; b < kNumBands; ++b) EXPECT_NEAR(a[b], reference[b], 0.005 * reference[b]) << kBandCentersHz[b];
  EXPECT_NEAR(a[3] * 1000.0, 4.66, 0.01);
  EXPECT_NEAR(a[6] * 1000.0, 105.0, 0.5);
}

TEST(AirAbsorption, DryAirAbsorbsHighFrequenciesMoreThanHumidAirAtTwentyDegrees) {
  // Drier air moves the oxygen relaxation frequency down toward 8 kHz, so at
  // 20 C, 10 % RH absorbs more at 8 kHz than 50 % RH does (ISO 9613-1 Table 1).
  AirConditions dry;
  dry.humidityPercent = 10;
  EXPECT_GT(airAttenuationDbPerMeter(8000.0, dry), 1.2 * airAttenuationDbPerMeter(8000.0, AirConditions{}));
}

TEST(AirAbsorption, DisabledIsZeroAndOutOfRangeIsAnError) {
  AirConditions off;
  off.enabled = false;
  for (double v : airAttenuationDbPerMeter(off)) EXPECT_EQ(v, 0.0);
  AirConditions bad;
  bad.humidityPercent = 120;
  Status s = validate(bad);
  EXPECT_FALSE(s.isOk());
  EXPECT_NE(s.message().find("humidity"), std::string::npos);
}

}  // namespace earshot
