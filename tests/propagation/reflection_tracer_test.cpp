#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <numeric>
#include <vector>

#include "earshot/core/math.h"
#include "earshot/core/thread_pool.h"
#include "earshot/io/input_file.h"
#include "earshot/propagation/reflection_tracer.h"
#include "earshot/scene/embree_limit.h"
#include "earshot/scene/ray_tracer.h"
#include "shoebox_fixture.h"

namespace earshot {
namespace {

using testing::Shoebox;

const Vec3d kSource{2, 3.5, 1.5}, kListener{7, 3.5, 1.5};

ReflectionSettings quietAir(uint32_t rays, uint32_t bounces, uint64_t seed) {
  ReflectionSettings s;
  s.rays = rays;
  s.bounces = bounces;
  s.seed = seed;
  s.air.enabled = false;
  s.maxTimeSeconds = 8.0;
  return s;
}

// Mean detected energy per reflection order over orders [from, to], band 0.
double meanPerOrder(const ReflectionStats& st, size_t from, size_t to) {
  double sum = 0;
  for (size_t o = from; o <= to; ++o) sum += st.detectedPerOrder[o][0];
  return sum / double(to - from + 1);
}

struct MeanAndError {
  double mean, standardError;
};
MeanAndError meanOverSeeds(const std::vector<double>& v) {
  double m = std::accumulate(v.begin(), v.end(), 0.0) / double(v.size());
  double var = 0;
  for (double x : v) var += (x - m) * (x - m);
  var /= double(v.size() - 1);
  return {m, std::sqrt(var / double(v.size()))};
}

}  // namespace

TEST(ReflectionTracer, ClosedBoxLeaksNoRays) {
  Shoebox room(0.0f, 0.5f);
  ThreadPool pool(2);
  ReflectionSettings s = quietAir(100000, 200, 7);
  s.maxTimeSeconds = 0.5;  // detections are irrelevant here; keep the histogram small
  auto r = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(r->stats.raysTraced, 100000u);
  EXPECT_EQ(r->stats.raysEscaped, 0u);
  // Every ray ran all its bounces (+1 final segment) since nothing absorbs;
  // the tail probes carried on to the histogram's end.
  EXPECT_EQ(r->stats.segmentsTraced - r->stats.tailProbeSegments, 100000u * 201u);
  EXPECT_GT(r->stats.tailProbeSegments, 0u);
  for (double e : r->stats.energyEscaped) EXPECT_EQ(e, 0.0);
}

TEST(ReflectionTracer, OpenSceneLetsRaysEscapeAndCountsTheirEnergy) {
  MaterialTable materials;
  TriangleMesh floor;
  floor.positions = {{-50, 0, -50}, {50, 0, -50}, {50, 0, 50}, {-50, 0, 50}};
  floor.triangles = {{0, 1, 2}, {0, 2, 3}};
  floor.materialIds = {0, 0};
  auto rt = RayTracer::create(floor);
  ASSERT_TRUE(rt.isOk());
  ThreadPool pool(2);
  auto r = traceReflections(**rt, materials, {0, 1.5, 0}, {3, 1.5, 0}, quietAir(4096, 12, 1), pool);
  ASSERT_TRUE(r.isOk());
  // Upward rays (about half) escape at once; downward ones after one bounce.
  EXPECT_EQ(r->stats.raysEscaped, 4096u);
  // Escaped energy = 1 - absorbed: half never hits, the other half loses alpha.
  const double alpha = materials[0].absorption[0];
  EXPECT_NEAR(r->stats.energyEscaped[0], 0.5 + 0.5 * (1.0 - alpha), 0.01);
}

// Energy conservation with zero absorption and no air. A lossless closed room
// holds the emitted energy 4 pi forever; once it has spread out (uniform in
// space, isotropic: a distribution that diffuse and specular reflection both
// leave unchanged), the energy crossing the listener per unit time is the
// energy density 4 pi / V times c. Both estimators target exactly this:
// next-event estimation (diffuse paths) and the receiver sphere (specular
// paths), so the late energy per second is 4 pi c / V whatever the scattering.
// (Per reflection order it is not: in a specular box the mean segment length
// depends on the ray's direction, so orders are not equally long.)
// Window 0.1-0.3 s: late enough to be spread out, early enough that no ray has
// used up its 60 bounces (at most ~40 by 0.3 s in this room).
TEST(ReflectionTracer, LateEnergyRateMatchesTheoryWithoutAbsorptionAndDoesNotDependOnScattering) {
  const double theory = 4.0 * kPi * 343.0 / Shoebox::kVolume;  // energy per second
  ThreadPool pool(2);
  std::vector<MeanAndError> results;
  for (float scattering : {1.0f, 0.5f, 0.0f}) {
    Shoebox room(0.0f, scattering);
    std::vector<double> perSeed;
    for (uint64_t seed = 1; seed <= 8; ++seed) {
      ReflectionSettings s = quietAir(4096, 60, seed);
      s.maxTimeSeconds = 0.4;
      auto r = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
      ASSERT_TRUE(r.isOk());
      ASSERT_EQ(r->stats.raysEscaped, 0u);
      const auto& h = r->histogram;
      const size_t from = size_t(0.1 / h.binSeconds()), to = size_t(0.3 / h.binSeconds());
      double e = 0;
      for (size_t i = from; i < to; ++i) e += h.energy(i, 0);
      perSeed.push_back(e / (double(to - from) * h.binSeconds()));
    }
    MeanAndError m = meanOverSeeds(perSeed);
    // The test must be able to fail: the statistical error is small.
    EXPECT_LT(m.standardError, 0.03 * theory) << "scattering " << scattering;
    EXPECT_NEAR(m.mean, theory, 4.0 * m.standardError) << "scattering " << scattering;
    results.push_back(m);
  }
  for (size_t i = 1; i < results.size(); ++i) {
    const double sigma = std::hypot(results[0].standardError, results[i].standardError);
    EXPECT_NEAR(results[i].mean, results[0].mean, 4.0 * sigma) << "scattering case " << i;
  }
}

// Per reflection order, the diffuse (scattering 1) estimate tends to
// (4 pi / N) * N * E[cos / (pi d^2)] = 4 pi * 4 pi / (pi S) = 16 pi / S:
// hit points are uniform over the surface S and the integral of cos / d^2
// over a closed surface seen from inside is 4 pi.
TEST(ReflectionTracer, DiffuseEnergyPerOrderIsSixteenPiOverSurface) {
  const double theory = 16.0 * kPi / Shoebox::kSurface;
  ThreadPool pool(2);
  Shoebox room(0.0f, 1.0f);
  std::vector<double> perSeed;
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    auto r = traceReflections(*room.tracer, room.materials, kSource, kListener, quietAir(4096, 60, seed), pool);
    ASSERT_TRUE(r.isOk());
    perSeed.push_back(meanPerOrder(r->stats, 15, 60));  // from order 15 on, hits are spread out
  }
  MeanAndError m = meanOverSeeds(perSeed);
  EXPECT_LT(m.standardError, 0.02 * theory);
  EXPECT_NEAR(m.mean, theory, 4.0 * m.standardError);
}

