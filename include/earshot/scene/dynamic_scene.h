#pragma once
/** @file An editable scene (the game thread's side) that commits immutable
 *  RayTracer snapshots (the simulation's side).
 *
 *  Meshes are added in their own frame with a transform. Static meshes are
 *  baked into one BVH in world space, built once and shared by every later
 *  snapshot until a static mesh is added, removed or moved. Each movable
 *  mesh has a BVH of its own in its own frame, built once, and enters each
 *  snapshot as an Embree instance with its current transform; moving it
 *  rebuilds only the snapshot's small top-level BVH over the instances (a
 *  door that swings does not rebuild the room). stats() counts the builds.
 *
 *  A snapshot is an ordinary `const RayTracer`: triangle indices, materials,
 *  planes (image sources) and normals refer to its mesh(), the world-space
 *  triangles of all meshes at commit time (static meshes first, then the
 *  movable ones, each block in mesh-id order). */
#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/io/input_file.h"
#include "earshot/core/vec3.h"
#include "earshot/materials/material.h"
#include "earshot/scene/ray_tracer.h"
#include "earshot/scene/triangle_mesh.h"

namespace earshot {

/** An affine map p -> R p + t, as a row-major 3x4 matrix: m[row][3] is the
 *  translation (metres). Scene edits expect rigid motions (rotation plus
 *  translation); any finite invertible map is accepted. */
struct AffineTransform {
  std::array<std::array<double, 4>, 3> m{{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}};

  static AffineTransform identity() { return {}; }
  /** Moves by `t` metres. */
  static AffineTransform translation(const Vec3d& t);
  /** Right-handed rotation by `radians` about the line through `pivot`
   *  (metres) along `axis` (any non-zero length; a zero axis gives the
   *  identity). */
  static AffineTransform rotation(const Vec3d& axis, double radians, const Vec3d& pivot = {});
  /** From a column-major 4x4 (glTF, OpenGL); its last row is ignored. */
  static AffineTransform fromColumnMajor(const std::array<double, 16>& c);

  Vec3d apply(const Vec3d& p) const;
  /** The map "first `rhs`, then this". */
  AffineTransform operator*(const AffineTransform& rhs) const;
  /** Determinant of the 3x3 part (0: not invertible). */
  double determinant() const;
  bool isFinite() const;
};

/** Whether a mesh may move after it is added. */
enum class MeshMotion {
  kStatic,   ///< baked into the shared static BVH; moving it rebuilds that BVH
  kMovable,  ///< its own BVH, instanced with its transform; moving it is cheap
};

/** Mesh handle: unique within one DynamicScene, never reused. 0 is never an id. */
using MeshId = uint32_t;

/** BVH builds since the DynamicScene was created (for tests and profiling). */
struct DynamicSceneStats {
  uint64_t commits = 0;          ///< commits that made a new snapshot
  uint64_t staticBvhBuilds = 0;  ///< builds of the BVH over all static meshes
  uint64_t meshBvhBuilds = 0;    ///< builds of a movable mesh's own BVH (once per mesh)
  uint64_t topLevelBuilds = 0;   ///< builds of a snapshot's BVH over instances
  double lastCommitMs = 0.0;     ///< wall time of the last commit that made a snapshot
};

/** The editable scene.
 *
 *  Threading: a DynamicScene is used by one thread at a time (the game
 *  thread): edits, commit() and stats() are not synchronised with each
 *  other. The snapshots commit() returns are immutable and safe to query
 *  from any number of threads while later edits and commits go on; each
 *  stays valid for as long as someone holds it, and frees its share of the
 *  Embree state when the last holder lets go (on whatever thread that is).
 *  The DynamicScene may be destroyed before its snapshots. */
class DynamicScene {
 public:
  /** Fails only when Embree cannot create a device. */
  static Result<std::unique_ptr<DynamicScene>> create();
  ~DynamicScene();
  DynamicScene(const DynamicScene&) = delete;
  DynamicScene& operator=(const DynamicScene&) = delete;

  /** Adds a mesh given in its own frame (metres), placed by `transform`.
   *  `name` only labels errors. Fails (naming the mesh) on a material-id
   *  count that is not one per triangle, non-finite vertices, indices out of
   *  range, or a transform that is not finite or not invertible or that
   *  takes a vertex beyond float range. Material ids are checked when a
   *  snapshot is traced (against the MaterialTable used there). Takes effect
   *  at the next commit. */
  Result<MeshId> addMesh(TriangleMesh mesh, MeshMotion motion, const AffineTransform& transform = {},
                         const std::string& name = "");
  /** Removes a mesh; fails on an unknown id. Snapshots already committed
   *  keep it. */
  Status removeMesh(MeshId id);
  /** Places a mesh (its frame -> world). Checked as in addMesh. Cheap for a
   *  movable mesh; moving a static one rebuilds the static BVH at commit. */
  Status setTransform(MeshId id, const AffineTransform& transform);
  /** Gives every triangle of the mesh `materialId`. Rebuilds no BVH. */
  Status setMaterial(MeshId id, uint32_t materialId);

  /** Builds a snapshot of the scene as edited so far: the static BVH only
   *  if a static mesh was added, removed or moved since the last one, a BVH
   *  for each movable mesh not seen before, a top-level BVH over the
   *  instances when there are movable meshes, the world-space mesh and its
   *  planes. Without edits since the last commit it returns the same
   *  snapshot again. On failure the scene is unchanged and the next commit
   *  tries again. */
  Result<std::shared_ptr<const RayTracer>> commit();

  /** The snapshot of the last successful commit, or null before one. */
  std::shared_ptr<const RayTracer> current() const;
  DynamicSceneStats stats() const;
  size_t meshCount() const;
  bool contains(MeshId id) const;
  /** The mesh's transform; fails on an unknown id. */
  Result<AffineTransform> transformOf(MeshId id) const;

 private:
  DynamicScene();
  struct State;
  std::unique_ptr<State> mState;
};

/** A glTF node that became a movable mesh. */
struct GltfMovableNode {
  std::string name;           ///< the node's name
  MeshId id = 0;
  AffineTransform transform;  ///< the node's world transform in the file (the mesh's initial transform)
};

struct GltfSceneMeshes {
  MeshId staticMesh = 0;                ///< every other node's triangles, in world space (0: none)
  std::vector<GltfMovableNode> movable;  ///< in file load order
  std::vector<std::string> warnings;    ///< the loader's (see loadGltf)
};

/** Loads a glTF file (loadGltf: same materials, map, warnings and errors)
 *  into `scene`: the nodes named in `movableNodeNames` each become a movable
 *  mesh in the node's own frame with the node's world transform (so rotating
 *  about the node's origin swings it as in the file's hierarchy), everything
 *  else one static mesh. Fails, naming the file and the name, when a listed
 *  name matches no node with a mesh, or a node's transform is not
 *  invertible; on failure nothing is added to the scene. Game thread. */
Result<GltfSceneMeshes> loadGltfIntoScene(const std::string& path, const MaterialTable& materials,
                                          const std::map<std::string, std::string>& materialMap,
                                          const std::vector<std::string>& movableNodeNames, DynamicScene& scene,
                                          const InputLimits& limits = defaultInputLimits());

}  // namespace earshot
