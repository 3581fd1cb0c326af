// Editable scene -> immutable RayTracer snapshots over shared Embree BVHs.
//
// Two-level instancing (Embree 3, RTC_GEOMETRY_TYPE_INSTANCE, one instance
// level): a snapshot's root scene holds one instance of the static BVH
// (identity transform: the ray is transformed exactly, so the static
// geometry stays watertight) and one instance per movable mesh. BVHs below
// the root are committed once and never touched again, so snapshots share
// them and old snapshots keep answering while a new root is built.
//
// The frame (RayTracer::frameOrigin): the static BVH holds world positions
// minus the centre of the static meshes' bounds, and every snapshot over it
// traces in that frame; a movable mesh's BVH stays in the mesh's own frame
// and its instance transform is "world -> frame" after "mesh -> world",
// composed in double.
#include "earshot/core/math.h"
#include "earshot/scene/dynamic_scene.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include "earshot/scene/gltf_loader.h"
#include "earshot/scene/planes.h"
#include "embree_bvh.h"
#include "planes_internal.h"

namespace earshot {

// ---- AffineTransform --------------------------------------------------------

AffineTransform AffineTransform::translation(const Vec3d& t) {
  AffineTransform a;
  a.m[0][3] = t.x;
  a.m[1][3] = t.y;
  a.m[2][3] = t.z;
  return a;
}

AffineTransform AffineTransform::rotation(const Vec3d& axis, double radians, const Vec3d& pivot) {
  const double len = length(axis);
  if (!(len > 0)) return {};
  const Vec3d k = axis / len;
  const double c = std::cos(radians), s = std::sin(radians), v = 1.0 - c;
  // Rodrigues: R = c I + s [k]x + (1 - c) k k^T.
  AffineTransform a;
  a.m[0] = {c + k.x * k.x * v, k.x * k.y * v - k.z * s, k.x * k.z * v + k.y * s, 0};
  a.m[1] = {k.y * k.x * v + k.z * s, c + k.y * k.y * v, k.y * k.z * v - k.x * s, 0};
  a.m[2] = {k.z * k.x * v - k.y * s, k.z * k.y * v + k.x * s, c + k.z * k.z * v, 0};
  // About the pivot: p -> R (p - pivot) + pivot.
  const Vec3d rp = a.apply(pivot);
  a.m[0][3] = pivot.x - rp.x;
  a.m[1][3] = pivot.y - rp.y;
  a.m[2][3] = pivot.z - rp.z;
  return a;
}

AffineTransform AffineTransform::fromColumnMajor(const std::array<double, 16>& c) {
  AffineTransform a;
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 4; ++col) a.m[r][col] = c[col * 4 + r];
  return a;
}

Vec3d AffineTransform::apply(const Vec3d& p) const {
  return {m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
          m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
          m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]};
}

AffineTransform AffineTransform::operator*(const AffineTransform& rhs) const {
  AffineTransform r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 4; ++j) {
      double s = j == 3 ? m[i][3] : 0.0;
      for (int k = 0; k < 3; ++k) s += m[i][k] * rhs.m[k][j];
      r.m[i][j] = s;
    }
  return r;
}

