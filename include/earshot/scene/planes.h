#pragma once
/** @file Coplanar triangles grouped into planes: image sources mirror in
 *  planes, and a wall of many triangles is one mirror. */
#include <cstdint>
#include <vector>

#include "earshot/core/vec3.h"
#include "earshot/scene/triangle_mesh.h"

namespace earshot {

struct Plane {
  Vec3d normal;        ///< unit; sign canonical (first non-zero component positive)
  double offset = 0;   ///< dot(normal, x) = offset on the plane, metres
  double distance(const Vec3d& p) const { return dot(normal, p) - offset; }
  /** Mirror image of p in the plane. */
  Vec3d mirror(const Vec3d& p) const { return p - normal * (2.0 * distance(p)); }
};

struct PlaneSet {
  std::vector<Plane> planes;
  std::vector<uint32_t> triangleToPlane;  ///< per triangle; degenerate triangles get kNoPlane
  std::vector<std::vector<uint32_t>> trianglesOfPlane;  ///< per plane, its triangles
  static constexpr uint32_t kNoPlane = 0xFFFFFFFFu;
};

/** Groups triangles whose planes agree within `angleTolerance` (radians) and
 *  `offsetTolerance` (metres). */
/** True when p (on or near the triangle's plane) lies inside triangle t of
 *  `mesh` or within `tolerance` metres of its edges. */
bool pointOnTriangle(const TriangleMesh& mesh, uint32_t t, const Vec3d& p, double tolerance);

PlaneSet groupCoplanarTriangles(const TriangleMesh& mesh, double angleTolerance = 1e-5,
                                double offsetTolerance = 1e-4);

}  // namespace earshot
