// Ambisonic IRs (issue 15): exact arrival directions, W = the omni IR, the
// late field's channel energies and correlations, frames.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <thread>

#include "../propagation/shoebox_fixture.h"
#include "earshot/core/math.h"
#include "earshot/core/thread_pool.h"
#include "earshot/ir/ambisonic_synthesis.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot {
namespace {

std::unique_ptr<RayTracer> freeField() {
  auto rt = RayTracer::create(TriangleMesh{});
  EXPECT_TRUE(rt.isOk());
  return std::move(rt.value());
}

// Sum of x over [from, to): a band-limited impulse's area, whatever its
// fractional delay.
double area(const std::vector<float>& x, size_t from, size_t to) {
  double s = 0;
  for (size_t i = from; i < std::min(to, x.size()); ++i) s += x[i];
  return s;
}

// A far source 90 degrees left and 30 degrees up of a listener facing
// `forward` with `up`: each channel's direct sound over W's is the real SH of
// (azimuth 90, elevation 30) in the listener's frame.
TEST(AmbisonicIr, DirectSoundCarriesTheHarmonicsOfItsDirection) {
  auto tracer = freeField();
  MaterialTable materials;
  const double az = kPi / 2, el = kPi / 6, r = 30.0;
  const Vec3d inFrame(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
  double want[16];
  realSphericalHarmonics(inFrame, 3, want);
  // Two listener orientations: the glTF default and an arbitrary one.
  const std::pair<Vec3d, Vec3d> orientations[] = {{{0, 0, -1}, {0, 1, 0}}, {{0.3, -0.2, 0.9}, {0.1, 1.0, 0.4}}};
  for (const auto& [forward, upHint] : orientations) {
    const Vec3d f = normalize(forward), l = normalize(cross(upHint, f)), u = cross(f, l);
    const Vec3d listener(1, 2, 3);
    const Vec3d source = listener + (f * inFrame.x + l * inFrame.y + u * inFrame.z) * r;
    for (int order : {1, 3}) {
      OmniIrSettings s;
      s.air.enabled = false;
      ThreadPool pool(1);
      AmbisonicReceiver receiver;
      receiver.order = order;
      receiver.frame.worldToFrame = worldToAmbisonicFrame(forward, upHint);
      auto ir = computeIr(*tracer, materials, source, listener, s, pool, nullptr, &receiver);
      ASSERT_TRUE(ir.isOk()) << ir.status().message();
      ASSERT_EQ(ir->ir.channelCount(), size_t(ambisonicChannels(order)));
      const size_t at = size_t(r / 343.0 * s.sampleRateHz);
      const double w = area(ir->ir.channels[0], at - 200, at + 200);
      EXPECT_NEAR(w, 1.0 / r, 0.01 / r) << "W is the omni pressure, 1/r";
      for (int c = 0; c < ambisonicChannels(order); ++c)
        EXPECT_NEAR(area(ir->ir.channels[size_t(c)], at - 200, at + 200) / w, want[c], 0.05)
            << "order " << order << " channel " << c;
    }
  }
}

// W is the omni IR of the same pair and settings (arrivals and late field).
TEST(AmbisonicIr, WIsTheOmniIr) {
  testing::Shoebox room(0.2f, 0.3f);
  OmniIrSettings s;
  s.rays = 4096;
  ThreadPool pool(2);
  const Vec3d src{2.3, 2.9, 1.4}, lis{7.1, 4.2, 1.7};
  auto omni = computeIr(*room.tracer, room.materials, src, lis, s, pool, nullptr);
  AmbisonicReceiver receiver;
  receiver.order = 2;
  auto amb = computeIr(*room.tracer, room.materials, src, lis, s, pool, nullptr, &receiver);
  ASSERT_TRUE(omni.isOk() && amb.isOk());
  ASSERT_EQ(amb->ir.channelCount(), 9u);
  ASSERT_EQ(omni->ir.frameCount(), amb->ir.frameCount());
  double peak = 0, worst = 0;
  for (size_t i = 0; i < omni->ir.frameCount(); ++i) {
    peak = std::max(peak, double(std::fabs(omni->ir.channels[0][i])));
    worst = std::max(worst, double(std::fabs(omni->ir.channels[0][i] - amb->ir.channels[0][i])));
  }
  EXPECT_LT(worst, 1e-6 * peak);
}

// The late field from a synthetic histogram: fully diffuse bins give each
// channel of order n 1/(2n+1) of W's energy, uncorrelated with W; bins whose
// energy all comes from one direction d give channel c correlation Y_c(d)
// with W and energy Y_c(d)^2.
TEST(AmbisonicIr, LateFieldFollowsTheTracedDirections) {
  const double fs = 48000, binS = 0.001;
  const size_t bins = 1000;
  for (double directional : {0.0, 1.0, 0.5}) {
    EnergyHistogram h(binS, bins);
    const Vec3d d = normalize(Vec3d(-0.4, 0.7, -0.3));  // world
    for (size_t b = 0; b < bins; ++b) {
      const double e = 1e-3 * std::exp(-double(b) * binS / 0.3);
      if (directional > 0) h.add(b, filledBands(e * directional), d);
      if (directional < 1) {
        // Diffuse: equal energy from six opposite directions sums to no direction.
        for (const Vec3d& v : {Vec3d(1, 0, 0), Vec3d(-1, 0, 0), Vec3d(0, 1, 0), Vec3d(0, -1, 0), Vec3d(0, 0, 1),
                               Vec3d(0, 0, -1)})
          h.add(b, filledBands(e * (1 - directional) / 6), v);
      }
    }
    IrSynthesisSettings s;
    s.sampleRateHz = fs;
    AmbisonicFrame frame;  // world frame
    auto ir = synthesizeAmbisonicIr({}, &h, s, 3, frame);
    ASSERT_TRUE(ir.isOk()) << ir.status().message();
    const Vec3d inFrame = rotate(frame.worldToFrame, d);
    double y[16];
    realSphericalHarmonics(inFrame, 3, y);
    const auto& w = ir->channels[0];
    double ww = 0;
    for (float v : w) ww += double(v) * v;
    for (int c = 1; c < 16; ++c) {
      double cc = 0, cw = 0;
      for (size_t i = 0; i < w.size(); ++i) {
        cc += double(ir->channels[size_t(c)][i]) * ir->channels[size_t(c)][i];
        cw += double(ir->channels[size_t(c)][i]) * w[i];
      }
      const double a = directional, diffuse = 1.0 / (2 * ambisonicOrderOf(c) + 1);
      // ~1000 ms of broadband noise: relative errors of a few percent.
      EXPECT_NEAR(cc / ww, a * y[c] * y[c] + (1 - a) * diffuse, 0.03) << "a " << a << " channel " << c;
      EXPECT_NEAR(cw / ww, a * y[c], 0.03) << "a " << a << " channel " << c;
    }
  }
}

// A fully diffuse late field's channels are mutually uncorrelated, whether
// they read one late noise at shifts (IRs of 0.7 s or more at order 3) or
// each its own (shorter IRs): every pair's correlation at zero lag within
// the estimate's own spread (sigma ~1 / sqrt(bandwidth x duration), ~0.015
// for 0.8 s of broadband noise, ~0.03 for 0.25 s; the largest of 120 pairs
// lies near 3 sigma). Channels reading the noise too close together would
// correlate by 0.1-0.6 (a band noise's correlation at lags under 5 ms).
TEST(AmbisonicIr, DiffuseLateChannelsAreMutuallyUncorrelated) {
  const double fs = 48000, binS = 0.001;
  for (size_t bins : {800, 250}) {
    EnergyHistogram h(binS, bins);
    for (size_t b = 0; b < bins; ++b) {
      const double e = 1e-3 * std::exp(-double(b) * binS / 0.5);
      for (const Vec3d& v : {Vec3d(1, 0, 0), Vec3d(-1, 0, 0), Vec3d(0, 1, 0), Vec3d(0, -1, 0), Vec3d(0, 0, 1),
                             Vec3d(0, 0, -1)})
        h.add(b, filledBands(e / 6), v);
    }
    IrSynthesisSettings s;
    s.sampleRateHz = fs;
    s.noiseKey = 12345;
    auto ir = synthesizeAmbisonicIr({}, &h, s, 3, AmbisonicFrame{});
    ASSERT_TRUE(ir.isOk()) << ir.status().message();
    const double bound = bins == 800 ? 0.05 : 0.1;
    double worst = 0;
    for (int a = 0; a < 16; ++a)
      for (int b = a + 1; b < 16; ++b) {
        const auto& x = ir->channels[size_t(a)];
        const auto& y = ir->channels[size_t(b)];
        double xy = 0, xx = 0, yy = 0;
        for (size_t i = 0; i < x.size(); ++i) {
          xy += double(x[i]) * y[i];
          xx += double(x[i]) * x[i];
          yy += double(y[i]) * y[i];
        }
        ASSERT_GT(xx * yy, 0.0);
        const double r = xy / std::sqrt(xx * yy);
        worst = std::max(worst, std::fabs(r));
        EXPECT_LT(std::fabs(r), bound) << bins << " ms: channels " << a << " and " << b;
      }
    std::printf("[ measured ] %zu ms diffuse field, order 3: largest |r| between channels %.3f\n", bins, worst);
  }
}

// Arrivals in a listener's frame equal the world-frame IR rotated by the SH
// rotation from the world frame to the listener's.
TEST(AmbisonicIr, ListenerFrameIsTheRotatedWorldFrame) {
  std::vector<Arrival> arrivals;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g;
  for (int i = 0; i < 6; ++i) {
    Arrival a;
    a.delaySeconds = 0.01 + 0.003 * i;
    a.gain = 0.5;
    a.bandGain = filledBands(1.0);
    a.direction = normalize(Vec3d(g(rng), g(rng), g(rng)));
    arrivals.push_back(a);
  }
  IrSynthesisSettings s;
  AmbisonicFrame world, listener;
  listener.worldToFrame = worldToAmbisonicFrame({0.5, 0.2, -0.8}, {0.0, 1.0, 0.3});
  auto a = synthesizeAmbisonicIr(arrivals, nullptr, s, 3, world);
  auto b = synthesizeAmbisonicIr(arrivals, nullptr, s, 3, listener);
  ASSERT_TRUE(a.isOk() && b.isOk());
  // R = L W^T takes world-frame directions to the listener's frame.
  const Rotation3 rel = relativeRotation(listener.worldToFrame, world.worldToFrame);
  ShRotation rot;
  std::vector<float> m(256);
  rot.compute(rel, 3, m.data());
  double worst = 0, peak = 0;
  for (size_t i = 0; i < a->frameCount(); ++i)
    for (int c = 0; c < 16; ++c) {
      double v = 0;
      for (int k = 0; k < 16; ++k) v += double(m[c * 16 + k]) * a->channels[size_t(k)][i];
      worst = std::max(worst, std::fabs(v - b->channels[size_t(c)][i]));
      peak = std::max(peak, std::fabs(double(b->channels[size_t(c)][i])));
    }
  EXPECT_LT(worst, 1e-4 * peak);
}

// Sources synthesised side by side (a simulation's threads) need the same
// late noises at the same moment: a thread waits for a noise another is
// making rather than making it too, and the sources start at different
// channels. Whatever the interleaving, each IR is the one it is alone (a
// seed no other test uses, so the noises are made here, concurrently).
TEST(AmbisonicIr, SourcesSynthesisedTogetherAreTheIrsTheyAreAlone) {
  EnergyHistogram h(0.001, 600);
  for (size_t b = 0; b < 600; ++b) {
    const double e = 1e-3 * std::exp(-double(b) * 0.001 / 0.2);
    h.add(b, filledBands(e * 0.6), normalize(Vec3d(0.3, -0.5, 0.2)));
    h.add(b, filledBands(e * 0.4), normalize(Vec3d(-0.3, 0.5, -0.2)));
  }
  const std::vector<Arrival> arrivals = {Arrival{0.004, 0.5, filledBands(1.0), Vec3d(1, 0, 0)}};
  auto synth = [&](uint64_t key) {
    IrSynthesisSettings s;
    s.seed = 0x5EED0F7E57ULL;
    s.noiseKey = key;
    auto ir = synthesizeAmbisonicIr(arrivals, &h, s, 2, AmbisonicFrame{});
    EXPECT_TRUE(ir.isOk());
    return ir.isOk() ? std::move(ir.value()) : AudioBuffer();
  };
  constexpr int kThreads = 6;
  std::vector<AudioBuffer> together(kThreads);
  std::atomic<int> ready{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&, t] {
      ready.fetch_add(1);
      while (ready.load() < kThreads) std::this_thread::yield();
      together[size_t(t)] = synth(uint64_t(t) * 7 + 1);
    });
  for (auto& t : threads) t.join();
  for (int t = 0; t < kThreads; ++t) {
    const AudioBuffer alone = synth(uint64_t(t) * 7 + 1);
    ASSERT_EQ(alone.channelCount(), 9u);
    for (size_t c = 0; c < 9; ++c) EXPECT_EQ(together[size_t(t)].channels[c], alone.channels[c]) << t << " " << c;
  }
  // The sources differ (their noise offsets), the channels are independent.
  EXPECT_NE(together[0].channels[4], together[1].channels[4]);
}

// A partial synthesis (what the runtime makes of a source whose tail the
// shared one stands for) is the whole IR's first partialFrames samples in
// every channel, zeros after in all but W, and W whole; synthesizeIrOf
// makes the whole IR again from the result, the same bits. Both trace modes
// (a shared trace's sources are synthesised on the pool's threads).
TEST(AmbisonicIr, PartialSynthesisIsTheWholeIrsStartAndWWhole) {
  testing::Shoebox room(0.2f, 0.3f);
  OmniIrSettings s;
  s.rays = 2048;
  ThreadPool pool(2);
  const Vec3d lis{7.1, 4.2, 1.7};
  const std::vector<Vec3d> sources = {{2.3, 2.9, 1.4}, {5.0, 1.5, 2.0}};
  AmbisonicReceiver receiver;
  receiver.order = 2;
  const size_t partial = 7680;  // 0.16 s
  for (TraceMode mode : {TraceMode::kShared, TraceMode::kPerSource}) {
    std::vector<IrRequest> whole, part;
    for (const Vec3d& src : sources) {
      IrRequest r;
      r.source = src;
      whole.push_back(r);
      r.ambisonicPartialFrames = partial;
      part.push_back(r);
    }
    auto a = computeIrs(*room.tracer, room.materials, lis, whole, s, mode, pool, nullptr, &receiver);
    auto b = computeIrs(*room.tracer, room.materials, lis, part, s, mode, pool, nullptr, &receiver);
    ASSERT_TRUE(a.isOk() && b.isOk());
    for (size_t k = 0; k < sources.size(); ++k) {
      const AudioBuffer& w = (*a)[k].ir;
      const AudioBuffer& p = (*b)[k].ir;
      ASSERT_EQ(w.channelCount(), 9u);
      ASSERT_EQ(p.channelCount(), 9u);
      ASSERT_GT(w.frameCount(), 3 * partial) << "the test needs a tail after the partial frames";
      ASSERT_EQ(w.frameCount(), p.frameCount());
      EXPECT_EQ(w.channels[0], p.channels[0]) << toString(mode) << " source " << k;
      for (size_t c = 1; c < 9; ++c) {
        bool prefix = true, zeros = true, tail = false;
        for (size_t i = 0; i < w.frameCount(); ++i) {
          if (i < partial) prefix = prefix && w.channels[c][i] == p.channels[c][i];
          else {
            zeros = zeros && p.channels[c][i] == 0.0f;
            tail = tail || w.channels[c][i] != 0.0f;
          }
        }
        EXPECT_TRUE(prefix) << toString(mode) << " source " << k << " channel " << c;
        EXPECT_TRUE(zeros) << toString(mode) << " source " << k << " channel " << c;
        EXPECT_TRUE(tail) << "the whole IR's channel " << c << " has a tail to leave out";
      }
      OmniIrSettings ws = s;
      ws.includeDirect = part[k].includeDirect;
      ws.directivity = part[k].directivity;
      // A shared trace synthesises on the pool's threads (denormals
      // flushed), so this does too; these IRs hold no denormals, so the
      // per-source mode (synthesised on the caller) gives the same bits.
      ThreadPool one(1);
      AudioBuffer again;
      one.parallelFor(1, [&](size_t, unsigned) {
        auto r = synthesizeIrOf((*b)[k], ws, sources[k], lis, nullptr, &receiver);
        ASSERT_TRUE(r.isOk()) << r.status().message();
        again = std::move(r.value());
      });
      ASSERT_EQ(again.channelCount(), 9u);
      for (size_t c = 0; c < 9; ++c) EXPECT_EQ(again.channels[c], w.channels[c]) << toString(mode) << " " << k << " " << c;
    }
  }
}

TEST(AmbisonicIr, RefusesBadOrdersAndFrames) {
  IrSynthesisSettings s;
  AmbisonicFrame frame;
  EXPECT_FALSE(synthesizeAmbisonicIr({}, nullptr, s, 0, frame).isOk());
  EXPECT_FALSE(synthesizeAmbisonicIr({}, nullptr, s, 4, frame).isOk());
  frame.worldToFrame[0] = std::nan("");
  EXPECT_FALSE(synthesizeAmbisonicIr({}, nullptr, s, 1, frame).isOk());
}

}  // namespace
}  // namespace earshot
