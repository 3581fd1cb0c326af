#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "earshot/core/thread_pool.h"
#include "earshot/propagation/tail_completion.h"
#include "earshot/scene/ray_tracer.h"
#include "shoebox_fixture.h"

namespace earshot {
namespace {

using Room = testing::Shoebox;

// Schroeder decay: time (s) at which the EDC falls to `db` below its start.
double edcCrossing(const EnergyHistogram& h, int band, double db) {
  std::vector<double> edc(h.binCount() + 1, 0.0);
  for (size_t i = h.binCount(); i-- > 0;) edc[i] = edc[i + 1] + h.energy(i, band);
  for (size_t i = 0; i < h.binCount(); ++i)
    if (10 * std::log10(edc[i] / edc[0]) <= db) return double(i) * h.binSeconds();
  return NAN;
}

// T30 by least squares over -5..-35 dB of the Schroeder decay.
double t30(const EnergyHistogram& h, int band) {
  std::vector<double> edc(h.binCount() + 1, 0.0);
  for (size_t i = h.binCount(); i-- > 0;) edc[i] = edc[i + 1] + h.energy(i, band);
  double sx = 0, sy = 0, sxx = 0, sxy = 0, n = 0;
  for (size_t i = 0; i < h.binCount(); ++i) {
    double db = 10 * std::log10(edc[i] / edc[0]);
    if (db > -5 || db < -35) continue;
    double x = double(i) * h.binSeconds();
    sx += x, sy += db, sxx += x * x, sxy += x * db, n += 1;
  }
  return -60.0 / ((n * sxy - sx * sy) / (n * sxx - sx * sx));
}

const Vec3d kSource{2, 3.5, 1.5}, kListener{7, 3.5, 1.5};

}  // namespace

// The default budget (16384 rays x 12 bounces) plus completion gives the
// decay of a trace that covers it all (150 bounces): T30 within 5 % (1 JND)
// and the -20 dB point of the EDC within 5 %; with tail probes (the default)
// and with the population's rate alone.
TEST(TailCompletion, TwelveBouncesPlusCompletionMatchAFullTrace) {
  for (uint32_t probes : {4096u, 0u})
  for (float alpha : {0.1f, 0.3f}) {
    SCOPED_TRACE("probes " + std::to_string(probes));
    Room room(alpha, 1.0f);
    ThreadPool pool(2);
    ReflectionSettings s;
    s.maxTimeSeconds = 4.0;
    s.bounces = 150;
    s.tailProbes = 0;
    auto full = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
    s.bounces = 12;
    s.tailProbes = probes;
    auto cut = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
    ASSERT_TRUE(full.isOk() && cut.isOk());
    EXPECT_GT(cut->stats.raysCut, 0u);
    TailInfo info;
    auto completed = completeTail(cut->histogram, cut->tail, TailCompletionSettings{}, &info);
    ASSERT_TRUE(completed.isOk()) << completed.status().message();
    EXPECT_TRUE(info.extended);
    for (int b = 0; b < kNumBands; ++b) {
      const double want = t30(full->histogram, b), got = t30(*completed, b);
      EXPECT_NEAR(got, want, 0.05 * want) << "alpha " << alpha << " band " << b;
      const double want20 = edcCrossing(full->histogram, b, -20), got20 = edcCrossing(*completed, b, -20);
      EXPECT_NEAR(got20, want20, 0.05 * want20) << "alpha " << alpha << " band " << b;
      // Without completion the 12-bounce trace is badly truncated (the test can fail).
      if (alpha < 0.2f) {
        EXPECT_LT(t30(cut->histogram, b), 0.8 * want) << "band " << b;
      }
    }
    // The automatic length reaches 60 dB down the Schroeder decay: for an
    // exponential tail at least T60 minus the time to the tail's start.
    EXPECT_GT(info.lengthSeconds, 0.9 * info.t60Seconds[0]);
    EXPECT_LT(info.lengthSeconds, 1.2 * info.t60Seconds[0] + info.startSeconds[0]);
  }
}

namespace {
// The same 2000 rays without roulette, traced twice: to 12 bounces with
// every ray a tail probe, and to the probes' own limit with no probes.
std::pair<Result<ReflectionResult>, Result<ReflectionResult>> traceProbedAndLong(const Room& room,
                                                                                 ReflectionSettings s) {
  ThreadPool pool(2);
  s.rays = 2000;
  s.russianRoulette = false;
  s.tailProbes = s.rays;
  auto probed = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
  s.bounces = 12 + kMaxProbeBounces;
  s.tailProbes = 0;
  return {std::move(probed), traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool)};
}
}  // namespace

