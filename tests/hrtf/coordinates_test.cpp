#include "earshot/hrtf/coordinates.h"

#include <gtest/gtest.h>

namespace earshot::hrtf {
namespace {

// Exact mappings of the axes; tolerances are float/double rounding of
// atan2/asin (1e-9 degrees).
TEST(HrtfCoordinates, LeftInHeadFrameIsSofaAzimuth90) {
  SofaAngles a = headDirectionToSofaAngles({-1.0, 0.0, 0.0});
  EXPECT_NEAR(a.azimuthDegrees, 90.0, 1e-9);
  EXPECT_NEAR(a.elevationDegrees, 0.0, 1e-9);
}

TEST(HrtfCoordinates, AxesMapToSofaAngles) {
  SofaAngles fwd = headDirectionToSofaAngles({0.0, 0.0, -1.0});
  EXPECT_NEAR(fwd.azimuthDegrees, 0.0, 1e-9);
  EXPECT_NEAR(fwd.elevationDegrees, 0.0, 1e-9);
  SofaAngles right = headDirectionToSofaAngles({1.0, 0.0, 0.0});
  EXPECT_NEAR(right.azimuthDegrees, -90.0, 1e-9);
  SofaAngles back = headDirectionToSofaAngles({0.0, 0.0, 1.0});
  EXPECT_NEAR(back.azimuthDegrees, 180.0, 1e-9);
  SofaAngles up = headDirectionToSofaAngles({0.0, 1.0, 0.0});
  EXPECT_NEAR(up.elevationDegrees, 90.0, 1e-9);
  SofaAngles down = headDirectionToSofaAngles({0.0, -2.0, 0.0});  // any length
  EXPECT_NEAR(down.elevationDegrees, -90.0, 1e-9);
}

TEST(HrtfCoordinates, CartesianFramesAreConsistent) {
  // SOFA x forward, y left, z up.
  Vec3d left = headToSofa(Vec3d(-1.0, 0.0, 0.0));
  EXPECT_EQ(left, Vec3d(0.0, 1.0, 0.0));
  Vec3d fwd = headToSofa(Vec3d(0.0, 0.0, -1.0));
  EXPECT_EQ(fwd, Vec3d(1.0, 0.0, 0.0));
  Vec3d up = headToSofa(Vec3d(0.0, 1.0, 0.0));
  EXPECT_EQ(up, Vec3d(0.0, 0.0, 1.0));
  Vec3d v(0.3, -0.2, 0.7);
  EXPECT_EQ(sofaToHead(headToSofa(v)), v);
}

TEST(HrtfCoordinates, AnglesRoundTrip) {
  for (double az = -170.0; az <= 180.0; az += 17.0) {
    for (double el = -80.0; el <= 80.0; el += 20.0) {
      Vec3d d = sofaAnglesToHeadDirection(az, el);
      EXPECT_NEAR(length(d), 1.0, 1e-12);
      SofaAngles a = headDirectionToSofaAngles(d);
      EXPECT_NEAR(a.azimuthDegrees, az, 1e-9);
      EXPECT_NEAR(a.elevationDegrees, el, 1e-9);
    }
  }
  // Azimuth 90 (left) in SOFA is -x in the head frame.
  Vec3d left = sofaAnglesToHeadDirection(90.0, 0.0);
  EXPECT_NEAR(left.x, -1.0, 1e-12);
  EXPECT_NEAR(left.z, 0.0, 1e-12);
}

}  // namespace
}  // namespace earshot::hrtf
