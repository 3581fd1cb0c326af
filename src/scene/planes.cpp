#include "earshot/scene/planes.h"

#include "planes_internal.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace earshot {

bool pointOnTriangle(const TriangleMesh& mesh, uint32_t t, const Vec3d& p, double tolerance) {
  const auto& tri = mesh.triangles[t];
  const Vec3d a(mesh.positions[tri[0]]), b(mesh.positions[tri[1]]), c(mesh.positions[tri[2]]);
  const Vec3d n = cross(b - a, c - a);
  const double area2 = length(n);
  if (!(area2 > 0)) return false;
  const Vec3d un = n / area2;
  if (std::fabs(dot(p - a, un)) > tolerance) return false;
  // Signed distance of p from each edge, inside positive.
  const Vec3d corners[3] = {a, b, c};
  for (int i = 0; i < 3; ++i) {
    const Vec3d e0 = corners[i], e1 = corners[(i + 1) % 3];
    const Vec3d edge = e1 - e0;
    const double edgeLength = length(edge);
    const double inside = dot(cross(edge, p - e0), un) / edgeLength;
    if (inside < -tolerance) return false;
  }
  return true;
}

namespace detail {

std::vector<PlaneEntry> sortedPlaneEntries(const TriangleMesh& mesh, size_t firstTriangle) {
  std::vector<PlaneEntry> entries;
  entries.reserve(mesh.triangles.size() - std::min(firstTriangle, mesh.triangles.size()));
  for (size_t t = firstTriangle; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    const Vec3d a(mesh.positions[tri[0]]), b(mesh.positions[tri[1]]), c(mesh.positions[tri[2]]);
    Vec3d nrm = cross(b - a, c - a);
    const double len = length(nrm);
    if (!(len > 0)) continue;
    nrm = nrm / len;
    // Canonical sign: the largest component positive (stable under noise).
    const double ax = std::fabs(nrm.x), ay = std::fabs(nrm.y), az = std::fabs(nrm.z);
    const double lead = (ax >= ay && ax >= az) ? nrm.x : (ay >= az ? nrm.y : nrm.z);
    if (lead < 0) nrm = -nrm;
    const Vec3d centroid = (a + b + c) / 3.0;
    entries.push_back({Plane{nrm, dot(nrm, centroid)}, uint32_t(t)});
  }
  std::sort(entries.begin(), entries.end(), byOffset);
  return entries;
}

PlaneSet groupSortedPlaneEntries(const std::vector<PlaneEntry>& entries, size_t triangleCount, double angleTol,
                                 double offsetTol) {
  PlaneSet set;
  set.triangleToPlane.assign(triangleCount, PlaneSet::kNoPlane);
  // Sweep by offset: a triangle joins an existing plane within the offset
  // window whose normal agrees.
  const double cosTol = std::cos(angleTol);
  std::vector<uint32_t> open;  // plane ids whose offset is within the window
  for (const PlaneEntry& e : entries) {
    open.erase(std::remove_if(open.begin(), open.end(),
                              [&](uint32_t id) { return e.plane.offset - set.planes[id].offset > offsetTol; }),
               open.end());
    uint32_t found = PlaneSet::kNoPlane;
    for (uint32_t id : open)
      if (dot(set.planes[id].normal, e.plane.normal) >= cosTol) {
        found = id;
        break;
      }
    if (found == PlaneSet::kNoPlane) {
      found = uint32_t(set.planes.size());
      set.planes.push_back(e.plane);
      open.push_back(found);
    }
    set.triangleToPlane[e.triangle] = found;
  }
  set.trianglesOfPlane.resize(set.planes.size());
  for (size_t t = 0; t < triangleCount; ++t)
    if (set.triangleToPlane[t] != PlaneSet::kNoPlane) set.trianglesOfPlane[set.triangleToPlane[t]].push_back(uint32_t(t));
  return set;
}

}  // namespace detail

PlaneSet groupCoplanarTriangles(const TriangleMesh& mesh, double angleTol, double offsetTol) {
  PlaneSet set =
      detail::groupSortedPlaneEntries(detail::sortedPlaneEntries(mesh), mesh.triangles.size(), angleTol, offsetTol);
  addPlaneBounds(mesh, set);
  return set;
}

void addPlaneBounds(const TriangleMesh& mesh, PlaneSet& set) {
  set.bounds.assign(set.planes.size(), {Vec3f(INFINITY, INFINITY, INFINITY), Vec3f(-INFINITY, -INFINITY, -INFINITY)});
  for (size_t t = 0; t < set.triangleToPlane.size() && t < mesh.triangles.size(); ++t) {
    const uint32_t p = set.triangleToPlane[t];
    if (p == PlaneSet::kNoPlane) continue;
    auto& [lo, hi] = set.bounds[p];
    for (uint32_t v : mesh.triangles[t]) {
      const Vec3f& q = mesh.positions[v];
      lo = {std::min(lo.x, q.x), std::min(lo.y, q.y), std::min(lo.z, q.z)};
      hi = {std::max(hi.x, q.x), std::max(hi.y, q.y), std::max(hi.z, q.z)};
    }
  }
}

std::vector<int8_t> convexSides(const TriangleMesh& mesh, const PlaneSet& planes, double tolerance) {
  std::vector<int8_t> sides(planes.planes.size(), 0);
  for (size_t i = 0; i < planes.planes.size(); ++i) {
    bool above = false, below = false;
    for (const Vec3f& v : mesh.positions) {
      const double d = planes.planes[i].distance(Vec3d(v));
      above |= d > tolerance;
      below |= d < -tolerance;
      if (above && below) return {};
    }
    sides[i] = below ? -1 : 1;
  }
  return sides;
}

bool segmentCrossesNoPlane(const PlaneSet& planes, const Vec3d& a, const Vec3d& b, double tolerance) {
  for (const Plane& p : planes.planes) {
    const double da = p.distance(a), db = p.distance(b);
    if (!((da > tolerance && db > tolerance) || (da < -tolerance && db < -tolerance))) return false;
  }
  return true;
}

}  // namespace earshot
