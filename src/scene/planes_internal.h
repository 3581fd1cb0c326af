#pragma once
// Internal to src/scene: groupCoplanarTriangles in two steps, so that a
// DynamicScene commit can keep the static triangles' sorted entries and
// merge in only the movable ones (the sort is most of the cost: ~1.2 of
// ~2.1 ms for 24k triangles).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "earshot/scene/planes.h"
#include "earshot/scene/triangle_mesh.h"

namespace earshot {
namespace detail {

/** The plane of one non-degenerate triangle (normal sign canonical). */
struct PlaneEntry {
  Plane plane;
  uint32_t triangle;
};

inline bool byOffset(const PlaneEntry& x, const PlaneEntry& y) { return x.plane.offset < y.plane.offset; }

/** Entries of triangles [firstTriangle, end) of `mesh`, sorted by offset. */
std::vector<PlaneEntry> sortedPlaneEntries(const TriangleMesh& mesh, size_t firstTriangle = 0);

/** Groups entries sorted by offset (byOffset) into planes, for a mesh of
 *  `triangleCount` triangles (triangles without an entry get kNoPlane). */
PlaneSet groupSortedPlaneEntries(const std::vector<PlaneEntry>& entries, size_t triangleCount,
                                 double angleTolerance = 1e-5, double offsetTolerance = 1e-4);

}  // namespace detail
}  // namespace earshot
