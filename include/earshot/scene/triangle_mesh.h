#pragma once
/** @file Scene geometry as earshot holds it: world-space triangles, each with
 *  an acoustic material id (an index into a MaterialTable). */
#include <array>
#include <cstdint>
#include <vector>

#include "earshot/core/vec3.h"

namespace earshot {

struct TriangleMesh {
  std::vector<Vec3f> positions;                   ///< metres, world frame
  std::vector<std::array<uint32_t, 3>> triangles;  ///< indices into positions
  std::vector<uint32_t> materialIds;              ///< one per triangle

  size_t triangleCount() const { return triangles.size(); }
  /** Appends another mesh (indices are offset). */
  void append(const TriangleMesh& other);
};

/** An axis-aligned box of 12 triangles, faces in the order west (x=min),
 *  east (x=max), south (y=min), north (y=max), floor (z=min), ceiling
 *  (z=max), each with its own material id. Normals point into the box. */
TriangleMesh makeBox(const Vec3d& minCorner, const Vec3d& maxCorner, const std::array<uint32_t, 6>& faceMaterialIds);
inline TriangleMesh makeBox(const Vec3d& minCorner, const Vec3d& maxCorner, uint32_t materialId = 0) {
  return makeBox(minCorner, maxCorner, {materialId, materialId, materialId, materialId, materialId, materialId});
}

}  // namespace earshot
