// PlaneSet::bounds (earshot/scene/planes.h): per plane, the box of its
// triangles' vertices.
#include <gtest/gtest.h>

#include "earshot/scene/planes.h"
#include "earshot/scene/ray_tracer.h"
#include "earshot/scene/triangle_mesh.h"

namespace earshot {
namespace {

TEST(PlaneBounds, EachWallOfABoxAndTwoPanelsOnOnePlane) {
  TriangleMesh box = makeBox({0, 0, 0}, {10, 7, 3});
  const PlaneSet set = groupCoplanarTriangles(box);
  ASSERT_EQ(set.planes.size(), 6u);
  ASSERT_EQ(set.bounds.size(), 6u);
  const Vec3f size{10, 7, 3};
  for (size_t p = 0; p < 6; ++p) {
    const Vec3d& n = set.planes[p].normal;
    const int axis = std::abs(n.x) > 0.5 ? 0 : std::abs(n.y) > 0.5 ? 1 : 2;
    const float at = float(set.planes[p].offset / (axis == 0 ? n.x : axis == 1 ? n.y : n.z));
    const Vec3f& lo = set.bounds[p][0];
    const Vec3f& hi = set.bounds[p][1];
    for (int a = 0; a < 3; ++a) {
      const float l = a == 0 ? lo.x : a == 1 ? lo.y : lo.z, h = a == 0 ? hi.x : a == 1 ? hi.y : hi.z;
      const float extent = a == 0 ? size.x : a == 1 ? size.y : size.z;
      if (a == axis) {
        EXPECT_FLOAT_EQ(l, at) << "plane " << p;
        EXPECT_FLOAT_EQ(h, at) << "plane " << p;
      } else {
        EXPECT_FLOAT_EQ(l, 0.0f) << "plane " << p << " axis " << a;
        EXPECT_FLOAT_EQ(h, extent) << "plane " << p << " axis " << a;
      }
    }
  }
  // Two boxes side by side on the floor (z = 0) with a gap: one floor
  // plane whose bounds span both.
  TriangleMesh two = makeBox({0, 0, 0}, {1, 1, 1});
  two.append(makeBox({3, 0, 0}, {4, 2, 1}));
  const PlaneSet both = groupCoplanarTriangles(two);
  bool found = false;
  for (size_t p = 0; p < both.planes.size(); ++p) {
    const Vec3d& n = both.planes[p].normal;
    if (std::abs(n.z) > 0.5 && std::abs(both.planes[p].offset) < 1e-9) {
      found = true;
      EXPECT_EQ(both.trianglesOfPlane[p].size(), 4u);
      EXPECT_FLOAT_EQ(both.bounds[p][0].x, 0.0f);
      EXPECT_FLOAT_EQ(both.bounds[p][1].x, 4.0f);
      EXPECT_FLOAT_EQ(both.bounds[p][0].y, 0.0f);
      EXPECT_FLOAT_EQ(both.bounds[p][1].y, 2.0f);
    }
  }
  EXPECT_TRUE(found);
  // The tracer's planes carry them.
  auto tracer = RayTracer::create(box);
  ASSERT_TRUE(tracer.isOk());
  EXPECT_EQ((*tracer)->planes().bounds.size(), (*tracer)->planes().planes.size());
}

}  // namespace
}  // namespace earshot