// A tail probe is the ray it was, carried on: with every ray a probe (and no
// roulette, which would end probes 60 dB down), the traced energy in flight
// plus the probes' equals, bin by bin, the energy in flight of a trace whose
// bounce limit is the probes' (same paths, same random numbers; detections
// do not draw any).
TEST(TailCompletion, ProbesCarryTheirRaysOnExactly) {
  Room room(0.2f, 0.5f);  // scattering draws random numbers: the streams must agree
  ReflectionSettings s;
  s.maxTimeSeconds = 2.0;
  auto [probed, full] = traceProbedAndLong(room, s);
  ASSERT_TRUE(probed.isOk() && full.isOk());
  EXPECT_LE(probed->stats.segmentsTraced, full->stats.segmentsTraced);  // probes stop at the histogram's end
  EXPECT_GT(probed->stats.tailProbeSegments, probed->stats.segmentsTraced / 2);
  const RayTail &p = probed->tail.rays(), &f = full->tail.rays();
  ASSERT_EQ(p.probeAlive.size(), f.alive.size());
  double peak = 0;
  for (const auto& a : f.alive) peak = std::max(peak, a[0]);
  for (size_t i = 0; i < f.alive.size(); ++i)
    for (int b = 0; b < kNumBands; ++b)
      ASSERT_NEAR(p.alive[i][b] + p.probeAlive[i][b], f.alive[i][b], 1e-12 * peak) << "bin " << i << " band " << b;
}

// What probes deposit past their cut is what the same rays would have
// deposited in a longer trace, bin for bin (a specular room: there a long
// trace detects every segment by the sphere too; a fixed sphere, as the
// automatic one depends on the bounces).
TEST(TailCompletion, ProbesDepositWhatALongerTraceDetects) {
  Room room(0.2f, 0.0f);
  ReflectionSettings s;
  s.maxTimeSeconds = 1.0;
  s.receiverRadiusMeters = 0.8;
  auto [probed, full] = traceProbedAndLong(room, s);
  ASSERT_TRUE(probed.isOk() && full.isOk());
  ASSERT_EQ(probed->tail.probeDetected.size(), full->histogram.binCount());
  double peak = 0, late = 0;
  for (size_t i = 0; i < full->histogram.binCount(); ++i) {
    peak = std::max(peak, full->histogram.energy(i, 0));
    late += probed->tail.probeDetected[i][0];
  }
  EXPECT_GT(late, 0.0);
  for (size_t i = 0; i < full->histogram.binCount(); ++i)
    for (int b = 0; b < kNumBands; ++b)
      ASSERT_NEAR(probed->histogram.energy(i, b) + probed->tail.probeDetected[i][b], full->histogram.energy(i, b),
                  1e-12 * peak)
          << "bin " << i << " band " << b;
}

