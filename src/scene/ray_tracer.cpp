// Embree 3 behind earshot's RayTracer. Embree is included only in src/scene.
#include "earshot/scene/ray_tracer.h"

#include <atomic>

#include <embree3/rtcore.h>

#include <cmath>
#include <mutex>
#include <string>

#include "earshot/core/math.h"

#include "earshot/scene/embree_limit.h"
#include "embree_bvh.h"

namespace earshot {

Result<std::unique_ptr<RayTracer>> RayTracer::create(const TriangleMesh& mesh) {
  EARSHOT_RETURN_IF_ERROR(detail::validateMesh(mesh));
  std::unique_ptr<RayTracer> rt(new RayTracer());
  rt->mMesh = mesh;
  detail::meshBounds(mesh, &rt->mMin, &rt->mMax);
  rt->mFrameOrigin = detail::frameOriginOf(rt->mMin, rt->mMax);
  rt->mEpsilon = detail::surfaceEpsilonOf(rt->mMin, rt->mMax, rt->mFrameOrigin);
  rt->mPlanes = groupCoplanarTriangles(mesh);
  rt->mConvexSides = convexSides(mesh, rt->mPlanes, rt->mEpsilon);

  auto device = detail::EmbreeDevice::create();
  if (!device) return device.status();
  auto bvh = detail::buildTriangleBvh(*device, mesh, rt->mFrameOrigin);
  if (!bvh) return bvh.status();
  rt->mImpl = std::make_unique<Impl>();
  rt->mImpl->device = std::move(device).value();
  rt->mImpl->flat = std::move(bvh).value();
  rt->mImpl->root = rt->mImpl->flat->scene;
  rtcRetainScene(rt->mImpl->root);
  return rt;
}

RayTracer::RayTracer() = default;

uint64_t RayTracer::nextId() {
  static std::atomic<uint64_t> next{1};
  return next.fetch_add(1, std::memory_order_relaxed);
}
RayTracer::~RayTracer() = default;

namespace {
/** What Embree can take: it asserts (aborts the process) on rays with huge
 *  or non-finite origins. The callers validate positions (kMaxCoordinateMeters);
 *  this keeps any ray that slipped through from reaching Embree at all. */
bool traceable(const Ray& ray) {
  return withinCoordinateRange(ray.origin) && std::isfinite(ray.direction.x) && std::isfinite(ray.direction.y) &&
         std::isfinite(ray.direction.z) && !(ray.tNear > ray.tFar) && std::isfinite(ray.tNear);
}
}  // namespace

static void recordQuery(QueryLog* log, const Ray& ray, bool shadow) {
  std::lock_guard<std::mutex> lock(log->mutex);
  log->rays.push_back(ray);
  log->shadow.push_back(shadow ? 1 : 0);
}

bool RayTracer::intersect(const Ray& ray, Hit& hit) const {
  if (QueryLog* log = mRecorder.load(std::memory_order_relaxed)) recordQuery(log, ray, false);
  if (!traceable(ray)) {
    hit.t = -1.0f;
    return false;
  }
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh;
  const Vec3f org(ray.origin - mFrameOrigin);  // Embree's frame (class comment)
  rh.ray.org_x = org.x;
  rh.ray.org_y = org.y;
  rh.ray.org_z = org.z;
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
  rtcIntersect1(mImpl->root, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
    hit.t = -1.0f;
    return false;
  }
  hit.t = rh.ray.tfar;
  hit.u = rh.hit.u;
  hit.v = rh.hit.v;
  if (rh.hit.instID[0] == RTC_INVALID_GEOMETRY_ID) {
    // The root's own triangles: normals do not change with the frame's translation.
    hit.triangle = mImpl->flat->primToTriangle[rh.hit.primID];
    hit.normal = mImpl->flat->normals[rh.hit.primID];
  } else {
    // An instance: Embree reports the instance and the primitive in the
    // instanced mesh; Hit.normal must be in the world frame.
    const Impl::Instance& inst = mImpl->instances[rh.hit.instID[0]];
    hit.triangle = inst.firstTriangle + inst.bvh->primToTriangle[rh.hit.primID];
    hit.normal = mImpl->worldNormals[hit.triangle];
  }
  return true;
}

bool RayTracer::occluded(const Ray& ray) const {
  if (QueryLog* log = mRecorder.load(std::memory_order_relaxed)) recordQuery(log, ray, true);
  if (!traceable(ray)) return false;
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay r;
  const Vec3f org(ray.origin - mFrameOrigin);  // Embree's frame (class comment)
  r.org_x = org.x;
  r.org_y = org.y;
  r.org_z = org.z;
  r.tnear = ray.tNear;
  r.dir_x = ray.direction.x;
  r.dir_y = ray.direction.y;
  r.dir_z = ray.direction.z;
  r.time = 0.0f;
  r.tfar = ray.tFar;
  r.mask = 0xFFFFFFFFu;
  r.id = 0;
  r.flags = 0;
  rtcOccluded1(mImpl->root, &ctx, &r);
  return r.tfar < 0.0f;  // Embree sets tfar to -inf on a hit
}

void RayTracer::occludedMany(const Ray* rays, size_t count, uint8_t* occludedOut) const {
  // Up to 64 rays per stream call, in a fixed buffer (no allocation).
  constexpr size_t kChunk = 64;
  RTCRay stream[kChunk];
  size_t index[kChunk];
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  // Incoherent (the default), although the rays often share an origin:
  // with RTC_INTERSECT_CONTEXT_FLAG_COHERENT, Embree 3.13.5 as Debian 12
  // builds it can loop for ever over instances on CPUs with AVX-512 (its
  // coherent packet path keeps a 16-bit ray mask in a 64-bit stack slot and
  // tests all 64 bits, so bytes left there by earlier calls keep the loop
  // going). Test: DynamicScene.ShadowRaysOverInstancesReturnWhateverTheStackHeld.
  for (size_t start = 0; start < count; start += kChunk) {
    const size_t end = std::min(count, start + kChunk);
    size_t n = 0;
    for (size_t i = start; i < end; ++i) {
      const Ray& ray = rays[i];
      if (QueryLog* log = mRecorder.load(std::memory_order_relaxed)) recordQuery(log, ray, true);
      occludedOut[i] = 0;
      if (!traceable(ray)) continue;
      RTCRay& r = stream[n];
      const Vec3f org(ray.origin - mFrameOrigin);
      r.org_x = org.x;
      r.org_y = org.y;
      r.org_z = org.z;
      r.tnear = ray.tNear;
      r.dir_x = ray.direction.x;
      r.dir_y = ray.direction.y;
      r.dir_z = ray.direction.z;
      r.time = 0.0f;
      r.tfar = ray.tFar;
      r.mask = 0xFFFFFFFFu;
      r.id = unsigned(n);
      r.flags = 0;
      index[n++] = i;
    }
    if (n == 0) continue;
    rtcOccluded1M(mImpl->root, &ctx, stream, unsigned(n), sizeof(RTCRay));
    for (size_t k = 0; k < n; ++k) occludedOut[index[k]] = stream[k].tfar < 0.0f ? 1 : 0;
  }
}

bool RayTracer::convexAround(const Vec3d& p) const {
  if (mConvexSides.empty()) return false;
  for (size_t i = 0; i < mPlanes.planes.size(); ++i)
    if (!(mPlanes.planes[i].distance(p) * mConvexSides[i] > mEpsilon)) return false;
  return true;
}

bool RayTracer::nothingBetween(const Vec3d& a, const Vec3d& b) const {
  if (mPlanes.planes.size() > 256) return false;
  return segmentCrossesNoPlane(mPlanes, a, b, mEpsilon);
}

}  // namespace earshot
