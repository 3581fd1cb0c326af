// Embree scenes over triangle meshes, shared by RayTracer and DynamicScene.
#include "earshot/core/math.h"
#include "embree_bvh.h"

#include <algorithm>
#include <cmath>

namespace earshot {
namespace detail {

Result<std::shared_ptr<EmbreeDevice>> EmbreeDevice::create() {
  std::shared_ptr<EmbreeDevice> d(new EmbreeDevice());
  d->mDevice = rtcNewDevice("verbose=0");
  if (!d->mDevice) return Status(StatusCode::kInternal, "cannot create an Embree device");
  rtcSetDeviceErrorFunction(d->mDevice, &EmbreeDevice::onError, d.get());
  return d;
}

EmbreeDevice::~EmbreeDevice() {
  if (mDevice) rtcReleaseDevice(mDevice);
}

void EmbreeDevice::onError(void* user, RTCError code, const char* message) {
  auto* self = static_cast<EmbreeDevice*>(user);
  std::lock_guard<std::mutex> lock(self->mMutex);
  if (self->mError.empty())
    self->mError = std::string("embree error ") + std::to_string(int(code)) + ": " + (message ? message : "");
}

std::string EmbreeDevice::takeError() {
  std::lock_guard<std::mutex> lock(mMutex);
  std::string e;
  e.swap(mError);
  return e;
}

TriangleBvh::~TriangleBvh() {
  if (scene) rtcReleaseScene(scene);
}

Status validateMesh(const TriangleMesh& mesh) {
  if (mesh.materialIds.size() != mesh.triangles.size())
    return invalidArgument("mesh has " + std::to_string(mesh.triangles.size()) + " triangles but " +
                           std::to_string(mesh.materialIds.size()) + " material ids");
  for (size_t i = 0; i < mesh.positions.size(); ++i)
  {
    const Vec3f& p = mesh.positions[i];
    if (!isFinite(p)) return invalidArgument("vertex " + std::to_string(i) + " is not finite");
    // Embree's builder asserts (aborts the process) from ~1.8e18; float
    // geometry loses centimetres long before. One documented limit instead.
    if (std::abs(p.x) > kMaxCoordinateMeters || std::abs(p.y) > kMaxCoordinateMeters ||
        std::abs(p.z) > kMaxCoordinateMeters)
      return outOfRange("vertex " + std::to_string(i) + " is farther than " + std::to_string(int(kMaxCoordinateMeters)) +
                        " m from the origin on some axis");
  }
  for (size_t t = 0; t < mesh.triangles.size(); ++t)
    for (uint32_t v : mesh.triangles[t])
      if (v >= mesh.positions.size())
        return invalidArgument("triangle " + std::to_string(t) + " has vertex index " + std::to_string(v) +
                               " beyond the " + std::to_string(mesh.positions.size()) + " vertices");
  return Status::ok();
}

void meshBounds(const TriangleMesh& mesh, Vec3f* loOut, Vec3f* hiOut) {
  Vec3f lo{1e30f, 1e30f, 1e30f}, hi{-1e30f, -1e30f, -1e30f};
  for (const Vec3f& p : mesh.positions) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  if (mesh.positions.empty()) lo = hi = Vec3f{};
  *loOut = lo;
  *hiOut = hi;
}

Vec3d frameOriginOf(const Vec3f& lo, const Vec3f& hi) {
  return Vec3d(Vec3f((Vec3d(lo) + Vec3d(hi)) * 0.5));
}

float surfaceEpsilonOf(const Vec3f& lo, const Vec3f& hi, const Vec3d& origin) {
  // Offset: well above float rounding at the largest frame coordinate (ulp ~
  // 6e-8 * |x|), and small against any room: 1e-5 of the extent, at least 1e-5 m.
  const Vec3d a = Vec3d(lo) - origin, b = Vec3d(hi) - origin;
  const double maxAbs =
      std::max({std::fabs(a.x), std::fabs(a.y), std::fabs(a.z), std::fabs(b.x), std::fabs(b.y), std::fabs(b.z)});
  const float extent = length(hi - lo);
  return std::max({1e-5f, 1e-5f * extent, float(64.0 * 6e-8 * maxAbs)});
}

Result<std::shared_ptr<const TriangleBvh>> buildTriangleBvh(const std::shared_ptr<EmbreeDevice>& device,
                                                            const TriangleMesh& mesh, const Vec3d& offset) {
  auto bvh = std::make_shared<TriangleBvh>();
  bvh->device = device;
  // The positions Embree sees; degeneracy and normals are judged on them.
  std::vector<Vec3f> local(mesh.positions.size());
  for (size_t i = 0; i < local.size(); ++i) local[i] = Vec3f(Vec3d(mesh.positions[i]) - offset);
  // Keep non-degenerate triangles only.
  std::vector<uint32_t> idx;
  idx.reserve(mesh.triangles.size() * 3);
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    Vec3f n = cross(local[tri[1]] - local[tri[0]], local[tri[2]] - local[tri[0]]);
    if (!(dot(n, n) > 0.0f)) continue;
    bvh->primToTriangle.push_back(uint32_t(t));
    bvh->normals.push_back(normalize(n));
    idx.insert(idx.end(), tri.begin(), tri.end());
  }

  device->takeError();
  bvh->scene = rtcNewScene(device->get());
  if (!bvh->scene) return Status(StatusCode::kInternal, "cannot create an Embree scene: " + device->takeError());
  rtcSetSceneBuildQuality(bvh->scene, RTC_BUILD_QUALITY_MEDIUM);
  // Robust (watertight) traversal: without it a ray hitting an edge exactly can
  // slip between two triangles and leave a closed room (1 in ~2e7 segments
  // here). It costs ~20 % of tracing time (docs/design.md).
  rtcSetSceneFlags(bvh->scene, RTC_SCENE_FLAG_ROBUST);
  if (!bvh->primToTriangle.empty()) {
    RTCGeometry geom = rtcNewGeometry(device->get(), RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                           3 * sizeof(float), mesh.positions.size()));
    auto* ib = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                              3 * sizeof(uint32_t), bvh->primToTriangle.size()));
    if (!vb || !ib) {
      rtcReleaseGeometry(geom);
      return Status(StatusCode::kInternal, "embree buffer allocation failed: " + device->takeError());
    }
    for (size_t i = 0; i < local.size(); ++i) {
      vb[3 * i] = local[i].x;
      vb[3 * i + 1] = local[i].y;
      vb[3 * i + 2] = local[i].z;
    }
    std::copy(idx.begin(), idx.end(), ib);
    rtcCommitGeometry(geom);
    rtcAttachGeometry(bvh->scene, geom);
    rtcReleaseGeometry(geom);
  }
  rtcCommitScene(bvh->scene);
  const std::string error = device->takeError();
  if (!error.empty()) return Status(StatusCode::kInternal, error);
  return std::shared_ptr<const TriangleBvh>(std::move(bvh));
}

}  // namespace detail
}  // namespace earshot
