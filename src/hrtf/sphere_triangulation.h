#pragma once
// Internal: spherical Delaunay triangulation of measured directions as the
// convex hull of the unit vectors. See sphere_triangulation.cpp.
#include <array>
#include <cstdint>
#include <vector>

#include "earshot/core/vec3.h"

namespace earshot::hrtf::detail {

/** Convex hull of unit vectors, outward-oriented (counter-clockwise seen from
 *  outside) triangles over indices into `points`. Duplicate directions (within
 *  1e-6) use the first occurrence. Returns an empty list when the points span
 *  no volume (e.g. all on one great circle). */
std::vector<std::array<uint32_t, 3>> convexHullTriangles(const std::vector<Vec3d>& points);

}  // namespace earshot::hrtf::detail