TEST(ReflectionTracer, HistogramIsBitIdenticalForAnyThreadCount) {
  Shoebox room(0.2f, 0.3f);
  ReflectionSettings s;
  s.rays = 3000;  // not a multiple of the task size on purpose
  s.bounces = 20;
  s.seed = 99;
  ThreadPool one(1), two(2), three(3);
  auto a = traceReflections(*room.tracer, room.materials, kSource, kListener, s, one);
  auto b = traceReflections(*room.tracer, room.materials, kSource, kListener, s, two);
  auto c = traceReflections(*room.tracer, room.materials, kSource, kListener, s, three);
  ASSERT_TRUE(a.isOk() && b.isOk() && c.isOk());
  EXPECT_GT(a->histogram.totalEnergy()[0], 0.0);
  EXPECT_TRUE(a->histogram.data() == b->histogram.data());
  EXPECT_TRUE(a->histogram.data() == c->histogram.data());
  // A different seed gives a different histogram.
  s.seed = 100;
  auto d = traceReflections(*room.tracer, room.materials, kSource, kListener, s, two);
  EXPECT_FALSE(a->histogram.data() == d->histogram.data());
}

// T30 from an energy histogram: Schroeder backward integration, least-squares
// line through the decay between -5 and -35 dB.
double t30FromHistogram(const EnergyHistogram& h, int band) {
  std::vector<double> edc(h.binCount() + 1, 0.0);
  for (size_t i = h.binCount(); i-- > 0;) edc[i] = edc[i + 1] + h.energy(i, band);
  std::vector<double> x, y;
  for (size_t i = 0; i < h.binCount(); ++i) {
    double db = 10 * std::log10(edc[i] / edc[0]);
    if (db <= -5 && db >= -35) {
      x.push_back(double(i) * h.binSeconds());
      y.push_back(db);
    }
  }
  double mx = std::accumulate(x.begin(), x.end(), 0.0) / double(x.size());
  double my = std::accumulate(y.begin(), y.end(), 0.0) / double(y.size());
  double sxy = 0, sxx = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
  }
  return -60.0 / (sxy / sxx);
}

