// Point-in-closed-mesh by ray parity: see enclosure.h.
#include "earshot/scene/enclosure.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <map>
#include <utility>
#include <vector>

#include "earshot/core/math.h"

namespace earshot {

bool isClosedMesh(const TriangleMesh& mesh) {
  if (mesh.triangles.empty()) return false;
  // Merge vertices by exact position (glTF meshes repeat corners per face).
  std::map<std::array<uint32_t, 3>, uint32_t> ids;
  std::vector<uint32_t> merged(mesh.positions.size());
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    std::array<uint32_t, 3> key;
    const Vec3f p = mesh.positions[i];
    const float c[3] = {p.x == 0.0f ? 0.0f : p.x, p.y == 0.0f ? 0.0f : p.y, p.z == 0.0f ? 0.0f : p.z};  // -0 == +0
    std::memcpy(key.data(), c, sizeof c);
    merged[i] = ids.emplace(key, uint32_t(ids.size())).first->second;
  }
  std::vector<std::pair<uint32_t, uint32_t>> edges;
  edges.reserve(mesh.triangles.size() * 3);
  for (const auto& t : mesh.triangles) {
    const uint32_t a = merged[t[0]], b = merged[t[1]], c = merged[t[2]];
    if (a == b || b == c || a == c) continue;
    for (auto [u, v] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}}) edges.emplace_back(std::min(u, v), std::max(u, v));
  }
  if (edges.empty()) return false;
  std::sort(edges.begin(), edges.end());
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i != 2) return false;
    i = j;
  }
  return true;
}

Enclosure enclosureOf(const RayTracer& tracer, bool closed, const Vec3d& p) {
  if (!closed || tracer.empty() || !withinCoordinateRange(p)) return Enclosure::kOpenMesh;
  // Directions no axis-aligned room has an edge along.
  const Vec3f dirs[3] = {normalize(Vec3f{0.5773f, 0.6112f, 0.5413f}), normalize(Vec3f{-0.7071f, 0.3162f, -0.6325f}),
                         normalize(Vec3f{0.1104f, -0.8944f, 0.4336f})};
  const float eps = tracer.surfaceEpsilon();
  int insideVotes = 0;
  for (const Vec3f& d : dirs) {
    Ray ray;
    ray.origin = p;
    ray.direction = d;
    int crossings = 0;
    Hit hit;
    while (crossings < 10000 && tracer.intersect(ray, hit)) {
      ++crossings;
      ray.origin = ray.origin + Vec3d(d) * double(hit.t);
      ray.tNear = eps;
    }
    insideVotes += crossings % 2;
  }
  return insideVotes >= 2 ? Enclosure::kInside : Enclosure::kOutside;
}

}  // namespace earshot
