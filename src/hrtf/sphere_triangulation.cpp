// Spherical Delaunay triangulation of HRTF measurement directions.
//
// Method: the convex hull of points on the unit sphere is their spherical
// Delaunay triangulation (K. Q. Brown, "Voronoi diagrams from convex hulls",
// Information Processing Letters 9(5), 1979). The hull is Qhull's (Debian's
// libqhull-r, reentrant: C. B. Barber, D. P. Dobkin, H. Huhdanpaa, "The
// Quickhull algorithm for convex hulls", ACM TOMS 22(4), 1996), option Qt
// (triangulated output).
//
// Robustness: measurement grids put many points on common circles (rings of
// equal elevation, Lebedev orbits), so four points are often exactly coplanar
// and Qhull would merge them into one facet, or keep a point as "coplanar"
// rather than as a vertex. Each point's radius is perturbed deterministically
// by up to 1e-6 (a "simulation of simplicity" style tie-break, H. Edelsbrunner
// and E. P. Muecke, ACM TOG 9(1), 1990), far above double rounding (~1e-15)
// and far below the bulge of the sphere between neighbours 0.5 degree apart
// (~1e-5): ties become a consistent arbitrary choice of diagonal and every
// direction is a vertex (checked: otherwise no triangles, as for a flat set).
#include "sphere_triangulation.h"

#include <cmath>
#include <cstdio>
#include <memory>

extern "C" {
#include <libqhull_r/qhull_ra.h>
}

namespace earshot::hrtf::detail {

namespace {

uint64_t splitMix(uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

struct FileCloser {
  void operator()(FILE* f) const {
    if (f) std::fclose(f);
  }
};

}  // namespace

std::vector<std::array<uint32_t, 3>> convexHullTriangles(const std::vector<Vec3d>& points) {
  std::vector<std::array<uint32_t, 3>> out;
  // Unique directions (the first of each), perturbed.
  std::vector<uint32_t> ids;
  std::vector<double> coords;
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
    const double r = 1.0 + 1e-6 * (double(splitMix(i) >> 11) * (1.0 / 9007199254740992.0));
    coords.insert(coords.end(), {points[i].x * r, points[i].y * r, points[i].z * r});
  }
  const size_t n = ids.size();
  if (n < 4) return out;

  // Qhull reports a degenerate set (all on one plane) as an error: into
  // /dev/null, and then no triangles.
  std::unique_ptr<FILE, FileCloser> sink(std::fopen("/dev/null", "w"));
  qhT qhData;
  qhT* qh = &qhData;
  QHULL_LIB_CHECK
  qh_zero(qh, sink.get());
  char options[] = "qhull Qt";
  const int exitCode = qh_new_qhull(qh, 3, int(n), coords.data(), False, options, nullptr, sink.get());
  if (exitCode == 0) {
    std::vector<char> used(n, 0);
    facetT* facet;
    FORALLfacets {
      std::array<uint32_t, 3> tri{};
      int k = 0;
      vertexT *vertex, **vertexp;
      FOREACHvertex_(facet->vertices) {
        if (k < 3) tri[size_t(k)] = uint32_t(qh_pointid(qh, vertex->point));
        ++k;
      }
      if (k != 3) continue;  // Qt triangulates every facet
      // Outward, counter-clockwise seen from outside: the normal points away
      // from the origin, which lies inside the hull of directions.
      const Vec3d a{coords[3 * tri[0]], coords[3 * tri[0] + 1], coords[3 * tri[0] + 2]};
      const Vec3d b{coords[3 * tri[1]], coords[3 * tri[1] + 1], coords[3 * tri[1] + 2]};
      const Vec3d c{coords[3 * tri[2]], coords[3 * tri[2] + 1], coords[3 * tri[2] + 2]};
      if (dot(cross(b - a, c - a), a + b + c) < 0) std::swap(tri[1], tri[2]);
      for (uint32_t v : tri) used[v] = 1;
      out.push_back({ids[tri[0]], ids[tri[1]], ids[tri[2]]});
    }
    // Every direction a vertex, or the set was degenerate after all.
    for (char u : used)
      if (!u) {
        out.clear();
        break;
      }
  }
  qh_freeqhull(qh, !qh_ALL);
  int curlong = 0, totlong = 0;
  qh_memfreeshort(qh, &curlong, &totlong);
  return out;
}

}  // namespace earshot::hrtf::detail
