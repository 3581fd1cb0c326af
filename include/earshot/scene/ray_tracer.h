#pragma once
/** @file Ray queries against scene geometry. Embree 3 is hidden behind this
 *  interface: no Embree type appears in earshot's headers (STYLE.md), and
 *  src/scene is the only module that includes Embree. */
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/core/vec3.h"
#include "earshot/scene/planes.h"
#include "earshot/scene/triangle_mesh.h"

namespace earshot {

struct QueryLog;  // embree_limit.h

/** A ray: points origin + t * direction for t in [tNear, tFar]. direction
 *  need not be unit length, but earshot always passes unit vectors so t is in
 *  metres. The origin is in world coordinates (metres) in double, so that a
 *  caller can carry hit points (origin + t * direction) without the float
 *  rounding of world coordinates far from 0 (see RayTracer's frame). */
struct Ray {
  Vec3d origin;
  float tNear = 0.0f;
  Vec3f direction;
  float tFar = 1e30f;
};

/** The nearest hit along a ray. */
struct Hit {
  float t = -1.0f;           ///< distance along the ray; < 0: no hit
  uint32_t triangle = 0;     ///< index into the mesh's triangles
  Vec3f normal;              ///< unit normal (v1-v0) x (v2-v0), not flipped toward the ray
  /** Barycentric coordinates of the hit: weights of v1 and v2 (v0's is
   *  1 - u - v); near 0 means near an edge. */
  float u = 0.0f, v = 0.0f;
  bool valid() const { return t >= 0.0f; }
};

/** Immutable acceleration structure over one TriangleMesh. All queries are
 *  const and thread-safe: call them from any number of threads at once.
 *
 *  The frame: Embree traces in float coordinates relative to frameOrigin(),
 *  a point at the scene's centre (create(): the centre of the mesh's bounds;
 *  a DynamicScene snapshot: that of its static meshes). A query converts
 *  `ray.origin - frameOrigin()` to float, so float precision scales with the
 *  scene's size, not with its distance from the world's origin (a room at
 *  1e5 m traces as well as one at 0, where world floats are ~8 mm apart).
 *  Everything a caller sees stays in world coordinates: Ray::origin, the
 *  mesh, planes, normals and bounds; Hit::t is a distance and frame-free.
 *
 *  Made either by create() (one BVH over the mesh) or by
 *  DynamicScene::commit() (a snapshot: a top-level BVH over instances of
 *  BVHs shared with other snapshots). Both answer the same way: triangle
 *  indices, materials, planes and normals refer to mesh(), the scene's
 *  world-space triangles. */
class RayTracer {
 public:
  /** Builds the BVH. Degenerate (zero-area) triangles are dropped from the
   *  BVH (they can never be hit). Fails on non-finite vertices or indices out
   *  of range, naming the triangle. */
  static Result<std::unique_ptr<RayTracer>> create(const TriangleMesh& mesh);
  ~RayTracer();
  RayTracer(const RayTracer&) = delete;
  RayTracer& operator=(const RayTracer&) = delete;

  /** Nearest hit in [tNear, tFar]; returns hit.valid(). */
  bool intersect(const Ray& ray, Hit& hit) const;
  /** True when anything lies on the ray within [tNear, tFar]. */
  bool occluded(const Ray& ray) const;
  /** occluded() for each of `count` rays (e.g. the shadow rays from a hit
   *  to many sources), through Embree's ray streams, up to 64 rays a call,
   *  without the coherent flag (ray_tracer.cpp says why):
   *  occludedOut[i] = 1 or 0. Allocates nothing. */
  void occludedMany(const Ray* rays, size_t count, uint8_t* occludedOut) const;

  /** The world-space triangles every hit's index refers to. */
  const TriangleMesh& mesh() const { return mMesh; }
  /** Unique among the tracers (and snapshots) this process made: what
   *  was traced in one is known to be of it (SharedTracePaths). */
  uint64_t id() const { return mId; }
  /** Material id of a triangle. */
  uint32_t materialOf(uint32_t triangle) const { return mMesh.materialIds[triangle]; }
  bool empty() const { return mMesh.triangles.empty(); }
  /** Coplanar groups of the mesh's triangles (for image sources). */
  const PlaneSet& planes() const { return mPlanes; }
  uint32_t planeOf(uint32_t triangle) const { return mPlanes.triangleToPlane[triangle]; }
  /** Axis-aligned bounds of the mesh (empty mesh: both zero). */
  Vec3f boundsMin() const { return mMin; }
  Vec3f boundsMax() const { return mMax; }
  /** Offset (metres) for leaving a surface without hitting it again, from the
   *  scene's extent and float precision in the frame (see the class comment;
   *  the same for a scene far from 0 as for one at 0). */
  float surfaceEpsilon() const { return mEpsilon; }
  /** The world point (metres) that Embree's float coordinates are relative
   *  to; each component is a float value. Callers need not use it: queries
   *  take and give world coordinates. */
  const Vec3d& frameOrigin() const { return mFrameOrigin; }
  /** True when the mesh bounds a convex region (convexSides) and p lies in
   *  it, surfaceEpsilon() from every plane: then nothing blocks the segment
   *  from p to any point on the mesh's surface, and occlusion tests toward p
   *  can be skipped. Cheap: one dot product per plane. */
  bool convexAround(const Vec3d& p) const;
  /** True when provably nothing lies between a and b (no plane of the mesh
   *  separates them or touches the segment); false when it cannot tell
   *  cheaply (then ask occluded()). Tests at most 256 planes. */
  bool nothingBetween(const Vec3d& a, const Vec3d& b) const;

 private:
  friend class DynamicScene;  // builds snapshots over shared BVHs
  RayTracer();

 public:
  struct Impl;  // Embree state; defined in ray_tracer.cpp only

 private:
  std::unique_ptr<Impl> mImpl;
  TriangleMesh mMesh;
  PlaneSet mPlanes;
  Vec3f mMin, mMax;
  Vec3d mFrameOrigin;  // Embree's vertices and ray origins are relative to it
  std::vector<int8_t> mConvexSides;  // convexSides(mMesh, mPlanes, mEpsilon)
  float mEpsilon = 1e-4f;
  uint64_t mId = nextId();
  static uint64_t nextId();
  // Set only while a QueryRecording (embree_limit.h) measures this tracer.
  mutable std::atomic<QueryLog*> mRecorder{nullptr};
  friend class QueryRecording;
  friend class EmbreeReplay;
};

}  // namespace earshot
