// The Embree limit of a trace: recorded queries replayed through plain
// Embree calls (embree_limit.h).
#include "earshot/scene/embree_limit.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>

#include "earshot/core/math.h"
#include "earshot/core/thread_pool.h"
#include "embree_bvh.h"

namespace earshot {

size_t QueryLog::shadowCount() const {
  size_t n = 0;
  for (uint8_t s : shadow) n += s;
  return n;
}

QueryRecording::QueryRecording(const RayTracer& tracer, QueryLog& log) : mTracer(tracer) {
  mTracer.mRecorder.store(&log);
}
QueryRecording::~QueryRecording() { mTracer.mRecorder.store(nullptr); }

const char* embreeModeName(EmbreeMode mode) {
  switch (mode) {
    case EmbreeMode::kSingle: return "single";
    case EmbreeMode::kStream: return "stream";
    case EmbreeMode::kPacket8: return "packet8";
  }
  return "?";
}

namespace {
constexpr size_t kChunk = 256;  // rays per task, as the tracer's ray batches

RTCRay embreeRay(const Ray& r, const Vec3d& frame) {
  RTCRay e{};
  const Vec3f org(r.origin - frame);
  e.org_x = org.x;
  e.org_y = org.y;
  e.org_z = org.z;
  e.tnear = r.tNear;
  e.dir_x = r.direction.x;
  e.dir_y = r.direction.y;
  e.dir_z = r.direction.z;
  e.time = 0.0f;
  e.tfar = r.tFar;
  e.mask = 0xFFFFFFFFu;
  e.id = 0;
  e.flags = 0;
  return e;
}
}  // namespace

struct EmbreeReplay::Impl {
  RTCScene scene = nullptr;
  std::vector<RTCRay> nearest, shadows;  // Embree's frame; copied before each trace
};

EmbreeReplay::EmbreeReplay(const RayTracer& tracer, const QueryLog& log) : mImpl(std::make_unique<Impl>()) {
  mImpl->scene = tracer.mImpl->root;
  for (size_t i = 0; i < log.rays.size(); ++i) {
    const Ray& r = log.rays[i];
    // As RayTracer: rays Embree cannot take are not traced.
    if (!withinCoordinateRange(r.origin) || !(r.tNear <= r.tFar)) continue;
    (log.shadow[i] ? mImpl->shadows : mImpl->nearest).push_back(embreeRay(r, tracer.frameOrigin()));
  }
}
EmbreeReplay::~EmbreeReplay() = default;
size_t EmbreeReplay::intersectCount() const { return mImpl->nearest.size(); }
size_t EmbreeReplay::shadowCount() const { return mImpl->shadows.size(); }

size_t EmbreeReplay::run(EmbreeMode mode, ThreadPool& pool) const {
  const Impl& m = *mImpl;
  const size_t nearestTasks = (m.nearest.size() + kChunk - 1) / kChunk;
  const size_t shadowTasks = (m.shadows.size() + kChunk - 1) / kChunk;
  std::atomic<size_t> hits{0};
  pool.parallelFor(nearestTasks + shadowTasks, [&](size_t task, unsigned) {
    const bool shadow = task >= nearestTasks;
    const std::vector<RTCRay>& rays = shadow ? m.shadows : m.nearest;
    const size_t first = (shadow ? task - nearestTasks : task) * kChunk;
    const size_t count = std::min(kChunk, rays.size() - first);
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    size_t found = 0;
    if (mode == EmbreeMode::kSingle) {
      for (size_t i = 0; i < count; ++i) {
        if (shadow) {
          RTCRay r = rays[first + i];
          rtcOccluded1(m.scene, &ctx, &r);
          found += r.tfar < 0.0f;
        } else {
          RTCRayHit rh;
          rh.ray = rays[first + i];
          rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
          rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
          rtcIntersect1(m.scene, &ctx, &rh);
          found += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
        }
      }
    } else if (mode == EmbreeMode::kStream) {
      if (shadow) {
        RTCRay rs[kChunk];
        std::copy(rays.begin() + long(first), rays.begin() + long(first + count), rs);
        rtcOccluded1M(m.scene, &ctx, rs, unsigned(count), sizeof(RTCRay));
        for (size_t i = 0; i < count; ++i) found += rs[i].tfar < 0.0f;
      } else {
        RTCRayHit rhs[kChunk];
        for (size_t i = 0; i < count; ++i) {
          rhs[i].ray = rays[first + i];
          rhs[i].hit.geomID = RTC_INVALID_GEOMETRY_ID;
          rhs[i].hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect1M(m.scene, &ctx, rhs, unsigned(count), sizeof(RTCRayHit));
        for (size_t i = 0; i < count; ++i) found += rhs[i].hit.geomID != RTC_INVALID_GEOMETRY_ID;
      }
    } else {
      for (size_t p = 0; p < count; p += 8) {
        const size_t lanes = std::min<size_t>(8, count - p);
        alignas(32) int valid[8];
        alignas(32) RTCRayHit8 rh;
        for (size_t l = 0; l < 8; ++l) {
          const RTCRay& r = rays[first + p + std::min(l, lanes - 1)];
          valid[l] = l < lanes ? -1 : 0;
          rh.ray.org_x[l] = r.org_x;
          rh.ray.org_y[l] = r.org_y;
          rh.ray.org_z[l] = r.org_z;
          rh.ray.tnear[l] = r.tnear;
          rh.ray.dir_x[l] = r.dir_x;
          rh.ray.dir_y[l] = r.dir_y;
          rh.ray.dir_z[l] = r.dir_z;
          rh.ray.time[l] = 0.0f;
          rh.ray.tfar[l] = r.tfar;
          rh.ray.mask[l] = 0xFFFFFFFFu;
          rh.ray.id[l] = 0;
          rh.ray.flags[l] = 0;
          rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
          rh.hit.instID[0][l] = RTC_INVALID_GEOMETRY_ID;
        }
        if (shadow) {
          rtcOccluded8(valid, m.scene, &ctx, &rh.ray);
          for (size_t l = 0; l < lanes; ++l) found += rh.ray.tfar[l] < 0.0f;
        } else {
          rtcIntersect8(valid, m.scene, &ctx, &rh);
          for (size_t l = 0; l < lanes; ++l) found += rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;
        }
      }
    }
    hits.fetch_add(found, std::memory_order_relaxed);
  });
  return hits.load();
}

}  // namespace earshot
