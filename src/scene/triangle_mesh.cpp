#include "earshot/scene/triangle_mesh.h"

namespace earshot {

void TriangleMesh::append(const TriangleMesh& other) {
  const auto offset = static_cast<uint32_t>(positions.size());
  positions.insert(positions.end(), other.positions.begin(), other.positions.end());
  for (const auto& t : other.triangles) triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  materialIds.insert(materialIds.end(), other.materialIds.begin(), other.materialIds.end());
}

TriangleMesh makeBox(const Vec3d& lo, const Vec3d& hi, const std::array<uint32_t, 6>& faceMaterialIds) {
  TriangleMesh m;
  // Corner i has x from bit 0, y from bit 1, z from bit 2.
  for (int i = 0; i < 8; ++i)
    m.positions.push_back(Vec3f(Vec3d{(i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z}));
  // Faces wound so that normals (counter-clockwise) point into the box.
  const uint32_t quads[6][4] = {
      {0, 2, 6, 4},  // west  x = lo: normal +x
      {1, 5, 7, 3},  // east  x = hi: normal -x
      {0, 4, 5, 1},  // south y = lo: normal +y
      {2, 3, 7, 6},  // north y = hi: normal -y
      {0, 1, 3, 2},  // floor z = lo: normal +z
      {4, 6, 7, 5},  // ceiling z = hi: normal -z
  };
  for (int f = 0; f < 6; ++f) {
    const auto* q = quads[f];
    m.triangles.push_back({q[0], q[1], q[2]});
    m.triangles.push_back({q[0], q[2], q[3]});
    m.materialIds.push_back(faceMaterialIds[f]);
    m.materialIds.push_back(faceMaterialIds[f]);
  }
  return m;
}

}  // namespace earshot