double AffineTransform::determinant() const {
  return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
         m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

bool AffineTransform::isFinite() const {
  for (const auto& row : m)
    for (double v : row)
      if (!std::isfinite(v)) return false;
  return true;
}

namespace {

/** The inverse of an invertible transform (adjugate / determinant). */
AffineTransform inverse(const AffineTransform& a) {
  const auto& m = a.m;
  const double inv = 1.0 / a.determinant();
  AffineTransform r;
  r.m[0] = {(m[1][1] * m[2][2] - m[1][2] * m[2][1]) * inv, (m[0][2] * m[2][1] - m[0][1] * m[2][2]) * inv,
            (m[0][1] * m[1][2] - m[0][2] * m[1][1]) * inv, 0};
  r.m[1] = {(m[1][2] * m[2][0] - m[1][0] * m[2][2]) * inv, (m[0][0] * m[2][2] - m[0][2] * m[2][0]) * inv,
            (m[0][2] * m[1][0] - m[0][0] * m[1][2]) * inv, 0};
  r.m[2] = {(m[1][0] * m[2][1] - m[1][1] * m[2][0]) * inv, (m[0][1] * m[2][0] - m[0][0] * m[2][1]) * inv,
            (m[0][0] * m[1][1] - m[0][1] * m[1][0]) * inv, 0};
  const Vec3d t = r.apply({-m[0][3], -m[1][3], -m[2][3]});
  r.m[0][3] = t.x;
  r.m[1][3] = t.y;
  r.m[2][3] = t.z;
  return r;
}

std::string label(MeshId id, const std::string& name) {
  return "mesh " + std::to_string(id) + (name.empty() ? "" : " " + quotedName(name));
}

/** Finite, invertible, and every vertex (inside the box lo..hi) lands in
 *  float range; `what` names the mesh. */
Status checkTransform(const AffineTransform& t, const TriangleMesh& mesh, const Vec3f& lo, const Vec3f& hi,
                      const std::string& what) {
  std::ostringstream s;
  s.precision(17);
  if (!t.isFinite()) {
    s << what << ": transform is not finite (";
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) s << t.m[r][c] << (r == 2 && c == 3 ? ")" : ", ");
    return invalidArgument(s.str());
  }
  const double det = t.determinant();
  if (!(std::fabs(det) > 1e-12)) {
    s << what << ": transform is not invertible (determinant " << det << ")";
    return invalidArgument(s.str());
  }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c)
      if (!std::isfinite(float(t.m[r][c]))) return invalidArgument(what + ": transform is beyond float range");
  if (mesh.positions.empty()) return Status::ok();
  // An affine map takes the box to a parallelepiped spanned by the mapped
  // corners: if they are in float range, every vertex is.
  for (int i = 0; i < 8; ++i) {
    const Vec3d corner{(i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z};
    const Vec3d placed = t.apply(corner);
    if (!isFinite(Vec3f(placed)))
      return invalidArgument(what + ": transform takes the mesh beyond float range");
    if (std::fabs(placed.x) > kMaxCoordinateMeters || std::fabs(placed.y) > kMaxCoordinateMeters ||
        std::fabs(placed.z) > kMaxCoordinateMeters)
      return outOfRange(what + ": transform takes the mesh farther than 1e6 m from the origin");
  }
  return Status::ok();
}

/** Appends `local` placed by `t` (positions in float after a double transform). */
void appendPlaced(TriangleMesh& out, const TriangleMesh& local, const AffineTransform& t) {
  const auto offset = static_cast<uint32_t>(out.positions.size());
  out.positions.reserve(out.positions.size() + local.positions.size());
  for (const Vec3f& p : local.positions) out.positions.push_back(Vec3f(t.apply(Vec3d(p))));
  out.triangles.reserve(out.triangles.size() + local.triangles.size());
  for (const auto& tri : local.triangles) out.triangles.push_back({tri[0] + offset, tri[1] + offset, tri[2] + offset});
  out.materialIds.insert(out.materialIds.end(), local.materialIds.begin(), local.materialIds.end());
}

struct MeshEntry {
  std::string name;
  TriangleMesh mesh;  // in its own frame
  MeshMotion motion = MeshMotion::kStatic;
  AffineTransform transform;
  Vec3f lo, hi;       // bounds in its own frame
  std::shared_ptr<const detail::TriangleBvh> bvh;  // movable: built at the first commit that sees the mesh
};

/** All static meshes in world space, and their BVH. */
struct StaticPart {
  TriangleMesh world;  // materialIds are taken from the entries at each commit
  Vec3d frameOrigin;   // of `world`'s bounds (detail::frameOriginOf); the BVH holds positions minus it
  std::shared_ptr<const detail::TriangleBvh> bvh;
  std::vector<detail::PlaneEntry> planeEntries;  // of `world`, sorted by offset
  std::vector<Vec3f> normals;                    // per triangle of `world` (instance hits)
};

/** Unit (v1-v0) x (v2-v0) of triangles [first, end) of `mesh`, appended to `out`
 *  (the formula of the BVHs' own normals). */
void appendNormals(const TriangleMesh& mesh, size_t first, std::vector<Vec3f>& out) {
  out.reserve(mesh.triangles.size());
  for (size_t t = first; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    out.push_back(normalize(cross(mesh.positions[tri[1]] - mesh.positions[tri[0]],
                                  mesh.positions[tri[2]] - mesh.positions[tri[0]])));
  }
}

}  // namespace

