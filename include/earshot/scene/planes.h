#pragma once
/** @file Coplanar triangles grouped into planes: image sources mirror in
 *  planes, and a wall of many triangles is one mirror. */
#include <array>
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
  /** Per plane, the bounding box of its triangles' vertices (min, max):
   *  a point beyond it is on none of them. Filled by groupCoplanarTriangles
   *  and addPlaneBounds; empty in a PlaneSet made otherwise. */
  std::vector<std::array<Vec3f, 2>> bounds;
  static constexpr uint32_t kNoPlane = 0xFFFFFFFFu;
};

/** Fills set.bounds from the mesh whose triangles set groups. */
void addPlaneBounds(const TriangleMesh& mesh, PlaneSet& set);

/** Groups triangles whose planes agree within `angleTolerance` (radians) and
 *  `offsetTolerance` (metres). */
/** True when p (on or near the triangle's plane) lies inside triangle t of
 *  `mesh` or within `tolerance` metres of its edges. */
bool pointOnTriangle(const TriangleMesh& mesh, uint32_t t, const Vec3d& p, double tolerance);

PlaneSet groupCoplanarTriangles(const TriangleMesh& mesh, double angleTolerance = 1e-5,
                                double offsetTolerance = 1e-4);

/** Per plane, the side (+1 or -1) on which every vertex of `mesh` lies
 *  (vertices within `tolerance` metres of a plane count as on both sides);
 *  empty when some plane has vertices beyond `tolerance` on both sides, or
 *  there are no planes. Non-empty means the mesh lies in the intersection of
 *  those half-spaces: a convex region whose boundary holds every triangle. */
std::vector<int8_t> convexSides(const TriangleMesh& mesh, const PlaneSet& planes, double tolerance);

/** True when no plane has a and b on opposite sides or within `tolerance`
 *  of it: then the segment a-b crosses no triangle of the planes' mesh. */
bool segmentCrossesNoPlane(const PlaneSet& planes, const Vec3d& a, const Vec3d& b, double tolerance);

}  // namespace earshot
