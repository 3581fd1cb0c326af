// The IR pipeline at the ends of its ranges: every case must give finite
// samples (no NaN/Inf) and the answer its comment states.
#include <gtest/gtest.h>

#include <cmath>

#include "earshot/core/thread_pool.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot {
namespace {

struct Scene {
  MaterialTable materials;
  std::unique_ptr<RayTracer> tracer;
};

Scene box(const Vec3d& lo, const Vec3d& hi, float absorption, float scattering, float transmission = 0.0f) {
  Scene s;
  Material m;
  m.name = "m";
  m.absorption = filledBands(absorption);
  m.scattering = filledBands(scattering);
  m.transmission = filledBands(transmission);
  auto rt = RayTracer::create(makeBox(lo, hi, s.materials.add(m)));
  EXPECT_TRUE(rt.isOk()) << rt.status().message();
  s.tracer = std::move(rt.value());
  return s;
}

OmniIrResult run(const Scene& s, const Vec3d& src, const Vec3d& lis, OmniIrSettings settings = {}) {
  ThreadPool pool(2);
  auto r = computeOmniIr(*s.tracer, s.materials, src, lis, settings, pool);
  EXPECT_TRUE(r.isOk()) << r.status().message();
  if (!r.isOk()) return {};
  for (size_t i = 0; i < r->ir.frameCount(); ++i) {
    const float v = r->ir.channels[0][i];
    if (!std::isfinite(v)) {
      ADD_FAILURE() << "sample " << i << " is " << v;
      break;
    }
  }
  return std::move(r.value());
}

double energy(const std::vector<float>& x, size_t from = 0, size_t to = SIZE_MAX) {
  double e = 0;
  const size_t end = std::min(to, x.size());
  for (size_t i = from; i < end; ++i) e += double(x[i]) * x[i];
  return e;
}

const Vec3d kSrc{2, 3.5, 1.5}, kLis{7, 3.5, 1.5};

}  // namespace

// Absorption 1 everywhere: only the direct sound survives.
TEST(PhysicsExtremes, FullAbsorptionLeavesOnlyTheDirectSound) {
  Scene s = box({0, 0, 0}, {10, 7, 3}, 1.0f, 0.5f);
  OmniIrSettings set;
  set.air.enabled = false;
  auto r = run(s, kSrc, kLis, set);
  for (const auto& p : r.early)
    for (double g : p.bandGain) EXPECT_EQ(g, 0.0);
  for (double e : r.late.totalEnergy()) EXPECT_EQ(e, 0.0);
  EXPECT_NEAR(energy(r.ir.channels[0]), 1.0 / 25.0, 1e-4);  // the direct sound's (1/r)^2 at 5 m
}

// Absorption 0: energy never decays, yet the IR stays finite and its
// automatic length bounded (the automatic cap, 30 s).
TEST(PhysicsExtremes, NoAbsorptionStaysFiniteAndBounded) {
  Scene s = box({0, 0, 0}, {10, 7, 3}, 0.0f, 0.5f);
  OmniIrSettings set;
  set.air.enabled = false;
  set.rays = 2000;
  auto r = run(s, kSrc, kLis, set);
  EXPECT_GT(r.ir.frameCount(), size_t(48000));
  EXPECT_LE(r.ir.frameCount(), size_t(48000 * 31));
  EXPECT_TRUE(std::isfinite(energy(r.ir.channels[0])));
}

// Transmission 1 (absorption 1): a wall that is not there. The direct sound
// passes through it at full level.
TEST(PhysicsExtremes, FullyTransmittingWallIsNotThere) {
  Scene s = box({-1, -1, -1}, {1, 1, 1}, 1.0f, 0.0f, 1.0f);
  OmniIrSettings set;
  set.air.enabled = false;
  auto r = run(s, {0, 0, 0}, {5, 0, 0}, set);
  EXPECT_EQ(r.direct.surfacesCrossed, 1);
  for (double g : r.direct.bandGain) EXPECT_NEAR(g, 1.0, 1e-6);
}

// A source at the listener, or 1 mm away: spreading is clamped at the
// minimum distance (0.1 m), so the peak is 1 / 0.1 = 10, finite.
TEST(PhysicsExtremes, SourceAtOrVeryNearTheListenerIsClamped) {
  Scene s = box({0, 0, 0}, {10, 7, 3}, 0.2f, 0.5f);
  for (double d : {0.0, 0.001}) {
    OmniIrSettings set;
    set.rays = 2000;
    auto r = run(s, kLis + Vec3d{d, 0, 0}, kLis, set);
    EXPECT_DOUBLE_EQ(r.direct.spreadingGain, 10.0) << d;
    double peak = 0;
    for (float v : r.ir.channels[0]) peak = std::max(peak, double(std::fabs(v)));
    EXPECT_LE(peak, 10.0 + 1e-3) << d;
  }
}

// A source on a wall (on the floor plane) and a listener outside the closed
// room: finite; outside, the opaque walls block the direct sound entirely.
TEST(PhysicsExtremes, SourceOnAWallAndListenerOutsideTheRoom) {
  Scene s = box({0, 0, 0}, {10, 7, 3}, 0.2f, 0.5f);
  OmniIrSettings set;
  set.rays = 2000;
  auto onWall = run(s, {5, 3.5, 0.0}, kLis, set);
  EXPECT_GT(energy(onWall.ir.channels[0]), 0.0);
  auto outside = run(s, kSrc, {20, 3.5, 1.5}, set);
  EXPECT_FALSE(outside.direct.audible);
  EXPECT_TRUE(outside.early.empty());
}