struct DynamicScene::State {
  std::shared_ptr<detail::EmbreeDevice> device;
  std::map<MeshId, MeshEntry> meshes;  // ordered by id: the order of blocks in a snapshot's mesh
  MeshId nextId = 1;
  bool dirty = true;        // edited since the last snapshot
  bool geometryDirty = true;  // a mesh added, removed or moved since the last snapshot (else only materials)
  bool staticDirty = true;  // a static mesh added, removed or moved since the static BVH was built
  std::shared_ptr<const StaticPart> staticPart;
  std::shared_ptr<const RayTracer> current;
  DynamicSceneStats stats;

  /** Material ids in the order of a snapshot's mesh: static meshes, then
   *  movable ones, each in id order. */
  std::vector<uint32_t> materialIds() const {
    std::vector<uint32_t> ids;
    for (MeshMotion motion : {MeshMotion::kStatic, MeshMotion::kMovable})
      for (const auto& [id, e] : meshes)
        if (e.motion == motion) ids.insert(ids.end(), e.mesh.materialIds.begin(), e.mesh.materialIds.end());
    return ids;
  }

  Result<MeshEntry*> find(MeshId id, const char* operation) {
    auto it = meshes.find(id);
    if (it == meshes.end())
      return notFound(std::string(operation) + ": no mesh with id " + std::to_string(id) + " in the scene");
    return &it->second;
  }
};

DynamicScene::DynamicScene() : mState(std::make_unique<State>()) {}
DynamicScene::~DynamicScene() = default;

Result<std::unique_ptr<DynamicScene>> DynamicScene::create() {
  auto device = detail::EmbreeDevice::create();
  if (!device) return device.status();
  std::unique_ptr<DynamicScene> scene(new DynamicScene());
  scene->mState->device = std::move(device).value();
  return scene;
}

Result<MeshId> DynamicScene::addMesh(TriangleMesh mesh, MeshMotion motion, const AffineTransform& transform,
                                     const std::string& name) {
  State& s = *mState;
  const MeshId id = s.nextId;
  const std::string what = "addMesh: " + label(id, name);
  if (Status v = detail::validateMesh(mesh); !v) return Status(v.code(), what + ": " + v.message());
  MeshEntry e;
  e.name = name;
  e.motion = motion;
  e.transform = transform;
  detail::meshBounds(mesh, &e.lo, &e.hi);
  EARSHOT_RETURN_IF_ERROR(checkTransform(transform, mesh, e.lo, e.hi, what));
  if (s.nextId == std::numeric_limits<MeshId>::max()) return outOfRange(what + ": mesh ids exhausted");
  e.mesh = std::move(mesh);
  s.meshes.emplace(id, std::move(e));
  ++s.nextId;
  s.dirty = s.geometryDirty = true;
  if (motion == MeshMotion::kStatic) s.staticDirty = true;
  return id;
}

Status DynamicScene::removeMesh(MeshId id) {
  State& s = *mState;
  auto e = s.find(id, "removeMesh");
  if (!e) return e.status();
  if ((*e)->motion == MeshMotion::kStatic) s.staticDirty = true;
  s.meshes.erase(id);
  s.dirty = s.geometryDirty = true;
  return Status::ok();
}

Status DynamicScene::setTransform(MeshId id, const AffineTransform& transform) {
  State& s = *mState;
  auto found = s.find(id, "setTransform");
  if (!found) return found.status();
  MeshEntry& e = **found;
  EARSHOT_RETURN_IF_ERROR(checkTransform(transform, e.mesh, e.lo, e.hi, "setTransform: " + label(id, e.name)));
  e.transform = transform;
  s.dirty = s.geometryDirty = true;
  if (e.motion == MeshMotion::kStatic) s.staticDirty = true;
  return Status::ok();
}

Status DynamicScene::setMaterial(MeshId id, uint32_t materialId) {
  State& s = *mState;
  auto found = s.find(id, "setMaterial");
  if (!found) return found.status();
  std::fill((*found)->mesh.materialIds.begin(), (*found)->mesh.materialIds.end(), materialId);
  s.dirty = true;
  return Status::ok();
}

