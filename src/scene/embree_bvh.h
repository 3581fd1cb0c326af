#pragma once
// Internal to src/scene (never installed, never included elsewhere): the
// Embree state behind RayTracer, shared by RayTracer::create and
// DynamicScene. A TriangleBvh is a committed Embree scene over one triangle
// geometry; once built it is never modified again, so any number of
// snapshots may instance it and query it from any thread at once.
#include <embree3/rtcore.h>

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/core/vec3.h"
#include "earshot/scene/ray_tracer.h"
#include "earshot/scene/triangle_mesh.h"

namespace earshot {
namespace detail {

/** An Embree device and the error messages it reported. Shared (shared_ptr)
 *  by every scene built on it, so the device outlives them. */
class EmbreeDevice {
 public:
  static Result<std::shared_ptr<EmbreeDevice>> create();
  ~EmbreeDevice();
  EmbreeDevice(const EmbreeDevice&) = delete;
  EmbreeDevice& operator=(const EmbreeDevice&) = delete;

  RTCDevice get() const { return mDevice; }
  /** The error reported since the last call, or "" (and clears it). */
  std::string takeError();

 private:
  EmbreeDevice() = default;
  static void onError(void* user, RTCError code, const char* message);

  RTCDevice mDevice = nullptr;
  std::mutex mMutex;  // Embree may report from its build threads
  std::string mError;
};

/** A committed, immutable Embree scene over the non-degenerate triangles of
 *  one mesh, in the mesh's own frame moved by -offset (buildTriangleBvh). */
struct TriangleBvh {
  std::shared_ptr<EmbreeDevice> device;  // declared first: released last
  RTCScene scene = nullptr;
  std::vector<uint32_t> primToTriangle;  // Embree primID -> triangle of the mesh (degenerates dropped)
  std::vector<Vec3f> normals;            // per primID: unit (v1-v0) x (v2-v0) (a translation leaves it)
  ~TriangleBvh();
};

/** Checks material-id count, finite vertices and index ranges; messages as
 *  RayTracer::create has always given them ("vertex 3 is not finite"). */
Status validateMesh(const TriangleMesh& mesh);

/** Bounds of the vertices (empty mesh: both zero). */
void meshBounds(const TriangleMesh& mesh, Vec3f* lo, Vec3f* hi);

/** The origin of the frame a scene with world bounds lo..hi is traced in
 *  (RayTracer::frameOrigin): the centre of the bounds, rounded to float. For a
 *  scene far from 0 a vertex minus it is then exact in float. */
Vec3d frameOriginOf(const Vec3f& lo, const Vec3f& hi);

/** RayTracer::surfaceEpsilon of a scene with world bounds lo..hi traced in
 *  the frame at `origin`: from the scene's extent and the magnitude of its
 *  frame coordinates (not of its world coordinates). */
float surfaceEpsilonOf(const Vec3f& lo, const Vec3f& hi, const Vec3d& origin);

/** Builds the BVH of a mesh that passed validateMesh (MEDIUM quality,
 *  robust traversal), its vertex buffer holding each position minus `offset`
 *  (metres; computed in double, rounded to float). */
Result<std::shared_ptr<const TriangleBvh>> buildTriangleBvh(const std::shared_ptr<EmbreeDevice>& device,
                                                            const TriangleMesh& mesh, const Vec3d& offset);

}  // namespace detail

/** What a RayTracer queries. Either the root scene holds one triangle
 *  geometry itself (`flat`: RayTracer::create, or a DynamicScene snapshot
 *  without movable meshes), or the root holds instances and a hit's instance
 *  ID picks the BVH and the first triangle of its block in the flattened
 *  mesh. */
struct RayTracer::Impl {
  struct Instance {
    uint32_t firstTriangle = 0;               // of the instanced mesh's block in RayTracer::mesh()
    const detail::TriangleBvh* bvh = nullptr;  // kept alive by `instanced`
  };
  std::shared_ptr<detail::EmbreeDevice> device;  // declared first: released last
  RTCScene root = nullptr;                       // owned reference; released in ~Impl
  std::shared_ptr<const detail::TriangleBvh> flat;
  std::vector<Instance> instances;               // by instance geomID in `root`
  std::vector<std::shared_ptr<const detail::TriangleBvh>> instanced;
  std::vector<Vec3f> worldNormals;               // per triangle of mesh(), for instance hits
  Impl() = default;
  /** Another handle on the same immutable state (the root is retained). */
  Impl(const Impl& o)
      : device(o.device), root(o.root), flat(o.flat), instances(o.instances), instanced(o.instanced),
        worldNormals(o.worldNormals) {
    if (root) rtcRetainScene(root);
  }
  Impl& operator=(const Impl&) = delete;
  ~Impl() {
    if (root) rtcReleaseScene(root);
  }
};

}  // namespace earshot
