// Spherical Delaunay triangulation of HRTF measurement directions.
//
// Method: the convex hull of points on the unit sphere is their spherical
// Delaunay triangulation (K. Q. Brown, "Voronoi diagrams from convex hulls",
// Information Processing Letters 9(5), 1979). The hull is built with the
// incremental algorithm (M. de Berg et al., Computational Geometry, ch. 11):
// each new point removes the faces it sees and is joined to the horizon.
//
// Robustness: measurement grids put many points on common circles (rings of
// equal elevation, Lebedev orbits), so four points are often exactly coplanar
// and the visibility test would be decided by rounding. Each point's radius is
// perturbed deterministically by up to 1e-6 (a "simulation of simplicity"
// style tie-break, H. Edelsbrunner and E. P. Muecke, ACM TOG 9(1), 1990), which
// is far above double rounding (~1e-15) and far below the bulge of the sphere
// between neighbours 0.5 degree apart (~1e-5): ties become a consistent
// arbitrary choice of diagonal and no point is lost.
#include "sphere_triangulation.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace earshot::hrtf::detail {

namespace {

uint64_t splitMix(uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

struct Face {
  std::array<uint32_t, 3> v;
  Vec3d n;  // outward normal (unnormalised)
  double d;  // plane offset: dot(n, p) - d > 0 means p is outside
  double tolerance;  // scale-aware: |n| ~ twice the face area
  bool alive;
};

uint64_t edgeKey(uint32_t a, uint32_t b) { return (uint64_t(a) << 32) | b; }

}  // namespace

std::vector<std::array<uint32_t, 3>> convexHullTriangles(const std::vector<Vec3d>& points) {
  std::vector<std::array<uint32_t, 3>> out;
  // Unique directions, perturbed.
  std::vector<uint32_t> ids;
  std::vector<Vec3d> p;
  for (uint32_t i = 0; i < points.size(); ++i) {
    bool dup = false;
    for (uint32_t j : ids) {
      const Vec3d d = points[i] - points[j];
      // Points 2e-6 apart on an axis are not duplicates: skip the square root.
      if (std::fabs(d.x) >= 2e-6 || std::fabs(d.y) >= 2e-6 || std::fabs(d.z) >= 2e-6) continue;
      if (length(d) < 1e-6) { dup = true; break; }
    }
    if (dup) continue;
    ids.push_back(i);
    double r = 1.0 + 1e-6 * (double(splitMix(i) >> 11) * (1.0 / 9007199254740992.0));
    p.push_back(points[i] * r);
  }
  const std::size_t n = p.size();
  if (n < 4) return out;

  // Initial tetrahedron from well-spread points.
  std::size_t i0 = 0, i1 = 0, i2 = 0, i3 = 0;
  double best = -1.0;
  for (std::size_t i = 1; i < n; ++i) {
    double d = length(p[i] - p[i0]);
    if (d > best) { best = d; i1 = i; }
  }
  best = -1.0;
  for (std::size_t i = 0; i < n; ++i) {
    double d = length(cross(p[i1] - p[i0], p[i] - p[i0]));
    if (d > best) { best = d; i2 = i; }
  }
  Vec3d n012 = cross(p[i1] - p[i0], p[i2] - p[i0]);
  best = -1.0;
  for (std::size_t i = 0; i < n; ++i) {
    double d = std::fabs(dot(n012, p[i] - p[i0]));
    if (d > best) { best = d; i3 = i; }
  }
  if (best < 1e-9) return out;  // coplanar set: no volume

  std::vector<Face> faces;
  struct LivePlane {  // a live face's plane, copied so the visibility scan reads memory in order
    Vec3d n;
    double d, tolerance;
    uint32_t face;
  };
  std::vector<LivePlane> alive;  // ascending face index
  std::unordered_map<uint64_t, uint32_t> edgeOwner;  // directed edge -> face
  const Vec3d centre = (p[i0] + p[i1] + p[i2] + p[i3]) * 0.25;
  auto addFace = [&](uint32_t a, uint32_t b, uint32_t c) {
    Face f{{a, b, c}, cross(p[b] - p[a], p[c] - p[a]), 0.0, 0.0, true};
    f.d = dot(f.n, p[a]);
    f.tolerance = 1e-14 * length(f.n);
    faces.push_back(f);
    auto id = uint32_t(faces.size() - 1);
    alive.push_back({f.n, f.d, f.tolerance, id});
    edgeOwner[edgeKey(a, b)] = id;
    edgeOwner[edgeKey(b, c)] = id;
    edgeOwner[edgeKey(c, a)] = id;
  };
  auto addOriented = [&](uint32_t a, uint32_t b, uint32_t c) {
    Vec3d nn = cross(p[b] - p[a], p[c] - p[a]);
    if (dot(nn, centre - p[a]) > 0) std::swap(b, c);
    addFace(a, b, c);
  };
  auto u = [](std::size_t i) { return uint32_t(i); };
  addOriented(u(i0), u(i1), u(i2));
  addOriented(u(i0), u(i1), u(i3));
  addOriented(u(i0), u(i2), u(i3));
  addOriented(u(i1), u(i2), u(i3));

  std::vector<uint32_t> visible;
  std::vector<std::pair<uint32_t, uint32_t>> horizon;
  for (std::size_t ip = 0; ip < n; ++ip) {
    if (ip == i0 || ip == i1 || ip == i2 || ip == i3) continue;
    const Vec3d& q = p[ip];
    visible.clear();
    for (const LivePlane& l : alive)
      if (dot(l.n, q) - l.d > l.tolerance) visible.push_back(l.face);
    if (visible.empty()) continue;  // inside the hull (not expected on a sphere)
    for (uint32_t f : visible) faces[f].alive = false;
    alive.erase(std::remove_if(alive.begin(), alive.end(), [&](const LivePlane& l) { return !faces[l.face].alive; }),
                alive.end());
    horizon.clear();
    for (uint32_t f : visible) {
      const auto& v = faces[f].v;
      for (int e = 0; e < 3; ++e) {
        uint32_t a = v[e], b = v[(e + 1) % 3];
        auto it = edgeOwner.find(edgeKey(b, a));
        if (it != edgeOwner.end() && faces[it->second].alive) horizon.emplace_back(a, b);
      }
    }
    for (uint32_t f : visible) {
      const auto& v = faces[f].v;
      for (int e = 0; e < 3; ++e) {
        auto it = edgeOwner.find(edgeKey(v[e], v[(e + 1) % 3]));
        if (it != edgeOwner.end() && it->second == f) edgeOwner.erase(it);
      }
    }
    for (const auto& [a, b] : horizon) addFace(a, b, u(ip));
  }
  for (const Face& f : faces)
    if (f.alive) out.push_back({ids[f.v[0]], ids[f.v[1]], ids[f.v[2]]});
  return out;
}

}  // namespace earshot::hrtf::detail
