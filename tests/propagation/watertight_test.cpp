// Issue 20, no leaks: rays never leave a closed watertight mesh, however
// many triangles it has and wherever its edges and vertices lie (a ray
// through an edge or a vertex must hit one of the triangles sharing it).
// One ray in 65,536 escaped a closed 508-triangle room before.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <utility>

#include "earshot/core/random.h"
#include "earshot/core/thread_pool.h"
#include "earshot/materials/material.h"
#include "earshot/propagation/reflection_tracer.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot {
namespace {

// A box whose faces are n x n grids of shared vertices (2 n^2 triangles a
// face, normals inward), every vertex then moved by up to `jitter` metres
// along random directions (the surface stays closed: neighbours share the
// moved vertex), and the whole turned about an oblique axis.
TriangleMesh gridBox(const Vec3d& size, int n, double jitter, uint64_t seed) {
  TriangleMesh m;
  std::map<std::array<long, 3>, uint32_t> index;  // lattice point -> vertex
  Pcg32 rng(seed, 3);
  const double c = std::cos(0.61), s = std::sin(0.61);  // about (1, 1, 1) / sqrt 3
  const Vec3d k = normalize(Vec3d(1, 1, 1));
  auto vertex = [&](long i, long j, long l) {
    const std::array<long, 3> key{i, j, l};
    auto it = index.find(key);
    if (it != index.end()) return it->second;
    Vec3d p(size.x * double(i) / n, size.y * double(j) / n, size.z * double(l) / n);
    const bool onEdge = (i == 0 || i == n) + (j == 0 || j == n) + (l == 0 || l == n) >= 2;
    if (!onEdge) {  // keep the box's edges straight; move the rest, inward or out
      const Vec3d d(rng.uniformDouble() - 0.5, rng.uniformDouble() - 0.5, rng.uniformDouble() - 0.5);
      p = p + d * (2.0 * jitter);
    }
    // Rodrigues rotation about k.
    p = p * c + cross(k, p) * s + k * (dot(k, p) * (1.0 - c));
    m.positions.push_back(Vec3f(p));
    index.emplace(key, uint32_t(m.positions.size() - 1));
    return uint32_t(m.positions.size() - 1);
  };
  // Each face: lattice coordinates (a, b) on the face, fixed third one.
  auto face = [&](int axis, long fixed, bool flip) {
    for (long a = 0; a < n; ++a)
      for (long b = 0; b < n; ++b) {
        auto at = [&](long u, long v) {
          std::array<long, 3> q{};
          q[size_t(axis)] = fixed;
          q[size_t((axis + 1) % 3)] = u;
          q[size_t((axis + 2) % 3)] = v;
          return vertex(q[0], q[1], q[2]);
        };
        const uint32_t v00 = at(a, b), v10 = at(a + 1, b), v11 = at(a + 1, b + 1), v01 = at(a, b + 1);
        if (flip) {
          m.triangles.push_back({v00, v11, v10});
          m.triangles.push_back({v00, v01, v11});
        } else {
          m.triangles.push_back({v00, v10, v11});
          m.triangles.push_back({v00, v11, v01});
        }
      }
  };
  for (int axis = 0; axis < 3; ++axis) {
    face(axis, 0, false);
    face(axis, n, true);
  }
  m.materialIds.assign(m.triangles.size(), 0);
  return m;
}

// A closed sphere-like mesh: an octahedron subdivided `levels` times, its
// vertices pushed to radius r (8 * 4^levels triangles, shared vertices).
TriangleMesh sphereMesh(double r, int levels) {
  TriangleMesh m;
  m.positions = {Vec3f(1, 0, 0), Vec3f(-1, 0, 0), Vec3f(0, 1, 0), Vec3f(0, -1, 0), Vec3f(0, 0, 1), Vec3f(0, 0, -1)};
  m.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
    auto middle = [&](uint32_t a, uint32_t b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      const Vec3d p = normalize(Vec3d(m.positions[a]) + Vec3d(m.positions[b]));
      m.positions.push_back(Vec3f(p));
      mid.emplace(key, uint32_t(m.positions.size() - 1));
      return uint32_t(m.positions.size() - 1);
    };
    std::vector<std::array<uint32_t, 3>> next;
    for (const auto& t : m.triangles) {
      const uint32_t ab = middle(t[0], t[1]), bc = middle(t[1], t[2]), ca = middle(t[2], t[0]);
      next.push_back({t[0], ab, ca});
      next.push_back({ab, t[1], bc});
      next.push_back({ca, bc, t[2]});
      next.push_back({ab, bc, ca});
    }
    m.triangles.swap(next);
  }
  for (auto& p : m.positions) p = Vec3f(Vec3d(p) * r);
  // Inward normals: reverse the winding (the octahedron's faces point out).
  for (auto& t : m.triangles) std::swap(t[1], t[2]);
  m.materialIds.assign(m.triangles.size(), 0);
  return m;
}

uint64_t escapes(const TriangleMesh& mesh, const Vec3d& source, const Vec3d& listener, float scattering) {
  MaterialTable materials;
  Material mat;
  mat.name = "wall";
  mat.absorption = filledBands(0.02f);
  mat.scattering = filledBands(scattering);
  mat.transmission = filledBands(0.0f);
  materials.add(mat);
  auto tracer = RayTracer::create(mesh);
  EXPECT_TRUE(tracer.isOk()) << tracer.status().message();
  if (!tracer.isOk()) return ~uint64_t(0);
  ThreadPool pool(2);
  ReflectionSettings s;
  s.rays = 65536;
  s.bounces = 60;
  s.seed = 5;
  s.air.enabled = false;
  s.russianRoulette = false;
  s.tailProbes = 0;
  s.maxTimeSeconds = 0.5;
  auto r = traceReflections(**tracer, materials, source, listener, s, pool);
  EXPECT_TRUE(r.isOk()) << r.status().message();
  if (!r.isOk()) return ~uint64_t(0);
  EXPECT_EQ(r->stats.raysTraced, 65536u);
  return r->stats.raysEscaped;
}

TEST(Watertight, NoRayLeavesClosedRoomsOfManyTriangles) {
  // Flat faces of many triangles (rays meet edges and vertices where four
  // and six triangles meet), turned off the axes.
  const TriangleMesh flat = gridBox({10, 7, 3}, 12, 0.0, 1);
  EXPECT_EQ(flat.triangleCount(), 6u * 2u * 144u);
  for (float scattering : {0.0f, 0.7f})
    EXPECT_EQ(escapes(flat, {2.3, 2.9, 1.4}, {7.1, 4.2, 1.7}, scattering), 0u) << "flat grid, scattering " << scattering;
  // The same with every vertex off its face's plane by up to 3 cm: concave
  // and convex creases everywhere.
  const TriangleMesh rough = gridBox({10, 7, 3}, 12, 0.03, 2);
  for (float scattering : {0.0f, 0.7f})
    EXPECT_EQ(escapes(rough, {2.3, 2.9, 1.4}, {7.1, 4.2, 1.7}, scattering), 0u) << "rough grid, scattering " << scattering;
  // A sphere of 2048 triangles: every ray meets a crease at each bounce.
  const TriangleMesh sphere = sphereMesh(4.0, 4);
  EXPECT_EQ(sphere.triangleCount(), 2048u);
  for (float scattering : {0.0f, 0.7f})
    EXPECT_EQ(escapes(sphere, {1.0, 0.5, -0.3}, {-1.2, 0.4, 0.8}, scattering), 0u) << "sphere, scattering " << scattering;
}

}  // namespace
}  // namespace earshot
