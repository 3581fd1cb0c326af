// Embree 3 behind earshot's RayTracer. The only file that includes Embree.
#include "earshot/scene/ray_tracer.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace earshot {

struct RayTracer::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<uint32_t> primToTriangle;  // Embree primID -> mesh triangle (degenerates dropped)
  std::vector<Vec3f> normals;            // per Embree primID: unit (v1-v0) x (v2-v0)
  std::string lastError;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

namespace {
void onEmbreeError(void* user, RTCError code, const char* str) {
  auto* impl = static_cast<RayTracer::Impl*>(user);
  impl->lastError = std::string("embree error ") + std::to_string(int(code)) + ": " + (str ? str : "");
}
}  // namespace

Result<std::unique_ptr<RayTracer>> RayTracer::create(const TriangleMesh& mesh) {
  if (mesh.materialIds.size() != mesh.triangles.size())
    return invalidArgument("mesh has " + std::to_string(mesh.triangles.size()) + " triangles but " +
                           std::to_string(mesh.materialIds.size()) + " material ids");
  std::unique_ptr<RayTracer> rt(new RayTracer());
  rt->mMesh = mesh;
  rt->mImpl = std::make_unique<Impl>();
  Impl& impl = *rt->mImpl;

  Vec3f lo{1e30f, 1e30f, 1e30f}, hi{-1e30f, -1e30f, -1e30f};
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    const Vec3f& p = mesh.positions[i];
    if (!isFinite(p)) return invalidArgument("vertex " + std::to_string(i) + " is not finite");
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  if (mesh.positions.empty()) lo = hi = Vec3f{};
  rt->mMin = lo;
  rt->mMax = hi;
  // Offset: well above float rounding at the largest coordinate (ulp ~ 6e-8 * |x|),
  // and small against any room: 1e-5 of the extent, at least 1e-5 m.
  float maxAbs = std::max({std::fabs(lo.x), std::fabs(lo.y), std::fabs(lo.z), std::fabs(hi.x), std::fabs(hi.y), std::fabs(hi.z)});
  float extent = length(hi - lo);
  rt->mEpsilon = std::max({1e-5f, 1e-5f * extent, 64.0f * 6e-8f * maxAbs});

  // Keep non-degenerate triangles only.
  std::vector<uint32_t> idx;
  idx.reserve(mesh.triangles.size() * 3);
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    for (uint32_t v : tri)
      if (v >= mesh.positions.size())
        return invalidArgument("triangle " + std::to_string(t) + " has vertex index " + std::to_string(v) +
                               " beyond the " + std::to_string(mesh.positions.size()) + " vertices");
    Vec3f n = cross(mesh.positions[tri[1]] - mesh.positions[tri[0]], mesh.positions[tri[2]] - mesh.positions[tri[0]]);
    if (!(dot(n, n) > 0.0f)) continue;
    impl.primToTriangle.push_back(uint32_t(t));
    impl.normals.push_back(normalize(n));
    idx.insert(idx.end(), tri.begin(), tri.end());
  }

  rt->mPlanes = groupCoplanarTriangles(mesh);

  impl.device = rtcNewDevice("verbose=0");
  if (!impl.device) return Status(StatusCode::kInternal, "cannot create an Embree device");
  rtcSetDeviceErrorFunction(impl.device, onEmbreeError, &impl);
  impl.scene = rtcNewScene(impl.device);
  rtcSetSceneBuildQuality(impl.scene, RTC_BUILD_QUALITY_MEDIUM);
  // Robust (watertight) traversal: without it a ray hitting an edge exactly can
  // slip between two triangles and leave a closed room (1 in ~2e7 segments
  // here). It costs ~20 % of tracing time (DESIGN.md).
  rtcSetSceneFlags(impl.scene, RTC_SCENE_FLAG_ROBUST);
  if (!impl.primToTriangle.empty()) {
    RTCGeometry geom = rtcNewGeometry(impl.device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                           3 * sizeof(float), mesh.positions.size()));
    auto* ib = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                              3 * sizeof(uint32_t), impl.primToTriangle.size()));
    if (!vb || !ib) {
      rtcReleaseGeometry(geom);
      return Status(StatusCode::kInternal, "embree buffer allocation failed: " + impl.lastError);
    }
    for (size_t i = 0; i < mesh.positions.size(); ++i) {
      vb[3 * i] = mesh.positions[i].x;
      vb[3 * i + 1] = mesh.positions[i].y;
      vb[3 * i + 2] = mesh.positions[i].z;
    }
    std::copy(idx.begin(), idx.end(), ib);
    rtcCommitGeometry(geom);
    rtcAttachGeometry(impl.scene, geom);
    rtcReleaseGeometry(geom);
  }
  rtcCommitScene(impl.scene);
  if (!impl.lastError.empty()) return Status(StatusCode::kInternal, impl.lastError);
  return rt;
}

RayTracer::~RayTracer() = default;

bool RayTracer::intersect(const Ray& ray, Hit& hit) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh;
  rh.ray.org_x = ray.origin.x;
  rh.ray.org_y = ray.origin.y;
  rh.ray.org_z = ray.origin.z;
  rh.ray.tnear = ray.tNear;
  rh.ray.dir_x = ray.direction.x;
  rh.ray.dir_y = ray.direction.y;
  rh.ray.dir_z = ray.direction.z;
  rh.ray.time = 0.0f;
  rh.ray.tfar = ray.tFar;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(mImpl->scene, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
    hit.t = -1.0f;
    return false;
  }
  hit.t = rh.ray.tfar;
  hit.triangle = mImpl->primToTriangle[rh.hit.primID];
  hit.normal = mImpl->normals[rh.hit.primID];
  return true;
}

bool RayTracer::occluded(const Ray& ray) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay r;
  r.org_x = ray.origin.x;
  r.org_y = ray.origin.y;
  r.org_z = ray.origin.z;
  r.tnear = ray.tNear;
  r.dir_x = ray.direction.x;
  r.dir_y = ray.direction.y;
  r.dir_z = ray.direction.z;
  r.time = 0.0f;
  r.tfar = ray.tFar;
  r.mask = 0xFFFFFFFFu;
  r.id = 0;
  r.flags = 0;
  rtcOccluded1(mImpl->scene, &ctx, &r);
  return r.tfar < 0.0f;  // Embree sets tfar to -inf on a hit
}

}  // namespace earshot