// A specular box decays as a mixture of exponentials (each direction class of
// rays at its own rate), slower late than any one rate. Probes measure that:
// 12 bounces plus completion give the T30 of a 200-bounce trace within 5 %;
// the population's one rate alone is over 10 % short (the test can fail).
TEST(TailCompletion, ProbesFollowTheSlowerLateDecayOfASpecularBox) {
  Room room(0.3f, 0.0f);
  ThreadPool pool(2);
  ReflectionSettings s;
  s.bounces = 200;
  s.tailProbes = 0;
  auto full = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
  ASSERT_TRUE(full.isOk());
  for (uint32_t probes : {4096u, 0u}) {
    s.bounces = 12;
    s.tailProbes = probes;
    auto cut = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
    ASSERT_TRUE(cut.isOk());
    auto completed = completeTail(cut->histogram, cut->tail, TailCompletionSettings{});
    ASSERT_TRUE(completed.isOk());
    for (int b = 1; b < 6; ++b) {
      const double want = t30(full->histogram, b), got = t30(*completed, b);
      if (probes > 0) {
        EXPECT_NEAR(got, want, 0.05 * want) << "band " << b;
      } else {
        EXPECT_LT(got, 0.9 * want) << "band " << b;
      }
    }
  }
}

// Same material, same positions: a floor alone (rays escape) against a closed
// 10x7x3 m room. The automatic length follows the decay: far shorter outdoors.
TEST(TailCompletion, OpenSceneGetsAShortTail) {
  MaterialTable materials;
  TriangleMesh floor;
  floor.positions = {{-50, -50, 0}, {50, -50, 0}, {50, 50, 0}, {-50, 50, 0}};
  floor.triangles = {{0, 1, 2}, {0, 2, 3}};
  floor.materialIds = {0, 0};
  auto open = RayTracer::create(floor);
  auto closed = RayTracer::create(makeBox({0, 0, 0}, {10, 7, 3}, 0));
  ThreadPool pool(2);
  ReflectionSettings s;
  auto r = traceReflections(**open, materials, kSource, kListener, s, pool);
  auto q = traceReflections(**closed, materials, kSource, kListener, s, pool);
  ASSERT_TRUE(r.isOk() && q.isOk());
  EXPECT_GT(r->stats.raysEscaped, s.rays / 2);
  TailInfo openInfo, closedInfo;
  ASSERT_TRUE(completeTail(r->histogram, r->tail, TailCompletionSettings{}, &openInfo).isOk());
  ASSERT_TRUE(completeTail(q->histogram, q->tail, TailCompletionSettings{}, &closedInfo).isOk());
  EXPECT_LT(openInfo.lengthSeconds, 0.25 * closedInfo.lengthSeconds)
      << openInfo.lengthSeconds << " s outdoors vs " << closedInfo.lengthSeconds << " s in the room";
}

// A shared trace's sources share the rays' tail data: the rates made once
// (tailRates) give each source's completion the same bits as its own would;
// rates made for other settings or another histogram length are not used.
TEST(TailCompletion, RatesMadeOnceForASharedTraceGiveTheSameBits) {
  Room room(0.2f, 0.5f);
  ThreadPool pool(2);
  ReflectionSettings s;
  s.rays = 4096;
  std::vector<SharedTraceSource> sources(3);
  sources[0].position = {2, 3.5, 1.5};
  sources[1].position = {8, 1.5, 1.0};
  sources[2].position = {4, 6, 2.2};
  auto r = traceReflectionsShared(*room.tracer, room.materials, kListener, sources, s, pool);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  TailCompletionSettings t;
  t.calibrationStartSeconds = 0.02;
  const EnergyHistogram& h0 = r->front().histogram;
  auto rates = tailRates(r->front().tail, h0.binSeconds(), h0.binCount(), t);
  ASSERT_TRUE(rates.isOk());
  EXPECT_TRUE(rates->anyCut);
  TailCompletionSettings longer = t;
  longer.lengthSeconds = 3.0;
  auto otherRates = tailRates(r->front().tail, h0.binSeconds(), h0.binCount(), longer);
  ASSERT_TRUE(otherRates.isOk());
  for (const ReflectionResult& one : *r) {
    TailInfo own, given, ignored;
    auto a = completeTail(one.histogram, one.tail, t, &own);
    auto b = completeTail(one.histogram, one.tail, t, &given, &*rates);
    auto c = completeTail(one.histogram, one.tail, t, &ignored, &*otherRates);
    ASSERT_TRUE(a.isOk() && b.isOk() && c.isOk());
    EXPECT_EQ(a->data(), b->data());
    EXPECT_EQ(a->data(), c->data());
    EXPECT_EQ(own.kappa, given.kappa);
    EXPECT_EQ(own.decayRatePerSecond, given.decayRatePerSecond);
    EXPECT_EQ(own.lengthSeconds, given.lengthSeconds);
  }
}