// Fully diffusing shoebox, uniform absorption 0.2, with air: the decay follows
// Eyring's formula T = 0.161 V / (-S ln(1 - alpha) + 4 m V) (Kuttruff, Room
// Acoustics, eq. 5.24, with m the energy attenuation of air per metre).
TEST(ReflectionTracer, FullyScatteringShoeboxDecaysAsEyringPredicts) {
  Shoebox room(0.2f, 1.0f);
  ThreadPool pool(2);
  ReflectionSettings s;
  s.rays = 16384;
  s.bounces = 120;  // 0.8^120 = -116 dB: the whole decay, no tail completion needed
  s.seed = 3;
  s.maxTimeSeconds = 2.5;
  auto r = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
  ASSERT_TRUE(r.isOk());
  const BandArrayD m = airEnergyAttenuationPerMeter(s.air);
  for (int b = 0; b < kNumBands; ++b) {
    const double eyring = 0.161 * Shoebox::kVolume /
                          (-Shoebox::kSurface * std::log(1.0 - 0.2) + 4.0 * m[b] * Shoebox::kVolume);
    const double t30 = t30FromHistogram(r->histogram, b);
    EXPECT_NEAR(t30, eyring, 0.10 * eyring) << kBandCentersHz[b] << " Hz";
  }
}

TEST(ReflectionTracer, NoGeometryOrNoBouncesTracesNothing) {
  MaterialTable materials;
  auto rt = RayTracer::create(TriangleMesh{});
  ASSERT_TRUE(rt.isOk());
  ThreadPool pool(1);
  auto r = traceReflections(**rt, materials, kSource, kListener, ReflectionSettings{}, pool);
  ASSERT_TRUE(r.isOk());
  EXPECT_EQ(r->stats.segmentsTraced, 0u);
  EXPECT_EQ(r->histogram.lastNonEmptyBin(), -1);
}

TEST(ReflectionTracer, BadSettingsAreErrorsNamingTheField) {
  Shoebox room(0.2f, 0.5f);
  ThreadPool pool(1);
  ReflectionSettings s;
  s.binSeconds = std::nan("");
  auto r = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
  ASSERT_FALSE(r.isOk());
  EXPECT_NE(r.status().message().find("histogram bin"), std::string::npos);
  auto q = traceReflections(*room.tracer, room.materials, {std::nan(""), 0, 0}, kListener, ReflectionSettings{}, pool);
  ASSERT_FALSE(q.isOk());
  EXPECT_NE(q.status().message().find("not finite"), std::string::npos);
}