Result<std::shared_ptr<const RayTracer>> DynamicScene::commit() {
  State& s = *mState;
  if (!s.dirty && s.current) return s.current;
  const auto start = std::chrono::steady_clock::now();
  auto finish = [&](std::unique_ptr<RayTracer> rt) -> std::shared_ptr<const RayTracer> {
    s.current = std::shared_ptr<const RayTracer>(std::move(rt));
    s.dirty = s.geometryDirty = false;
    ++s.stats.commits;
    s.stats.lastCommitMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return s.current;
  };
  if (!s.geometryDirty && s.current) {
    // Only materials changed: the previous snapshot's geometry, planes and
    // BVHs serve as they are.
    const RayTracer& prev = *s.current;
    std::unique_ptr<RayTracer> rt(new RayTracer());
    rt->mMesh.positions = prev.mMesh.positions;
    rt->mMesh.triangles = prev.mMesh.triangles;
    rt->mMesh.materialIds = s.materialIds();
    rt->mPlanes = prev.mPlanes;
    rt->mMin = prev.mMin;
    rt->mMax = prev.mMax;
    rt->mFrameOrigin = prev.mFrameOrigin;  // the BVHs below were built for it
    rt->mEpsilon = prev.mEpsilon;
    rt->mConvexSides = prev.mConvexSides;
    rt->mImpl = std::make_unique<RayTracer::Impl>(*prev.mImpl);
    return finish(std::move(rt));
  }
  // Hit::triangle and the vertex indices are 32-bit.
  uint64_t triangles = 0, vertices = 0;
  for (const auto& [id, e] : s.meshes) triangles += e.mesh.triangles.size(), vertices += e.mesh.positions.size();
  if (triangles > std::numeric_limits<uint32_t>::max() || vertices > std::numeric_limits<uint32_t>::max())
    return outOfRange("commit: the scene's " + std::to_string(triangles) + " triangles and " +
                      std::to_string(vertices) + " vertices exceed 2^32 - 1");
  const std::shared_ptr<detail::EmbreeDevice>& device = s.device;

  // The static BVH, only when the static meshes changed.
  if (s.staticDirty || !s.staticPart) {
    auto part = std::make_shared<StaticPart>();
    for (const auto& [id, e] : s.meshes)
      if (e.motion == MeshMotion::kStatic) appendPlaced(part->world, e.mesh, e.transform);
    Vec3f lo, hi;
    detail::meshBounds(part->world, &lo, &hi);
    part->frameOrigin = detail::frameOriginOf(lo, hi);
    auto bvh = detail::buildTriangleBvh(device, part->world, part->frameOrigin);
    if (!bvh) return Status(bvh.status().code(), "commit: static meshes: " + bvh.status().message());
    part->bvh = std::move(bvh).value();
    part->planeEntries = detail::sortedPlaneEntries(part->world);
    appendNormals(part->world, 0, part->normals);
    s.staticPart = std::move(part);
    s.staticDirty = false;
    ++s.stats.staticBvhBuilds;
  }
  // A BVH of its own for each movable mesh seen for the first time.
  for (auto& [id, e] : s.meshes) {
    if (e.motion != MeshMotion::kMovable || e.bvh) continue;
    auto bvh = detail::buildTriangleBvh(device, e.mesh, Vec3d{});  // in the mesh's own frame
    if (!bvh) return Status(bvh.status().code(), "commit: " + label(id, e.name) + ": " + bvh.status().message());
    e.bvh = std::move(bvh).value();
    ++s.stats.meshBvhBuilds;
  }

  // The world-space mesh every index of the snapshot refers to: the static
  // block, then each movable mesh.
  std::unique_ptr<RayTracer> rt(new RayTracer());
  TriangleMesh& world = rt->mMesh;
  const StaticPart& sp = *s.staticPart;
  world.positions = sp.world.positions;
  world.triangles = sp.world.triangles;
  struct Placed {
    const MeshEntry* entry;
    uint32_t firstTriangle;
  };
  std::vector<Placed> movable;
  for (const auto& [id, e] : s.meshes) {
    if (e.motion != MeshMotion::kMovable) continue;
    movable.push_back({&e, static_cast<uint32_t>(world.triangles.size())});
    appendPlaced(world, e.mesh, e.transform);
  }
  world.materialIds = s.materialIds();  // the entries' current materials (setMaterial)
  detail::meshBounds(world, &rt->mMin, &rt->mMax);
  // The static BVH's frame; without static meshes nothing shared fixes it,
  // and the snapshot centres on its own bounds.
  rt->mFrameOrigin = sp.world.positions.empty() ? detail::frameOriginOf(rt->mMin, rt->mMax) : sp.frameOrigin;
  rt->mEpsilon = detail::surfaceEpsilonOf(rt->mMin, rt->mMax, rt->mFrameOrigin);
  // groupCoplanarTriangles(world), with the static triangles' entries sorted once.
  const std::vector<detail::PlaneEntry> movableEntries = detail::sortedPlaneEntries(world, sp.world.triangles.size());
  std::vector<detail::PlaneEntry> planeEntries(sp.planeEntries.size() + movableEntries.size());
  std::merge(sp.planeEntries.begin(), sp.planeEntries.end(), movableEntries.begin(), movableEntries.end(),
             planeEntries.begin(), detail::byOffset);
  rt->mPlanes = detail::groupSortedPlaneEntries(planeEntries, world.triangles.size());
  addPlaneBounds(world, rt->mPlanes);
  rt->mConvexSides = convexSides(world, rt->mPlanes, rt->mEpsilon);

  auto impl = std::make_unique<RayTracer::Impl>();
  impl->device = device;
  const bool anyInstance = std::any_of(movable.begin(), movable.end(),
                                       [](const Placed& p) { return !p.entry->bvh->primToTriangle.empty(); });
  if (!anyInstance) {
    // Nothing moves: the static BVH itself is the root, shared as it is.
    impl->flat = sp.bvh;
    impl->root = sp.bvh->scene;
    rtcRetainScene(impl->root);
  } else {
    device->takeError();
    impl->root = rtcNewScene(device->get());
    if (!impl->root) return Status(StatusCode::kInternal, "commit: cannot create an Embree scene: " + device->takeError());
    rtcSetSceneBuildQuality(impl->root, RTC_BUILD_QUALITY_MEDIUM);
    rtcSetSceneFlags(impl->root, RTC_SCENE_FLAG_ROBUST);
    auto attach = [&](const std::shared_ptr<const detail::TriangleBvh>& bvh, const AffineTransform& t,
                      uint32_t firstTriangle) {
      float xfm[12];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) xfm[r * 4 + c] = float(t.m[r][c]);
      RTCGeometry g = rtcNewGeometry(device->get(), RTC_GEOMETRY_TYPE_INSTANCE);
      rtcSetGeometryInstancedScene(g, bvh->scene);
      rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, xfm);
      rtcCommitGeometry(g);
      const unsigned geomId = rtcAttachGeometry(impl->root, g);
      rtcReleaseGeometry(g);
      if (geomId == RTC_INVALID_GEOMETRY_ID) return;  // reported through the device's error
      if (impl->instances.size() <= geomId) impl->instances.resize(geomId + 1);
      impl->instances[geomId] = {firstTriangle, bvh.get()};
      impl->instanced.push_back(bvh);
    };
    // The static BVH is in the frame already; a movable mesh goes from its
    // own frame to the world (its transform), then to the frame.
    const AffineTransform worldToFrame = AffineTransform::translation(-rt->mFrameOrigin);
    if (!sp.bvh->primToTriangle.empty()) attach(sp.bvh, AffineTransform::identity(), 0);
    for (const Placed& p : movable)
      if (!p.entry->bvh->primToTriangle.empty())
        attach(p.entry->bvh, worldToFrame * p.entry->transform, p.firstTriangle);
    rtcCommitScene(impl->root);
    const std::string error = device->takeError();
    if (!error.empty()) return Status(StatusCode::kInternal, "commit: " + error);
    ++s.stats.topLevelBuilds;
    // Hit normals in the world frame, from the world-space triangles.
    impl->worldNormals = sp.normals;
    appendNormals(world, sp.world.triangles.size(), impl->worldNormals);
  }
  rt->mImpl = std::move(impl);
  return finish(std::move(rt));
}