// The automatic length says when its cap, not the decay, ended it: a room
// that hardly absorbs, or a cap below a room's decay; an explicit length
// or a decay that ends first is not capped.
TEST(TailCompletion, ALengthCutByTheCapSaysSo) {
  ThreadPool pool(1);
  ReflectionSettings s;
  s.rays = 2000;
  s.air.enabled = false;
  Room live(0.001f, 0.5f), room(0.2f, 0.5f);
  auto l = traceReflections(*live.tracer, live.materials, kSource, kListener, s, pool);
  auto r = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
  ASSERT_TRUE(l.isOk() && r.isOk());
  TailCompletionSettings t;
  t.air.enabled = false;
  TailInfo info;
  ASSERT_TRUE(completeTail(l->histogram, l->tail, t, &info).isOk());
  EXPECT_EQ(info.cappedAtSeconds, t.maxAutoSeconds);  // T60 ~ 500 s
  EXPECT_NEAR(info.lengthSeconds, t.maxAutoSeconds, l->histogram.binSeconds());
  ASSERT_TRUE(completeTail(r->histogram, r->tail, t, &info).isOk());
  EXPECT_EQ(info.cappedAtSeconds, 0.0);
  const double natural = info.lengthSeconds;
  EXPECT_LT(natural, t.maxAutoSeconds);
  t.maxAutoSeconds = natural / 2;
  ASSERT_TRUE(completeTail(r->histogram, r->tail, t, &info).isOk());
  EXPECT_EQ(info.cappedAtSeconds, natural / 2);
  t.lengthSeconds = natural;  // explicit: its own length, not capped
  ASSERT_TRUE(completeTail(r->histogram, r->tail, t, &info).isOk());
  EXPECT_EQ(info.cappedAtSeconds, 0.0);
}

// Where a trace's histogram ends with the room still ringing, the tail
// carries on from the probes' measured level at the population's rate:
// no dip before the end, no step after it, and a tail at all when no bin
// past the image sources was complete enough to calibrate kappa (few
// bounces), where it used to stop at the trace's end.
TEST(TailCompletion, TheTailCarriesOnSmoothlyPastTheTracesEnd) {
  Room live(0.03f, 0.5f);  // T60 ~4.7 s
  ThreadPool pool(2);
  ReflectionSettings s;
  s.maxTimeSeconds = 1.5;
  s.bounces = 8;
  s.air.enabled = false;  // as the completion's
  auto r = traceReflections(*live.tracer, live.materials, kSource, kListener, s, pool);
  ASSERT_TRUE(r.isOk());
  const double dt = r->histogram.binSeconds();
  for (double calibrationStart : {0.02, 0.12}) {  // 0.12 s: past where the 8-bounce trace is complete
    TailCompletionSettings t;
    t.air.enabled = false;
    t.calibrationStartSeconds = calibrationStart;
    TailInfo info;
    auto c = completeTail(r->histogram, r->tail, t, &info);
    ASSERT_TRUE(c.isOk());
    ASSERT_GT(c->durationSeconds(), 3.0);
    // Mean level (dB) of all bands over [from, to).
    auto level = [&](double from, double to) {
      double e = 0;
      for (size_t i = size_t(from / dt); i < size_t(to / dt); ++i)
        for (int b = 0; b < kNumBands; ++b) e += c->energy(i, b);
      return 10 * std::log10(e / (to - from));
    };
    // The decay line through [0.6, 1.0) and [1.9, 2.3): the probes' level
    // and the extrapolation's; every 50 ms from 0.3 s before the end to 0.3
    // s after it on that line within 1 dB (before: -2 dB just before the
    // end, +1 dB just after).
    const double a = level(0.6, 1.0), z = level(1.9, 2.3);
    auto line = [&](double mid) { return a + (z - a) * (mid - 0.8) / (2.1 - 0.8); };
    for (int k = 0; k < 12; ++k) {
      const double from = 1.2 + 0.05 * k;
      EXPECT_NEAR(level(from, from + 0.05), line(from + 0.025), 1.0)
          << "calibration from " << calibrationStart << " s, window at " << from << " s";
    }
    // The rate: the room's ~4.7 s T60 (13 dB per second) within 20 %.
    EXPECT_NEAR((a - z) / 1.3, 60.0 / 4.7, 0.2 * 60.0 / 4.7) << calibrationStart;
    for (int b = 0; b < kNumBands; ++b) EXPECT_GT(info.kappa[b], 0.0) << calibrationStart;
  }
}