// A ray count or histogram whose trace would hold more than the memory
// limit is refused before anything is allocated (with the check gone, the
// first trace below would allocate ~12 GiB): the default 1 GiB, and a
// lower limit set the way --max-memory sets it. Under the limit the same
// trace runs. The estimate covers the trace's per-ray slots and each
// thread's per-bin sums, and grows with every term.
TEST(ReflectionTracer, ATraceOverTheMemoryLimitIsRefusedBeforeItAllocates) {
  Shoebox room(0.2f, 0.5f);
  ThreadPool pool(2);
  ReflectionSettings many;
  many.rays = 100000000;
  auto r = traceReflections(*room.tracer, room.materials, kSource, kListener, many, pool);
  ASSERT_FALSE(r.isOk());
  EXPECT_EQ(r.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(r.status().message().find("100000000 rays"), std::string::npos) << r.status().message();
  EXPECT_NE(r.status().message().find("--max-memory"), std::string::npos) << r.status().message();
  ReflectionSettings fine;  // 1e7 bins: within validate()'s 5e7
  fine.binSeconds = 1e-5;
  fine.maxTimeSeconds = 100;
  auto f = traceReflections(*room.tracer, room.materials, kSource, kListener, fine, pool);
  ASSERT_FALSE(f.isOk());
  EXPECT_NE(f.status().message().find("10000000 histogram bins"), std::string::npos) << f.status().message();

  // Under a limit of 8 MiB: one detector of a balanced trace fits, eight
  // sharing it do not, a trace of 200k rays does not.
  struct Restore {
    InputLimits saved = defaultInputLimits();
    ~Restore() { setDefaultInputLimits(saved); }
  } restore;
  InputLimits low = restore.saved;
  low.maxMemoryBytes = uint64_t(8) << 20;
  setDefaultInputLimits(low);
  ReflectionSettings balanced;
  balanced.bounces = 2;
  EXPECT_LT(traceMemoryBytes(balanced, 1, 2), double(low.maxMemoryBytes));
  auto one = traceReflections(*room.tracer, room.materials, kSource, kListener, balanced, pool);
  ASSERT_TRUE(one.isOk()) << one.status().message();
  EXPECT_GT(one->stats.segmentsTraced, 0u);
  std::vector<SharedTraceSource> eight(8);
  for (size_t i = 0; i < eight.size(); ++i) eight[i].position = {1.0 + double(i), 2.0, 1.5};
  auto shared = traceReflectionsShared(*room.tracer, room.materials, kListener, eight, balanced, pool);
  ASSERT_FALSE(shared.isOk());
  EXPECT_NE(shared.status().message().find("for 8 sources"), std::string::npos) << shared.status().message();
  auto sharedOne = traceReflectionsShared(*room.tracer, room.materials, kListener, {eight[0]}, balanced, pool);
  EXPECT_TRUE(sharedOne.isOk()) << sharedOne.status().message();
  ReflectionSettings more = balanced;
  more.rays = 200000;
  auto m = traceReflections(*room.tracer, room.materials, kSource, kListener, more, pool);
  ASSERT_FALSE(m.isOk());
  EXPECT_NE(m.status().message().find("8.0 MiB"), std::string::npos) << m.status().message();

  // What the estimate must cover: two CutRay slots per ray, each thread's
  // and the merged histogram and probe sums per bin; more of anything costs more.
  const double bins = std::ceil(balanced.maxTimeSeconds / balanced.binSeconds);
  EXPECT_GE(traceMemoryBytes(more, 1, 1), double(more.rays) * 2.0 * double(sizeof(CutRay)));
  EXPECT_GE(traceMemoryBytes(balanced, 3, 2),
            bins * 3.0 * 3.0 * double(EnergyHistogram::kStride + kNumBands) * double(sizeof(int64_t)));
  EXPECT_GT(traceMemoryBytes(more, 1, 2), traceMemoryBytes(balanced, 1, 2));
  EXPECT_GT(traceMemoryBytes(balanced, 2, 2), traceMemoryBytes(balanced, 1, 2));
  EXPECT_GT(traceMemoryBytes(balanced, 1, 4), traceMemoryBytes(balanced, 1, 2));
  EXPECT_GT(traceMemoryBytes(fine, 1, 2), traceMemoryBytes(balanced, 1, 2));
}

}  // namespace earshot