std::shared_ptr<const RayTracer> DynamicScene::current() const { return mState->current; }
DynamicSceneStats DynamicScene::stats() const { return mState->stats; }
size_t DynamicScene::meshCount() const { return mState->meshes.size(); }
bool DynamicScene::contains(MeshId id) const { return mState->meshes.count(id) != 0; }

Result<AffineTransform> DynamicScene::transformOf(MeshId id) const {
  auto it = mState->meshes.find(id);
  if (it == mState->meshes.end())
    return notFound("transformOf: no mesh with id " + std::to_string(id) + " in the scene");
  return it->second.transform;
}

// ---- glTF ---------------------------------------------------------------

namespace {

/** Triangles [first, first + count) of `mesh` (their vertices are
 *  contiguous, as loadGltf lays them out) as a mesh of their own, each
 *  vertex mapped by `t`. */
TriangleMesh extract(const TriangleMesh& mesh, uint32_t first, uint32_t count, const AffineTransform* t) {
  TriangleMesh out;
  if (count == 0) return out;
  uint32_t lo = std::numeric_limits<uint32_t>::max(), hi = 0;
  for (uint32_t k = first; k < first + count; ++k)
    for (uint32_t v : mesh.triangles[k]) lo = std::min(lo, v), hi = std::max(hi, v);
  out.positions.reserve(hi - lo + 1);
  for (uint32_t v = lo; v <= hi; ++v)
    out.positions.push_back(t ? Vec3f(t->apply(Vec3d(mesh.positions[v]))) : mesh.positions[v]);
  for (uint32_t k = first; k < first + count; ++k) {
    const auto& tri = mesh.triangles[k];
    out.triangles.push_back({tri[0] - lo, tri[1] - lo, tri[2] - lo});
    out.materialIds.push_back(mesh.materialIds[k]);
  }
  return out;
}

}  // namespace