// Rooms of 1 cm and 1 km: finite, the direct sound at r/c in both.
TEST(PhysicsExtremes, CentimetreAndKilometreRooms) {
  for (double size : {0.01, 1000.0}) {
    Scene s = box({0, 0, 0}, {size, size, size}, 0.3f, 0.5f);
    OmniIrSettings set;
    set.rays = 2000;
    const Vec3d a{0.2 * size, 0.5 * size, 0.5 * size}, b{0.8 * size, 0.5 * size, 0.5 * size};
    auto r = run(s, a, b, set);
    EXPECT_NEAR(r.direct.delaySeconds, 0.6 * size / 343.0, 1e-12) << size;
    EXPECT_EQ(r.traceStats.raysEscaped, 0u) << size;
  }
}

// Coordinates offset by 1e5 m (float spacing there is ~8 mm): finite, and
// the decay matches the same room at the origin within 5 %.
const Vec3d kFar{1e5, 1e5, 1e5};
TEST(PhysicsExtremes, FarFromTheOriginTheSameDecay) {
  Scene near = box({0, 0, 0}, {10, 7, 3}, 0.2f, 1.0f);
  Scene far = box(kFar, kFar + Vec3d{10, 7, 3}, 0.2f, 1.0f);
  OmniIrSettings set;
  set.air.enabled = false;
  auto a = run(near, kSrc, kLis, set), b = run(far, kSrc + kFar, kLis + kFar, set);
  EXPECT_NEAR(b.tail.t60Seconds[3], a.tail.t60Seconds[3], 0.05 * a.tail.t60Seconds[3]);
}

// No ray leaks from the closed box at 1e5 m. It used to lose 126 of 16384
// rays: hit points were computed in float world coordinates, ~8 mm apart
// there, so near an edge a hit point could round to outside the neighbouring
// wall and the next segment left through it. Now RayTracer traces in a frame
// centred on the scene (RayTracer::frameOrigin) and the tracer carries ray
// origins and hit points in double world coordinates.
TEST(PhysicsExtremes, FarFromTheOriginNoLeaks) {
  Scene far = box(kFar, kFar + Vec3d{10, 7, 3}, 0.2f, 1.0f);
  auto b = run(far, kSrc + kFar, kLis + kFar);
  EXPECT_EQ(b.traceStats.raysEscaped, 0u);
}

// Degenerate, duplicate and open geometry: finite; an open mesh lets rays out.
TEST(PhysicsExtremes, DegenerateDuplicateAndOpenMeshes) {
  MaterialTable materials;
  TriangleMesh mesh = makeBox({0, 0, 0}, {10, 7, 3}, 0);
  mesh.append(makeBox({0, 0, 0}, {10, 7, 3}, 0));  // every wall twice
  mesh.positions.push_back({1, 1, 1});
  mesh.triangles.push_back({uint32_t(mesh.positions.size() - 1), uint32_t(mesh.positions.size() - 1), 0});
  mesh.materialIds.push_back(0);  // zero area
  Scene dup;
  dup.tracer = std::move(RayTracer::create(mesh).value());
  OmniIrSettings set;
  set.rays = 2000;
  auto r = run(dup, kSrc, kLis, set);
  EXPECT_EQ(r.traceStats.raysEscaped, 0u);
  TriangleMesh open = makeBox({0, 0, 0}, {10, 7, 3}, 0);
  open.triangles.resize(10);  // no ceiling
  open.materialIds.resize(10);
  Scene o;
  o.tracer = std::move(RayTracer::create(open).value());
  auto q = run(o, kSrc, kLis, set);
  EXPECT_GT(q.traceStats.raysEscaped, 0u);
}

// 1 ray, 0 bounces, 1000 bounces: finite and sensible.
TEST(PhysicsExtremes, OneRayZeroBouncesAndAThousandBounces) {
  Scene s = box({0, 0, 0}, {10, 7, 3}, 0.2f, 0.5f);
  OmniIrSettings one;
  one.rays = 1;
  run(s, kSrc, kLis, one);
  OmniIrSettings none;
  none.bounces = 0;
  auto z = run(s, kSrc, kLis, none);
  EXPECT_EQ(z.traceStats.segmentsTraced, 0u);
  OmniIrSettings many;
  many.rays = 500;
  many.bounces = 1000;
  auto m = run(s, kSrc, kLis, many);
  EXPECT_EQ(m.traceStats.raysCut, 0u);  // Russian roulette ends them first
}

// Sample rates 8 kHz and 192 kHz (the direct sound at r/c; free field, where
// nothing arrives louder), IR lengths of 1 sample and 30 s in a room.
TEST(PhysicsExtremes, SampleRatesAndLengths) {
  Scene freeField;
  freeField.tracer = std::move(RayTracer::create(TriangleMesh{}).value());
  for (double fs : {8000.0, 192000.0}) {
    OmniIrSettings set;
    set.sampleRateHz = fs;
    auto r = run(freeField, kSrc, kLis, set);
    size_t peak = 0;
    const auto& x = r.ir.channels[0];
    for (size_t i = 0; i < x.size(); ++i)
      if (std::fabs(x[i]) > std::fabs(x[peak])) peak = i;
    EXPECT_NEAR(double(peak), 5.0 / 343.0 * fs, 1.0) << fs;
  }
  Scene s = box({0, 0, 0}, {10, 7, 3}, 0.2f, 0.5f);
  OmniIrSettings one;
  one.rays = 500;
  one.lengthSeconds = 1.0 / 48000.0;
  EXPECT_EQ(run(s, kSrc, kLis, one).ir.frameCount(), 1u);
  OmniIrSettings longIr;
  longIr.rays = 500;
  longIr.lengthSeconds = 30.0;
  EXPECT_EQ(run(s, kSrc, kLis, longIr).ir.frameCount(), size_t(30 * 48000));
}

}  // namespace earshot