namespace earshot {

// The statistical error of the energy histogram falls as 1/sqrt(rays): the
// relative RMS difference of two independent traces (different seeds), in
// 10 ms bins over the first 0.2 s at 1 kHz, fitted over 1k..64k rays on a
// log-log scale, has a slope in [-0.6, -0.4]. With a fixed receiver: the
// automatic one is sized from the ray density (larger for fewer rays).
TEST(ReflectionTracer, HistogramErrorFallsAsOneOverSqrtRays) {
  testing::Shoebox room(0.2f, 0.3f);
  ThreadPool pool(2);
  auto coarse = [](const EnergyHistogram& h) {
    std::vector<double> e(20, 0.0);
    for (size_t i = 0; i < 200 && i < h.binCount(); ++i) e[i / 10] += h.energy(i, 3);
    return e;
  };
  std::vector<double> logRays, logError;
  for (uint32_t rays : {1024u, 4096u, 16384u, 65536u}) {
    double sumSq = 0;
    int pairs = 0;
    for (uint64_t pair = 0; pair < 3; ++pair) {
      ReflectionSettings s;
      s.rays = rays;
      s.receiverRadiusMeters = 0.5;
      s.seed = 100 + 2 * pair;
      auto a = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
      s.seed += 1;
      auto b = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
      ASSERT_TRUE(a.isOk() && b.isOk());
      const auto ea = coarse(a->histogram), eb = coarse(b->histogram);
      double num = 0, den = 0;
      for (size_t i = 1; i < ea.size(); ++i) {  // from 10 ms: after the direct sound
        num += (ea[i] - eb[i]) * (ea[i] - eb[i]);
        den += 0.5 * (ea[i] + eb[i]) * 0.5 * (ea[i] + eb[i]);
      }
      sumSq += num / den;
      ++pairs;
    }
    logRays.push_back(std::log(double(rays)));
    logError.push_back(0.5 * std::log(sumSq / pairs));
  }
  double mx = 0, my = 0;
  for (size_t i = 0; i < logRays.size(); ++i) mx += logRays[i], my += logError[i];
  mx /= double(logRays.size()), my /= double(logRays.size());
  double sxy = 0, sxx = 0;
  for (size_t i = 0; i < logRays.size(); ++i) {
    sxy += (logRays[i] - mx) * (logError[i] - my);
    sxx += (logRays[i] - mx) * (logRays[i] - mx);
  }
  const double slope = sxy / sxx;
  std::printf("histogram error vs rays: slope %.3f (errors %.4f %.4f %.4f %.4f)\n", slope, std::exp(logError[0]),
              std::exp(logError[1]), std::exp(logError[2]), std::exp(logError[3]));
  EXPECT_GE(slope, -0.6);
  EXPECT_LE(slope, -0.4);
}

// Model only what the scene requires: in a convex room nothing can block a
// diffuse reflection's path to the listener, so no occlusion test is made.
// A triangle outside the room (parallel to a wall, 10 m beyond it) makes the
// mesh non-convex without blocking anything: there every shadow ray is cast,
// and the detected energy is the same.
TEST(ReflectionTracer, ConvexRoomNeedsNoShadowRaysAndLosesNothing) {
  Shoebox room(0.2f, 0.5f);
  TriangleMesh mesh = room.tracer->mesh();
  const uint32_t base = uint32_t(mesh.positions.size());
  mesh.positions.push_back({20, 1, 1});
  mesh.positions.push_back({20, 2, 1});
  mesh.positions.push_back({20, 1, 2});
  mesh.triangles.push_back({base, base + 1, base + 2});
  mesh.materialIds.push_back(0);
  auto outside = RayTracer::create(mesh);
  ASSERT_TRUE(outside.isOk());
  EXPECT_TRUE(room.tracer->convexAround(kListener));
  EXPECT_FALSE((*outside)->convexAround(kListener));
  EXPECT_FALSE(room.tracer->convexAround({11, 3.5, 1.5}));  // outside the room
  ThreadPool pool(2);
  const ReflectionSettings s = quietAir(4000, 12, 3);
  auto convex = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
  auto tested = traceReflections(**outside, room.materials, kSource, kListener, s, pool);
  ASSERT_TRUE(convex.isOk() && tested.isOk());
  EXPECT_EQ(convex->stats.shadowRays, 0u);
  EXPECT_GT(convex->stats.shadowRaysSkipped, 0u);
  EXPECT_EQ(tested->stats.shadowRays, convex->stats.shadowRaysSkipped);
  EXPECT_EQ(tested->stats.shadowRaysSkipped, 0u);
  // The extra triangle moves the tracer's frame (the centre of its bounds),
  // so hit points round differently and a few paths near edges part ways:
  // the energies agree to 1e-4 here, not to the bit. (The bound catches a
  // skip that changes what is deposited, not one stray shadow ray.)
  for (int b = 0; b < kNumBands; ++b) {
    double e1 = 0, e2 = 0;
    for (size_t i = 0; i < convex->histogram.binCount(); ++i)
      e1 += convex->histogram.energy(i, b), e2 += tested->histogram.energy(i, b);
    EXPECT_NEAR(e1, e2, 1e-3 * e2) << "band " << b;
  }
}

// Stopping when converged. A loose target stops early (after 4 to 15 of 16
// rounds) with the energy of the full trace within its stated error; a
// target no trace reaches traces every ray and changes nothing (rounds only
// reorder the rays; the sums are exact); and the stop is the same for any
// thread count.
TEST(ReflectionTracer, StopsWhenTheHistogramHasConverged) {
  Shoebox room(0.2f, 0.5f);
  ReflectionSettings s = quietAir(16384, 12, 5);
  s.maxTimeSeconds = 1.0;
  ThreadPool two(2), one(1);
  auto all = traceReflections(*room.tracer, room.materials, kSource, kListener, s, two);
  ASSERT_TRUE(all.isOk());
  EXPECT_EQ(all->stats.raysTraced, 16384u);

  s.convergenceDb = 1e-6;  // unreachable: every round runs
  auto strict = traceReflections(*room.tracer, room.materials, kSource, kListener, s, two);
  ASSERT_TRUE(strict.isOk());
  EXPECT_EQ(strict->stats.raysTraced, 16384u);
  EXPECT_GT(strict->stats.estimatedErrorDb, 1e-6);
  EXPECT_EQ(strict->histogram.data(), all->histogram.data());
  EXPECT_EQ(strict->tail.rays().alive, all->tail.rays().alive);

  s.convergenceDb = 2.0;
  auto loose = traceReflections(*room.tracer, room.materials, kSource, kListener, s, two);
  auto loose1 = traceReflections(*room.tracer, room.materials, kSource, kListener, s, one);
  ASSERT_TRUE(loose.isOk() && loose1.isOk());
  EXPECT_LT(loose->stats.raysTraced, 16384u);
  EXPECT_GE(loose->stats.raysTraced, 4096u);
  EXPECT_LE(loose->stats.estimatedErrorDb, 2.0);
  EXPECT_EQ(loose1->stats.raysTraced, loose->stats.raysTraced);
  EXPECT_EQ(loose1->histogram.data(), loose->histogram.data());
  // Energy per 10 ms window over the first 100 ms (well within 30 dB of the
  // peak): within 3 stated standard errors of the full trace's.
  const double rel = std::pow(10.0, loose->stats.estimatedErrorDb / 10.0) - 1.0;
  for (int b = 0; b < kNumBands; b += 3)
    for (size_t w = 0; w < 10; ++w) {
      double e1 = 0, e2 = 0;
      for (size_t i = w * 10; i < w * 10 + 10; ++i) e1 += loose->histogram.energy(i, b), e2 += all->histogram.energy(i, b);
      if (e2 == 0) continue;
      EXPECT_NEAR(e1, e2, 3.0 * rel * e2 + 1e-12) << "band " << b << " window " << w;
    }
}

TEST(ReflectionTracer, RejectsAConvergenceTargetOutOfRange) {
  Shoebox room(0.2f, 0.5f);
  ThreadPool pool(1);
  ReflectionSettings s = quietAir(100, 4, 1);
  for (double bad : {-1.0, 21.0, std::nan("")}) {
    s.convergenceDb = bad;
    auto r = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
    ASSERT_FALSE(r.isOk());
    EXPECT_NE(r.status().message().find("convergence target"), std::string::npos) << r.status().message();
  }
}


namespace {
// The reference shoebox with reflective end walls (x = 0 and x = 10, alpha
// 0.02) and four walls absorbing 60 % (a round trip between two of them
// keeps 0.16 specularly): a flutter echo along x, and only there.
struct FlutterBox {
  MaterialTable materials;
  std::unique_ptr<RayTracer> tracer;
  explicit FlutterBox(float endScattering = 0.0f, float endAbsorption = 0.02f) {
    Material end, side;
    end.name = "end";
    end.absorption = filledBands(endAbsorption);
    end.scattering = filledBands(endScattering);
    end.transmission = filledBands(0.0f);
    side = end;
    side.name = "side";
    side.absorption = filledBands(0.6f);
    side.scattering = filledBands(0.0f);
    const uint32_t e = materials.add(end), s = materials.add(side);
    auto rt = RayTracer::create(makeBox({0, 0, 0}, {10, 7, 3}, {e, e, s, s, s, s}));
    EXPECT_TRUE(rt.isOk());
    tracer = std::move(rt.value());
  }
};

double energyBetween(const EnergyHistogram& h, double from, double to) {
  double e = 0;
  for (size_t i = size_t(from / h.binSeconds()); i < size_t(to / h.binSeconds()) && i < h.binCount(); ++i)
    e += h.energy(i, 0);
  return e;
}
}  // namespace

// Flutter cones (ReflectionSettings::flutterCones) are importance sampling:
// the late energy of a flutter echo keeps its mean over seeds and loses
// most of its spread. Full traces (no tail completion), source and listener
// off the axis and the room's mid-planes.
TEST(ReflectionTracer, FlutterConesSampleTheEchoDenselyAndKeepItsMean) {
  FlutterBox room;
  ThreadPool pool(2);
  const Vec3d src{2.3, 3.1, 1.2}, lis{6.6, 4.2, 1.7};
  for (auto [from, to] : {std::pair{0.1, 0.3}, std::pair{0.3, 0.6}, std::pair{0.6, 1.2}}) {
    std::vector<double> with, without;
    for (uint64_t seed = 1; seed <= 8; ++seed)
      for (bool cones : {true, false}) {
        ReflectionSettings s = quietAir(4096, 120, seed);
        s.tailProbes = 0;
        s.flutterCones = cones;
        auto r = traceReflections(*room.tracer, room.materials, src, lis, s, pool);
        ASSERT_TRUE(r.isOk()) << r.status().message();
        EXPECT_EQ(r->stats.flutterAxes, cones ? 1u : 0u);
        EXPECT_EQ(r->stats.coneRays, cones ? 512u : 0u);
        (cones ? with : without).push_back(energyBetween(r->histogram, from, to));
      }
    const MeanAndError a = meanOverSeeds(with), b = meanOverSeeds(without);
    const double sdA = a.standardError * std::sqrt(8.0), sdB = b.standardError * std::sqrt(8.0);
    std::printf("%.1f-%.1f s: cones %.4g +- %.2g (sd), uniform %.4g +- %.2g\n", from, to, a.mean, sdA, b.mean, sdB);
    EXPECT_NEAR(a.mean, b.mean, 3.0 * std::hypot(a.standardError, b.standardError)) << from << "-" << to << " s";
    // Measured sd ratios 0.40, 0.08, 0.08.
    EXPECT_LT(sdA, (from < 0.2 ? 0.7 : 0.3) * sdB) << from << "-" << to << " s";
  }
}

// Cones only where a pair of parallel walls reflects specularly, and only
// for a whole trace of at least 1024 rays.
TEST(ReflectionTracer, FlutterConesOnlyWhereParallelWallsReflectSpecularly) {
  ThreadPool pool(2);
  auto axesOf = [&](const RayTracer& tracer, const MaterialTable& materials, ReflectionSettings s) {
    s.bounces = 4;
    auto r = traceReflections(tracer, materials, kSource, kListener, s, pool);
    EXPECT_TRUE(r.isOk());
    return std::pair{r->stats.flutterAxes, r->stats.coneRays};
  };
  ReflectionSettings s = quietAir(2048, 4, 1);
  FlutterBox flutter;
  EXPECT_EQ(axesOf(*flutter.tracer, flutter.materials, s), std::pair(1u, 256u));
  FlutterBox scattering(0.9f);  // end walls that scatter: no specular flutter
  EXPECT_EQ(axesOf(*scattering.tracer, scattering.materials, s), std::pair(0u, 0u));
  FlutterBox absorbing(0.0f, 0.6f);  // end walls like the sides: a round trip keeps 0.16 < 0.25
  EXPECT_EQ(axesOf(*absorbing.tracer, absorbing.materials, s), std::pair(0u, 0u));
  // A uniform specular box: the longest axis decays slowest (10 m apart
  // against 7 and 3), and no other is within 1.25x of its rate.
  Shoebox uniform(0.3f, 0.0f);
  EXPECT_EQ(axesOf(*uniform.tracer, uniform.materials, s), std::pair(1u, 256u));
  ReflectionSettings converging = s;
  converging.convergenceDb = 3.0;  // rounds must each cover the sphere alike
  EXPECT_EQ(axesOf(*flutter.tracer, flutter.materials, converging), std::pair(0u, 0u));
  ReflectionSettings few = s;
  few.rays = 1000;
  EXPECT_EQ(axesOf(*flutter.tracer, flutter.materials, few), std::pair(0u, 0u));
  ReflectionSettings off = s;
  off.flutterCones = false;
  EXPECT_EQ(axesOf(*flutter.tracer, flutter.materials, off), std::pair(0u, 0u));
}

}  // namespace earshot