Result<GltfSceneMeshes> loadGltfIntoScene(const std::string& path, const MaterialTable& materials,
                                          const std::map<std::string, std::string>& materialMap,
                                          const std::vector<std::string>& movableNodeNames, DynamicScene& scene,
                                          const InputLimits& limits) {
  auto loaded = loadGltf(path, materials, materialMap, limits);
  if (!loaded) return loaded.status();
  const GltfLoadResult& g = *loaded;
  std::vector<char> isMovable(g.nodes.size(), 0);
  for (const std::string& name : movableNodeNames) {
    bool found = false;
    for (size_t i = 0; i < g.nodes.size(); ++i)
      if (g.nodes[i].name == name) isMovable[i] = 1, found = true;
    if (!found) return notFound(path + ": no node named " + quotedName(name) + " with a mesh (asked to be movable)");
  }

  GltfSceneMeshes out;
  out.warnings = g.warnings;
  TriangleMesh staticMesh;
  struct Pending {
    std::string name;
    TriangleMesh mesh;
    AffineTransform transform;
  };
  std::vector<Pending> pending;
  for (size_t i = 0; i < g.nodes.size(); ++i) {
    const GltfNodeTriangles& n = g.nodes[i];
    if (!isMovable[i]) {
      staticMesh.append(extract(g.mesh, n.firstTriangle, n.triangleCount, nullptr));
      continue;
    }
    const AffineTransform world = AffineTransform::fromColumnMajor(n.worldMatrix);
    if (!(std::fabs(world.determinant()) > 1e-12))
      return invalidArgument(path + ": node " + std::to_string(n.node) + " " + quotedName(n.name) +
                             ": transform is not invertible, so it cannot be a movable mesh");
    // Back to the node's frame: the loader gave world positions.
    const AffineTransform toLocal = inverse(world);
    pending.push_back({n.name, extract(g.mesh, n.firstTriangle, n.triangleCount, &toLocal), world});
  }

  // Add everything or nothing.
  std::vector<MeshId> added;
  auto rollback = [&](const Status& why) {
    for (MeshId id : added) (void)scene.removeMesh(id);
    return Status(why.code(), path + ": " + why.message());
  };
  if (!staticMesh.triangles.empty()) {
    auto id = scene.addMesh(std::move(staticMesh), MeshMotion::kStatic, {}, "static part of " + path);
    if (!id) return rollback(id.status());
    out.staticMesh = *id;
    added.push_back(*id);
  }
  for (Pending& p : pending) {
    auto id = scene.addMesh(std::move(p.mesh), MeshMotion::kMovable, p.transform, p.name);
    if (!id) return rollback(id.status());
    added.push_back(*id);
    out.movable.push_back({p.name, *id, p.transform});
  }
  return out;
}

}  // namespace earshot