// Without tail probes and with few bounces, no bin past the image sources
// is complete: kappa comes from the traced rays still in flight there, and
// the tail carries on at the population's rate (it used to end at the
// cut: kappa 0).
TEST(TailCompletion, WithoutProbesOrACompleteBinTheTailStillCarriesOn) {
  Room live(0.03f, 0.5f);  // T60 ~4.7 s
  ThreadPool pool(2);
  ReflectionSettings s;
  s.bounces = 8;
  s.tailProbes = 0;
  s.maxTimeSeconds = 1.0;
  s.air.enabled = false;
  auto r = traceReflections(*live.tracer, live.materials, kSource, kListener, s, pool);
  ASSERT_TRUE(r.isOk());
  TailCompletionSettings t;
  t.air.enabled = false;
  t.calibrationStartSeconds = 0.12;
  TailInfo info;
  auto c = completeTail(r->histogram, r->tail, t, &info);
  ASSERT_TRUE(c.isOk());
  EXPECT_GT(c->durationSeconds(), 3.0);
  const double dt = c->binSeconds();
  auto level = [&](double from, double to) {
    double e = 0;
    for (size_t i = size_t(from / dt); i < size_t(to / dt); ++i)
      for (int b = 0; b < kNumBands; ++b) e += c->energy(i, b);
    return 10 * std::log10(e / (to - from));
  };
  EXPECT_NEAR((level(0.5, 0.7) - level(2.5, 2.7)) / 2.0, 60.0 / 4.7, 0.2 * 60.0 / 4.7);
  for (int b = 0; b < kNumBands; ++b) EXPECT_GT(info.kappa[b], 0.0);
  // kappa within 25 % of what a trace complete there measures (40 bounces).
  s.bounces = 40;
  auto full = traceReflections(*live.tracer, live.materials, kSource, kListener, s, pool);
  ASSERT_TRUE(full.isOk());
  TailInfo complete;
  ASSERT_TRUE(completeTail(full->histogram, full->tail, t, &complete).isOk());
  for (int b = 0; b < kNumBands; ++b) EXPECT_NEAR(info.kappa[b], complete.kappa[b], 0.25 * complete.kappa[b]) << b;
}

TEST(TailCompletion, ExplicitLengthIsHonoured) {
  Room room(0.2f, 1.0f);
  ThreadPool pool(1);
  ReflectionSettings s;
  s.rays = 2000;
  auto r = traceReflections(*room.tracer, room.materials, kSource, kListener, s, pool);
  ASSERT_TRUE(r.isOk());
  TailCompletionSettings t;
  t.lengthSeconds = 2.5;
  auto completed = completeTail(r->histogram, r->tail, t);
  ASSERT_TRUE(completed.isOk());
  EXPECT_NEAR(completed->durationSeconds(), 2.5, completed->binSeconds());
  EXPECT_GT(completed->energy(completed->binCount() - 1, 0), 0.0);
}

}  // namespace earshot
