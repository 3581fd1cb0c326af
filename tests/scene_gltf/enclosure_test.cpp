// enclosure.h: closed meshes and which side of them a point is on (issue 17:
// a listener outside a closed room is warned about, not silently rendered).
#include <gtest/gtest.h>

#include "earshot/scene/enclosure.h"
#include "earshot/scene/ray_tracer.h"
#include "earshot/scene/triangle_mesh.h"

namespace earshot {
namespace {

TEST(Enclosure, BoxIsClosedAndTellsInsideFromOutside) {
  const TriangleMesh box = makeBox({0, 0, 0}, {10, 7, 3});
  ASSERT_TRUE(isClosedMesh(box));
  auto rt = RayTracer::create(box);
  ASSERT_TRUE(rt.isOk());
  EXPECT_EQ(enclosureOf(**rt, true, {5, 3.5, 1.5}), Enclosure::kInside);
  EXPECT_EQ(enclosureOf(**rt, true, {0.01, 0.01, 0.01}), Enclosure::kInside);  // near a corner
  EXPECT_EQ(enclosureOf(**rt, true, {15, 3.5, 1.5}), Enclosure::kOutside);
  EXPECT_EQ(enclosureOf(**rt, true, {-5, -5, -5}), Enclosure::kOutside);
  // Inside one box of two (a room in a building): still inside; between them: outside.
  TriangleMesh two = box;
  const TriangleMesh inner = makeBox({2, 2, 1}, {4, 4, 2});
  const uint32_t base = uint32_t(two.positions.size());
  two.positions.insert(two.positions.end(), inner.positions.begin(), inner.positions.end());
  for (auto t : inner.triangles) two.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  two.materialIds.insert(two.materialIds.end(), inner.materialIds.begin(), inner.materialIds.end());
  ASSERT_TRUE(isClosedMesh(two));
  auto rt2 = RayTracer::create(two);
  ASSERT_TRUE(rt2.isOk());
  EXPECT_EQ(enclosureOf(**rt2, true, {3, 3, 1.5}), Enclosure::kOutside);  // inside both: even crossings
  EXPECT_EQ(enclosureOf(**rt2, true, {8, 5, 1.5}), Enclosure::kInside);
}

TEST(Enclosure, OpenMeshGivesNoAnswer) {
  TriangleMesh box = makeBox({0, 0, 0}, {10, 7, 3});
  box.triangles.pop_back();  // one face half open
  box.materialIds.pop_back();
  EXPECT_FALSE(isClosedMesh(box));
  auto rt = RayTracer::create(box);
  ASSERT_TRUE(rt.isOk());
  EXPECT_EQ(enclosureOf(**rt, isClosedMesh(box), {15, 3.5, 1.5}), Enclosure::kOpenMesh);
  EXPECT_FALSE(isClosedMesh(TriangleMesh{}));
}

}  // namespace
}  // namespace earshot
