#include <gtest/gtest.h>

#include <cmath>

#include "earshot/propagation/direct_path.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot {

TEST(DirectPath, FreeFieldDelayAndSpreading) {
  MaterialTable materials;
  DirectPathSettings s;
  s.air.enabled = false;
  DirectPath d = computeDirectPath(nullptr, materials, {3, 4, 0}, {0, 0, 0}, s);
  EXPECT_DOUBLE_EQ(d.distanceMeters, 5.0);
  EXPECT_DOUBLE_EQ(d.delaySeconds, 5.0 / 343.0);
  EXPECT_DOUBLE_EQ(d.spreadingGain, 0.2);
  for (double g : d.bandGain) EXPECT_DOUBLE_EQ(g, 1.0);
  EXPECT_NEAR(d.directionFromListener.x, 0.6, 1e-12);
  EXPECT_NEAR(d.directionFromListener.y, 0.8, 1e-12);
}

TEST(DirectPath, SpreadingIsClampedAtTheMinimumDistance) {
  MaterialTable materials;
  DirectPathSettings s;
  DirectPath d = computeDirectPath(nullptr, materials, {0, 0, 0}, {0, 0, 0}, s);
  EXPECT_DOUBLE_EQ(d.spreadingGain, 1.0 / s.minDistanceMeters);
  EXPECT_TRUE(std::isfinite(d.directionFromListener.x));
}

namespace {

// Two parallel 10 x 10 m walls at x = 1 and x = 2 (each a box face would be
// two crossings; so quads).
TriangleMesh twoWalls(uint32_t materialId) {
  TriangleMesh mesh;
  for (float x : {1.0f, 2.0f}) {
    const uint32_t base = uint32_t(mesh.positions.size());
    mesh.positions.push_back({x, -5, -5});
    mesh.positions.push_back({x, 5, -5});
    mesh.positions.push_back({x, 5, 5});
    mesh.positions.push_back({x, -5, 5});
    mesh.triangles.push_back({base, base + 1, base + 2});
    mesh.triangles.push_back({base, base + 2, base + 3});
    mesh.materialIds.push_back(materialId);
    mesh.materialIds.push_back(materialId);
  }
  return mesh;
}

}  // namespace

TEST(DirectPath, EachWallCrossedMultipliesEnergyByItsTransmission) {
  MaterialTable materials;
  Material wall;
  wall.name = "thin";
  wall.absorption = filledBands(0.5f);
  wall.transmission = {0.1f, 0.1f, 0.05f, 0.05f, 0.01f, 0.01f, 0.0f};
  TriangleMesh mesh = twoWalls(materials.add(wall));
  auto rt = RayTracer::create(mesh);
  ASSERT_TRUE(rt.isOk()) << rt.status().message();
  DirectPathSettings s;
  s.air.enabled = false;
  DirectPath d = computeDirectPath(rt->get(), materials, {3, 0.3, 0.2}, {0, 0.1, 0}, s);
  EXPECT_EQ(d.surfacesCrossed, 2);
  for (int b = 0; b < kNumBands; ++b)
    EXPECT_NEAR(d.bandGain[b], std::sqrt(double(wall.transmission[b]) * wall.transmission[b]), 1e-6) << b;
  EXPECT_TRUE(d.audible);
  // Opaque wall: inaudible.
  Material opaque = wall;
  opaque.name = "opaque";
  opaque.transmission = filledBands(0.0f);
  for (auto& m : mesh.materialIds) m = materials.add(opaque);
  auto rt2 = RayTracer::create(mesh);
  ASSERT_TRUE(rt2.isOk());
  EXPECT_FALSE(computeDirectPath(rt2->get(), materials, {3, 0.3, 0.2}, {0, 0.1, 0}, s).audible);
}

// The occluders' own factor, without the air: what the runtime filters a
// source's direct sound with and reports (Engine::sourceOcclusion). Two
// walls of transmission t_b: t_b exactly (sqrt(t_b^2)), with the air on
// and off, while bandGain carries the air's loss besides; 1 with nothing
// in the way.
TEST(DirectPath, TransmissionGainIsTheOccludersAlone) {
  MaterialTable materials;
  Material wall;
  wall.name = "thin";
  wall.absorption = filledBands(0.5f);
  wall.transmission = {0.1f, 0.1f, 0.05f, 0.05f, 0.01f, 0.01f, 0.002f};
  auto rt = RayTracer::create(twoWalls(materials.add(wall)));
  ASSERT_TRUE(rt.isOk()) << rt.status().message();
  for (bool air : {false, true}) {
    DirectPathSettings s;
    s.air.enabled = air;
    const DirectPath d = computeDirectPath(rt->get(), materials, {30, 0.3, 0.2}, {0, 0.1, 0}, s);
    ASSERT_EQ(d.surfacesCrossed, 2);
    for (int b = 0; b < kNumBands; ++b) {
      EXPECT_EQ(d.transmissionGain[b], double(wall.transmission[b])) << "band " << b << (air ? ", air on" : "");
      if (air)
        EXPECT_LT(d.bandGain[b], d.transmissionGain[b]) << "band " << b;
      else
        EXPECT_NEAR(d.bandGain[b], d.transmissionGain[b], 1e-15) << "band " << b;
    }
    const DirectPath clear = computeDirectPath(rt->get(), materials, {0.5, 0.3, 0.2}, {0, 0.1, 0}, s);
    EXPECT_EQ(clear.surfacesCrossed, 0);
    for (double g : clear.transmissionGain) EXPECT_EQ(g, 1.0);
  }
}

// The occlusion test is made only where a surface could be in the way: not
// between two points inside a box (no plane separates them), but between
// two points on either side of a wall.
TEST(DirectPath, OcclusionIsTestedOnlyWhereASurfaceCouldBlock) {
  MaterialTable materials;
  auto box = RayTracer::create(makeBox({0, 0, 0}, {10, 7, 3}, 0));
  ASSERT_TRUE(box.isOk());
  DirectPathSettings s;
  DirectPath inside = computeDirectPath(box->get(), materials, {2, 3.5, 1.5}, {7, 3.5, 1.5}, s);
  EXPECT_FALSE(inside.occlusionTested);
  EXPECT_TRUE(inside.audible);
  EXPECT_EQ(inside.surfacesCrossed, 0);
  EXPECT_TRUE((*box)->nothingBetween({2, 3.5, 1.5}, {7, 3.5, 1.5}));
  // One point outside: the wall x = 10 separates them; it is tested and blocks.
  DirectPath through = computeDirectPath(box->get(), materials, {12, 3.5, 1.5}, {7, 3.5, 1.5}, s);
  EXPECT_TRUE(through.occlusionTested);
  EXPECT_EQ(through.surfacesCrossed, 1);
  // A point on a wall is not provably clear.
  EXPECT_FALSE((*box)->nothingBetween({10, 3.5, 1.5}, {7, 3.5, 1.5}));
}

}  // namespace earshot