namespace earshot {
namespace {

// The Embree limit's replay (issue 16, `earshot bench trace`): a trace's
// queries are all recorded, nearest-hit and shadow apart, and every plain
// Embree mode finds the same hits for them. Box with an inner wall so that
// next-event estimation needs shadow rays.
TEST(EmbreeLimit, RecordedQueriesReplayAlikeInEveryMode) {
  MaterialTable materials;
  Material m;
  m.name = "wall";
  m.absorption = filledBands(0.2f);
  m.scattering = filledBands(0.5f);
  m.transmission = filledBands(0.0f);
  const uint32_t id = materials.add(m);
  TriangleMesh mesh = makeBox({0, 0, 0}, {10, 7, 3}, id);
  // A free-standing panel between source and listener.
  const uint32_t base = uint32_t(mesh.positions.size());
  for (Vec3f p : {Vec3f{5, 1, 0.5f}, Vec3f{5, 6, 0.5f}, Vec3f{5, 6, 2.5f}, Vec3f{5, 1, 2.5f}}) mesh.positions.push_back(p);
  mesh.triangles.push_back({base, base + 1, base + 2});
  mesh.triangles.push_back({base, base + 2, base + 3});
  mesh.materialIds.push_back(id);
  mesh.materialIds.push_back(id);
  auto rt = RayTracer::create(mesh);
  ASSERT_TRUE(rt.isOk()) << rt.status().message();
  ReflectionSettings s;
  s.rays = 2000;
  s.bounces = 8;
  ThreadPool pool(2);
  QueryLog log;
  ReflectionResult r;
  {
    QueryRecording recording(**rt, log);
    auto traced = traceReflections(**rt, materials, {2, 3.5, 1.5}, {8, 3.5, 1.5}, s, pool);
    ASSERT_TRUE(traced.isOk());
    r = std::move(traced.value());
  }
  // Recording stopped with the recording's scope.
  Hit h;
  (*rt)->intersect(Ray{{2, 3.5, 1.5}, 0.0f, {1, 0, 0}, 1e30f}, h);
  ASSERT_EQ(log.rays.size(), log.shadow.size());
  EXPECT_EQ(log.shadowCount(), r.stats.shadowRays);
  ASSERT_GT(r.stats.shadowRays, 0u);
  // Besides the segments: the receiver sizing's 64 probes and near-edge offset checks.
  EXPECT_GE(log.rays.size() - log.shadowCount(), r.stats.segmentsTraced);
  EXPECT_LE(log.rays.size() - log.shadowCount(), r.stats.segmentsTraced + 64 + r.stats.segmentsTraced / 50);
  const EmbreeReplay replay(**rt, log);
  EXPECT_EQ(replay.intersectCount() + replay.shadowCount(), log.rays.size());
  const size_t single = replay.run(EmbreeMode::kSingle, pool);
  EXPECT_GT(single, replay.intersectCount() / 2);
  EXPECT_EQ(replay.run(EmbreeMode::kStream, pool), single);
  EXPECT_EQ(replay.run(EmbreeMode::kPacket8, pool), single);
}

}  // namespace
}  // namespace earshot
