// The runtime (issue 6, 7): the direct voice (delay, Doppler, head rotation),
// and the engine (exact static convolution, round-robin simulation, errors).
#include <gtest/gtest.h>
#include <chrono>
#include <thread>
#include <sstream>
#include <fstream>
#include <filesystem>
#include <functional>
#include <optional>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "earshot/core/math.h"
#include "earshot/core/random.h"
#include "earshot/core/thread_pool.h"
#include "earshot/io/input_file.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/runtime/direct_voice.h"
#include "earshot/runtime/engine.h"
#include "earshot/runtime/latest_values.h"
#include "earshot/scene/ray_tracer.h"
#include "../support/sine_frequency.h"
#include "runtime_fixture.h"

namespace earshot::runtime {
namespace {

using test::kFs;

double sineFrequency(const std::vector<float>& x, size_t from, size_t n) {
  return earshot::test::sineFrequency(x, from, n, kFs);
}

double energy(const float* x, size_t n) {
  double e = 0;
  for (size_t i = 0; i < n; ++i) e += double(x[i]) * x[i];
  return e;
}

// The Hann window over n samples, at sample i.
double hann(size_t i, size_t n) { return 0.5 - 0.5 * std::cos(2 * kPi * double(i) / double(n)); }

// |X_k|^2 of the Hann-windowed DFT of n samples.
double hannBinPower(const float* x, size_t n, size_t k) {
  double re = 0, im = 0;
  for (size_t i = 0; i < n; ++i) {
    const double w = hann(i, n);
    re += w * x[i] * std::cos(2 * kPi * double(k * i) / double(n));
    im -= w * x[i] * std::sin(2 * kPi * double(k * i) / double(n));
  }
  return re * re + im * im;
}

// Share of n samples' energy at or above `fromHz`, in dB (Hann-windowed DFT
// over the n samples, DC left out): where a tick or a chirp shows.
double highBandShareDb(const float* x, size_t n, double fromHz) {
  double all = 0, high = 0;
  for (size_t k = 1; k < n / 2; ++k) {
    const double p = hannBinPower(x, n, k);
    all += p;
    if (double(k) * kFs / double(n) >= fromHz) high += p;
  }
  return energyToDb(high / all);
}

// Share of n samples' energy farther than `halfWidthHz` from a tone's
// frequency `hz`, in dB (Hann window; the near bins' energy by DFT, the
// whole by Parseval): how far a moving source's tone is from one pure
// Doppler-shifted tone (a staircase of delays modulates it: sidebands).
double offToneShareDb(const float* x, size_t n, double hz, double halfWidthHz) {
  double all = 0;
  for (size_t i = 0; i < n; ++i) all += hann(i, n) * hann(i, n) * double(x[i]) * x[i];
  double near = 0;  // the one-sided spectrum's bins within the band, twice (the mirror)
  const size_t k0 = size_t(std::ceil((hz - halfWidthHz) * double(n) / kFs)),
               k1 = size_t(std::floor((hz + halfWidthHz) * double(n) / kFs));
  for (size_t k = k0; k <= k1; ++k) near += 2 * hannBinPower(x, n, k) / double(n);
  return energyToDb(std::max(all - near, 1e-30 * all) / all);
}

}  // namespace

// A static source: the voice's impulse response peaks at r/c plus the
// convolver latency it is told to align with, with the HRTF's energy / r^2.
TEST(DirectVoice, StaticSourceArrivesAtRoverCWithOneOverR) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  DirectVoiceSettings s;
  s.air.enabled = false;
  s.extraDelayFrames = 256;
  auto voice = DirectVoice::create(s, model->hrtfPtr());
  ASSERT_TRUE(voice.isOk()) << voice.status().message();
  DirectTarget t;
  t.source = {0, 0, -6.86};  // ahead, 20 ms
  const size_t n = 4096;
  std::vector<float> in(n, 0.0f), l(n, 0.0f), r(n, 0.0f);
  in[0] = 1.0f;
  (*voice)->process(in.data(), l.data(), r.data(), n, t);
  size_t peak = 0;
  for (size_t i = 0; i < n; ++i)
    if (std::fabs(l[i]) > std::fabs(l[peak])) peak = i;
  const double expected = 6.86 / 343.0 * kFs + 256;
  EXPECT_NEAR(double(peak), expected, 0.001 * kFs) << "within the HRIR's onset";
  auto pair = std::make_unique<hrtf::HrirPair>();
  model->hrtf().lookup({0, 0, -1}, *pair);
  const double hrirEnergy = energy(pair->left.data(), pair->length);
  EXPECT_NEAR(energyToDb(energy(l.data(), n)), energyToDb(hrirEnergy / (6.86 * 6.86)), 0.2);
}

// Issue 7: a source passing the listener at constant speed is heard at
// f c / (c - v cos) approaching and f c / (c + v cos) receding (within 1 %).
TEST(DirectVoice, MovingSourceGivesTheDopplerShift) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  DirectVoiceSettings s;
  auto voice = DirectVoice::create(s, model->hrtfPtr());
  ASSERT_TRUE(voice.isOk());
  const double v = 20.0, f0 = 500.0, c = 343.0, seconds = 6.0;
  const size_t total = size_t(seconds * kFs), block = 256;
  std::vector<float> in(total), l(total, 0.0f), r(total, 0.0f);
  for (size_t i = 0; i < total; ++i) in[i] = float(std::sin(2 * kPi * f0 * double(i) / kFs));
  DirectTarget t;
  for (size_t off = 0; off < total; off += block) {
    const double time = double(off + block) / kFs;
    t.source = {-60.0 + v * time, 0.0, -2.0};  // passes 2 m in front at t = 3 s
    (*voice)->process(in.data() + off, l.data() + off, r.data() + off, block, t);
  }
  // Emission at 0.5-1.0 s: approaching at about v (the path is 2 m aside, 30+ m away).
  const double approach = sineFrequency(l, size_t(1.0 * kFs), size_t(0.4 * kFs));
  const double recede = sineFrequency(l, size_t(5.2 * kFs), size_t(0.4 * kFs));
  EXPECT_NEAR(approach / (f0 * c / (c - v)), 1.0, 0.01) << approach;
  EXPECT_NEAR(recede / (f0 * c / (c + v)), 1.0, 0.01) << recede;
  EXPECT_GT(approach, f0 * 1.04);
  EXPECT_LT(recede, f0 * 0.96);
}

// A teleport (the source 3 m away, then 40 m in the next block: 5,200
// samples of delay in a 256-frame block) is a crossfade across the block
// from the line read at the old delay to the line read at the new one. A
// ramp of the delay read the line at ~21 times its rate there: a 1 kHz
// tone became an aliased chirp, all but 0.03 dB of the block's energy
// above 3 kHz.
TEST(DirectVoice, ATeleportCrossfadesInsteadOfChirping) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  DirectVoiceSettings s;
  auto voice = DirectVoice::create(s, model->hrtfPtr());
  ASSERT_TRUE(voice.isOk());
  const size_t block = 256, blocks = 80;
  std::vector<float> in(block * blocks), l(block * blocks, 0.0f), r(block * blocks, 0.0f);
  for (size_t i = 0; i < in.size(); ++i) in[i] = float(std::sin(2 * kPi * 1000.0 * double(i) / kFs));
  // The same through the ambisonic path (W, the head centre's delay).
  auto ambisonic = DirectVoice::create(s, model->hrtfPtr());
  ASSERT_TRUE(ambisonic.isOk());
  std::vector<std::vector<float>> bus(4, std::vector<float>(block * blocks, 0.0f));
  DirectTarget t;
  for (size_t b = 0; b < blocks; ++b) {
    t.source = {1.0, 0.0, b < 40 ? -3.0 : -40.0};
    (*voice)->process(in.data() + b * block, l.data() + b * block, r.data() + b * block, block, t);
    float* outs[4] = {bus[0].data() + b * block, bus[1].data() + b * block, bus[2].data() + b * block,
                      bus[3].data() + b * block};
    (*ambisonic)->processAmbisonic(in.data() + b * block, outs, 1, block, t);
  }
  // Share of a block's energy above 3 kHz.
  auto highShareOf = [&](const std::vector<float>& x, size_t b) {
    return highBandShareDb(x.data() + b * block, block, 3000.0);
  };
  auto highShare = [&](size_t b) { return highShareOf(l, b); };
  const double before = highShare(30), jump = highShare(40), after = highShare(50);
  EXPECT_LT(highShareOf(bus[0], 40), -30.0) << "no chirp in W";
  EXPECT_LT(highShareOf(bus[0], 30), -40.0);
  std::printf("energy above 3 kHz: %.1f dB of the block before, %.1f in the jump's, %.1f after\n", before, jump, after);
  EXPECT_LT(before, -40.0);
  EXPECT_LT(after, -40.0);
  EXPECT_LT(jump, -30.0) << "no chirp";
  auto rms = [&](size_t b) { return std::sqrt(energy(l.data() + b * block, block) / double(block)); };
  EXPECT_LE(rms(40), 1.05 * std::max(rms(39), rms(41))) << "no burst";
  EXPECT_GE(rms(40), 0.95 * std::min(rms(39), rms(41))) << "no gap";
}

// An occluder that comes or goes (a door: transmission 1 to a 20 dB tilt,
// and back) changes the direct sound's shelves: they crossfade over the
// block. Switching a running biquad's coefficients at once ticked: with a
// 200 Hz tone, the block where the change came out of the delay line had
// -27 dB of its energy above 2 kHz, against -70 dB or less in steady blocks.
TEST(DirectVoice, AnOccluderComingOrGoingIsAFadeNotATick) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  DirectVoiceSettings s;
  s.air.enabled = false;
  auto voice = DirectVoice::create(s, model->hrtfPtr());
  ASSERT_TRUE(voice.isOk());
  const size_t block = 256, blocks = 60;
  std::vector<float> in(block * blocks), l(block * blocks, 0.0f), r(block * blocks, 0.0f);
  for (size_t i = 0; i < in.size(); ++i) in[i] = float(std::sin(2 * kPi * 200.0 * double(i) / kFs));
  DirectTarget t;
  t.source = {1, 0, -3};
  const double door[kNumBands] = {0.9, 0.8, 0.6, 0.4, 0.2, 0.1, 0.05};
  for (size_t b = 0; b < blocks; ++b) {
    const bool closed = (b / 10) % 2 == 1;  // closes at block 10, opens at 20, ...
    for (int k = 0; k < kNumBands; ++k) t.transmission[k] = closed ? door[k] : 1.0;
    (*voice)->process(in.data() + b * block, l.data() + b * block, r.data() + b * block, block, t);
  }
  auto highShare = [&](size_t b) { return highBandShareDb(l.data() + b * block, block, 2000.0); };  // above 2 kHz
  double steady = -1e9, switching = -1e9;
  for (size_t b = 5; b < blocks; ++b) {
    const bool nearSwitch = b % 10 <= 3;  // the change reaches the output after the 9 ms delay
    (nearSwitch ? switching : steady) = std::max(nearSwitch ? switching : steady, highShare(b));
  }
  std::printf("energy above 2 kHz, worst block: %.1f dB near a change, %.1f dB elsewhere\n", switching, steady);
  EXPECT_LT(steady, -60.0);
  EXPECT_LT(switching, -55.0) << "no tick";
}

// Issue 6: after the listener turns 90 degrees, the direct sound's ILD has
// flipped sign within 2 audio blocks.
TEST(DirectVoice, HeadTurnFlipsTheIldWithinTwoBlocks) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  DirectVoiceSettings s;
  auto voice = DirectVoice::create(s, model->hrtfPtr());
  ASSERT_TRUE(voice.isOk());
  const size_t block = 256;
  Pcg32 rng(3, 4);
  std::vector<float> in(block), l(block), r(block);
  DirectTarget t;
  t.source = {-2, 0, -2};  // 45 degrees to the left of forward (-z)
  auto ildOfNextBlock = [&] {
    for (float& x : in) x = rng.uniform() * 2.0f - 1.0f;
    std::fill(l.begin(), l.end(), 0.0f);
    std::fill(r.begin(), r.end(), 0.0f);
    (*voice)->process(in.data(), l.data(), r.data(), block, t);
    return energyToDb(energy(l.data(), block) / energy(r.data(), block));
  };
  for (int i = 0; i < 20; ++i) ildOfNextBlock();
  EXPECT_GT(ildOfNextBlock(), 3.0) << "source on the left";
  t.orientation.forward = {-1, 0, 0};  // turn 90 degrees left: the source is now 45 degrees right
  ildOfNextBlock();                     // block 1: crossfading
  EXPECT_LT(ildOfNextBlock(), -3.0) << "block 2: the ILD has flipped";
}

// A turn far below what anyone hears (under 0.25 degrees a block, a
// source gliding past) keeps the HRIR, which follows once the turn adds
// up: a source turned 0.1 degrees a block from ahead to 60 degrees left
// ends with the HRIR of 60 degrees (its ILD within 0.2 dB of a source
// standing there, the same noise), not the one it started with.
TEST(DirectVoice, ASlowTurnAddsUpToTheHrirOfWhereItEnds) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  DirectVoiceSettings s;
  s.air.enabled = false;
  const size_t block = 256, blocks = 640;
  auto at = [](double degrees) {
    const double a = degrees * kPi / 180.0;
    return Vec3d{-2.0 * std::sin(a), 0.0, -2.0 * std::cos(a)};  // forward is -z, left -x
  };
  // The ILD of the last 40 blocks (the same noise for both voices).
  auto ild = [&](bool turning) {
    auto voice = DirectVoice::create(s, model->hrtfPtr());
    EXPECT_TRUE(voice.isOk());
    Pcg32 rng(3, 9);
    std::vector<float> in(block), l(block), r(block);
    double el = 0, er = 0;
    DirectTarget t;
    for (size_t b = 0; b <= blocks; ++b) {
      t.source = at(turning ? std::min(0.1 * double(b), 60.0) : 60.0);  // the last 40 blocks at 60
      for (float& x : in) x = rng.uniform() - 0.5f;
      std::fill(l.begin(), l.end(), 0.0f);
      std::fill(r.begin(), r.end(), 0.0f);
      (*voice)->process(in.data(), l.data(), r.data(), block, t);
      if (b + 40 > blocks) {
        el += energy(l.data(), block);
        er += energy(r.data(), block);
      }
    }
    return energyToDb(el / er);
  };
  const double turned = ild(true), standing = ild(false);
  std::printf("ILD at 60 degrees: turned there 0.1 degrees a block %.2f dB, standing there %.2f dB\n", turned,
              standing);
  EXPECT_GT(standing, 6.0);
  EXPECT_NEAR(turned, standing, 0.2);
}

// Any host block size gives the same output (parameters fixed).
TEST(DirectVoice, BlockSizeDoesNotChangeTheOutputOfAStaticSource) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  DirectVoiceSettings s;
  auto a = DirectVoice::create(s, model->hrtfPtr());
  auto b = DirectVoice::create(s, model->hrtfPtr());
  ASSERT_TRUE(a.isOk() && b.isOk());
  const size_t n = 20000;
  std::vector<float> in(n), la(n, 0.0f), ra(n, 0.0f), lb(n, 0.0f), rb(n, 0.0f);
  Pcg32 rng(1, 2);
  for (float& x : in) x = rng.uniform() - 0.5f;
  DirectTarget t;
  t.source = {3, 1, -4};
  (*a)->process(in.data(), la.data(), ra.data(), n, t);
  const size_t sizes[] = {1, 7, 64, 333, 1024, 5};
  for (size_t off = 0, k = 0; off < n; ++k) {
    const size_t m = std::min(sizes[k % 6], n - off);
    (*b)->process(in.data() + off, lb.data() + off, rb.data() + off, m, t);
    off += m;
  }
  for (size_t i = 0; i < n; ++i) {
    ASSERT_NEAR(la[i], lb[i], 1e-6) << i;
    ASSERT_NEAR(ra[i], rb[i], 1e-6) << i;
  }
}

// Issue 7's exactness, at the engine: a static source whose IR includes the
// direct sound renders exactly the dry signal convolved with computeIr's IR
// for the same poses and settings, delayed by the latency (1e-5 of peak).
TEST(Engine, StaticSourceIsTheDrySignalConvolvedWithTheIr) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room;
  EngineSettings es = test::fastSettings();
  es.ambisonicOrder = 0;  // binaural reflections: the IR computeIr gives for a binaural receiver
  auto engine = Engine::create(es, model);
  ASSERT_TRUE(engine.isOk()) << engine.status().message();
  Engine& e = **engine;
  e.setScene(room.tracer, room.materials);
  SourceSettings ss;
  ss.direct = DirectMode::kInImpulseResponse;
  auto id = e.addSource(ss);
  ASSERT_TRUE(id.isOk());
  const Vec3d source{2, 3, 1.5}, listener{7, 4, 1.6};
  ListenerOrientation o{{1, 0, 0}, {0, 0, 1}};
  ASSERT_TRUE(e.setSourcePosition(*id, source).isOk());
  ASSERT_TRUE(e.setListener(listener, o).isOk());
  ASSERT_TRUE(e.simulate().isOk());

  ThreadPool pool(1);
  BinauralReceiver receiver{model, o};
  OmniIrSettings is = es.simulation;
  auto irs = computeIrs(*room.tracer, *room.materials, listener, {IrRequest{source, {}, true, {}}}, is, es.traceMode, pool,
                        &receiver);
  ASSERT_TRUE(irs.isOk());
  const OmniIrResult* ir = &irs->front();

  const size_t n = size_t(0.5 * kFs), lat = e.latencyFrames();
  std::vector<float> dry(n, 0.0f);
  Pcg32 rng(9, 9);
  for (size_t i = 0; i < 2000; ++i) dry[i] = rng.uniform() - 0.5f;
  std::vector<float> l(n + lat), r(n + lat), zeros(4096, 0.0f);
  std::vector<const float*> inputs(es.maxSources, nullptr);
  const size_t sizes[] = {256, 100, 1000, 17, 512};
  for (size_t off = 0, k = 0; off < n + lat; ++k) {
    const size_t m = std::min(sizes[k % 5], n + lat - off);
    inputs[*id] = off < n ? dry.data() + off : zeros.data();
    if (off < n && off + m > n) inputs[*id] = zeros.data();  // keep the tail simple: dry is zero there anyway
    e.process(inputs.data(), l.data() + off, r.data() + off, m);
    off += m;
  }
  // Reference: direct convolution of the first 2000 samples (the rest is 0).
  const auto& h = ir->ir.channels;
  double peak = 0, worst = 0;
  for (int ear = 0; ear < 2; ++ear) {
    const std::vector<float>& out = ear ? r : l;
    for (size_t t = 0; t < n; ++t) {
      double y = 0;
      for (size_t k = 0; k < 2000 && k <= t; ++k)
        if (t - k < h[ear].size()) y += double(dry[k]) * h[ear][t - k];
      peak = std::max(peak, std::fabs(y));
      worst = std::max(worst, std::fabs(y - out[t + lat]));
    }
  }
  EXPECT_GT(peak, 0.0);
  EXPECT_LE(worst, 1e-5 * peak) << "worst " << worst << " peak " << peak;
}

// One trace serves every source of a simulation (issue 16): with the shared
// trace each of 4 sources gets an IR whose late energy (after 50 ms, W of
// the ambisonic IR) is within 1 dB of its IR from a trace of its own (the
// two traces' noise; by reciprocity the same energies), and the IRs do not
// depend on the simulation's thread count.
TEST(Engine, SharedTraceGivesEachSourceTheEnergiesOfItsOwnTrace) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room;
  const std::vector<Vec3d> sources = {{2, 3, 1.5}, {8.5, 1.2, 1.1}, {3.5, 6.0, 2.2}, {6.0, 2.0, 0.8}};
  auto irsWith = [&](TraceMode mode, unsigned threads) {
    EngineSettings es = test::fastSettings();
    es.simulation.rays = 8000;
    es.traceMode = mode;
    es.threads = threads;
    auto engine = Engine::create(es, model);
    EXPECT_TRUE(engine.isOk());
    Engine& e = **engine;
    e.setScene(room.tracer, room.materials);
    std::vector<uint32_t> ids;
    for (const Vec3d& p : sources) {
      auto id = e.addSource({});
      EXPECT_TRUE(id.isOk());
      EXPECT_TRUE(e.setSourcePosition(*id, p).isOk());
      ids.push_back(*id);
    }
    EXPECT_TRUE(e.setListener({7, 4, 1.6}, {{1, 0, 0}, {0, 0, 1}}).isOk());
    EXPECT_TRUE(e.simulate().isOk());
    EXPECT_EQ(e.lastSimulation().sourcesSimulated, sources.size());
    std::vector<std::shared_ptr<const AudioBuffer>> out;
    for (uint32_t id : ids) out.push_back(e.sourceIr(id).ir);
    return out;
  };
  const auto shared = irsWith(TraceMode::kShared, 2);
  const auto sharedOneThread = irsWith(TraceMode::kShared, 1);
  const auto perSource = irsWith(TraceMode::kPerSource, 2);
  auto lateDb = [](const AudioBuffer& ir) {
    double e = 0;
    for (size_t i = size_t(0.05 * ir.sampleRateHz); i < ir.frameCount(); ++i) e += double(ir.channels[0][i]) * ir.channels[0][i];
    return 10.0 * std::log10(e);
  };
  for (size_t i = 0; i < sources.size(); ++i) {
    ASSERT_TRUE(shared[i] && perSource[i] && sharedOneThread[i]);
    EXPECT_EQ(shared[i]->channels, sharedOneThread[i]->channels) << "source " << i;
    const double d = lateDb(*shared[i]) - lateDb(*perSource[i]);
    std::printf("source %zu: late W energy shared - per source %+.2f dB\n", i, d);
    EXPECT_LT(std::fabs(d), 1.0) << "source " << i;
  }
}

// A removed source's reverberation rings out in its slot (its direct sound
// stops at once). A source added meanwhile takes another slot: it neither
// cuts that ring-out nor carries it through its own IR. (It took the lowest
// free slot before, and once simulated played the removed source's last
// sound through its own IR: its reflections from the new source's place.)
TEST(Engine, ARemovedSourceRingsOutAndANewSourceTakesAnotherSlot) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room;
  const size_t block = 256;
  auto afterRemoval = [&](bool addAnother, uint32_t* removedSlot, uint32_t* newSlot) {
    EngineSettings es = test::fastSettings();
    es.ambisonicOrder = 0;  // binaural reflections: each source's whole IR in its slot (with ambisonic
                            // ones the late part is one shared tail, made again at each simulation)
    auto engine = Engine::create(es, model);
    EXPECT_TRUE(engine.isOk());
    Engine& e = **engine;
    e.setScene(room.tracer, room.materials);
    EXPECT_TRUE(e.setListener({7, 4, 1.6}, {{1, 0, 0}, {0, 0, 1}}).isOk());
    auto a = e.addSource({});
    EXPECT_TRUE(a.isOk());
    *removedSlot = *a;
    EXPECT_TRUE(e.setSourcePosition(*a, {2, 3, 1.5}).isOk());
    EXPECT_TRUE(e.simulate().isOk());
    std::vector<float> in(block), silence(block, 0.0f), l(block), r(block);
    std::vector<const float*> inputs(size_t(es.maxSources), nullptr);
    inputs[*a] = in.data();
    Pcg32 rng(7, 1);
    for (int b = 0; b < 94; ++b) {  // 0.5 s of noise
      for (float& x : in) x = float(rng.uniformDouble() - 0.5);
      e.process(inputs.data(), l.data(), r.data(), block);
    }
    EXPECT_TRUE(e.removeSource(*a).isOk());
    inputs[*a] = silence.data();
    if (addAnother) {
      auto b = e.addSource({});
      EXPECT_TRUE(b.isOk());
      *newSlot = *b;
      EXPECT_TRUE(e.setSourcePosition(*b, {8.5, 1.2, 1.1}).isOk());
      inputs[*b] = silence.data();
      EXPECT_TRUE(e.simulate().isOk());
    }
    std::vector<float> out;
    for (int b = 0; b < 375; ++b) {  // 2 s
      e.process(inputs.data(), l.data(), r.data(), block);
      out.insert(out.end(), l.begin(), l.end());
      out.insert(out.end(), r.begin(), r.end());
    }
    return out;
  };
  uint32_t slotA = 0, slotB = 0;
  const std::vector<float> alone = afterRemoval(false, &slotA, &slotB);
  auto energy = [&](double from, double to) {
    double e = 0;
    for (size_t k = size_t(from * kFs / block); k < size_t(to * kFs / block); ++k)
      for (size_t i = 0; i < 2 * block; ++i) e += double(alone[k * 2 * block + i]) * alone[k * 2 * block + i];
    return e;
  };
  EXPECT_GT(energy(0.0, 0.25), 10 * energy(0.5, 0.75)) << "a decay";
  EXPECT_GT(energy(0.5, 0.75), 0.0) << "the reverberation rings out";
  EXPECT_EQ(energy(1.7, 2.0), 0.0) << "and ends with the IR (1.5 s after the output's latency)";
  const std::vector<float> withAnother = afterRemoval(true, &slotA, &slotB);
  EXPECT_NE(slotA, slotB);
  ASSERT_EQ(withAnother.size(), alone.size());
  size_t differ = 0;
  double ringOut = 0, difference = 0;
  for (size_t i = 0; i < alone.size(); ++i) {
    differ += alone[i] != withAnother[i];
    ringOut += double(alone[i]) * alone[i];
    difference += (double(withAnother[i]) - alone[i]) * (double(withAnother[i]) - alone[i]);
  }
  std::printf("slots %u and %u; the output's change with the new source: %.1f dB of the ring-out\n", slotA, slotB,
              10 * std::log10(difference / ringOut + 1e-30));
  EXPECT_EQ(differ, 0u) << "a silent new source changes nothing of the ring-out";
}

// Which slot a new source takes: one whose last source has rung out or
// never played reflections (the lowest), else one never used, else the one
// that played longest ago.
TEST(Engine, ANewSourceTakesARungOutSlotThenAnUnusedOneThenTheOneFreedLongestAgo) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room;
  EngineSettings es = test::fastSettings();
  es.maxSources = 3;
  es.maxIrSeconds = 0.2;
  es.simulation.rays = 300;
  auto engine = Engine::create(es, model);
  ASSERT_TRUE(engine.isOk());
  Engine& e = **engine;
  e.setScene(room.tracer, room.materials);
  std::vector<float> silence(256, 0.0f), l(256), r(256);
  std::vector<const float*> inputs(3, silence.data());  // every slot fed (silence: what counts is that it plays)
  auto play = [&](int blocks) {
    for (int b = 0; b < blocks; ++b) e.process(inputs.data(), l.data(), r.data(), 256);
  };
  auto add = [&] {
    auto id = e.addSource({});
    EXPECT_TRUE(id.isOk()) << id.status().message();
    if (id.isOk()) {
      EXPECT_TRUE(e.setSourcePosition(*id, {2.0 + *id, 3, 1.5}).isOk());
    }
    return id.isOk() ? *id : ~0u;
  };
  const uint32_t a = add(), b = add();
  EXPECT_EQ(a, 0u);
  EXPECT_EQ(b, 1u);
  ASSERT_TRUE(e.removeSource(b).isOk());
  EXPECT_EQ(add(), 1u) << "slot 1 never played: taken again";
  ASSERT_TRUE(e.simulate().isOk());
  play(10);
  ASSERT_TRUE(e.removeSource(a).isOk());
  play(10);
  const uint32_t c = add();
  EXPECT_EQ(c, 2u) << "slot 0 still rings: an unused slot";
  ASSERT_TRUE(e.simulate().isOk());
  play(10);
  ASSERT_TRUE(e.removeSource(b).isOk());
  ASSERT_TRUE(e.removeSource(c).isOk());
  const uint32_t d = add();
  EXPECT_EQ(d, 0u) << "every free slot rings: the one that played longest ago";
  play(int(0.4 * kFs / 256));  // past 0.2 s, the latency and the margin
  const uint32_t f = add();
  EXPECT_EQ(f, 1u) << "rung out: the lowest such slot";
  EXPECT_FALSE(e.addSource({}).isOk() && e.addSource({}).isOk()) << "three slots";
}

// Moved most first, but not for ever: a source that stands still while two
// others move every step is simulated again within twice a round (here
// 2 x 3 steps of one source), so its reflections follow a door that opened
// or its own turn. It was simulated once, at its start, and never again
// while the others moved.
TEST(Engine, ASourceStandingStillIsNotStarvedBySourcesThatMove) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room;
  EngineSettings es = test::fastSettings();
  es.simulation.rays = 300;
  auto engine = Engine::create(es, model);
  ASSERT_TRUE(engine.isOk());
  Engine& e = **engine;
  e.setScene(room.tracer, room.materials);
  ASSERT_TRUE(e.setListener({7, 4, 1.6}, {{1, 0, 0}, {0, 0, 1}}).isOk());
  const std::vector<Vec3d> at = {{2, 3, 1.5}, {8.5, 1.2, 1.1}, {3.5, 6.0, 2.2}};
  std::vector<uint32_t> ids;
  for (const Vec3d& p : at) {
    auto id = e.addSource({});
    ASSERT_TRUE(id.isOk());
    ASSERT_TRUE(e.setSourcePosition(*id, p).isOk());
    ids.push_back(*id);
  }
  for (int step = 0; step < 24; ++step) {
    const double dx = step % 2 ? 0.5 : -0.5;
    for (int k = 0; k < 2; ++k) ASSERT_TRUE(e.setSourcePosition(ids[k], at[k] + Vec3d{dx, 0, 0}).isOk());
    ASSERT_TRUE(e.simulate(1).isOk());
  }
  std::vector<uint64_t> simulations;
  for (uint32_t id : ids) simulations.push_back(e.sourceIrInfo(id).simulations);
  std::printf("simulations of the moving sources %llu, %llu, of the still one %llu\n",
              (unsigned long long)simulations[0], (unsigned long long)simulations[1],
              (unsigned long long)simulations[2]);
  EXPECT_EQ(simulations[0] + simulations[1] + simulations[2], 24u);
  EXPECT_GE(simulations[2], 4u) << "at its start, then at least every 6 steps";
  EXPECT_GE(simulations[0], 9u) << "the moving ones take the rest";
  EXPECT_GE(simulations[1], 9u);
}

// Issue 6: motion to sound through the whole engine: after the listener
// turns 90 degrees (a game-thread call between two audio blocks), the direct
// sound's ILD has flipped sign within 2 blocks.
TEST(Engine, ListenerTurnFlipsTheIldWithinTwoBlocks) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  auto engine = Engine::create(test::fastSettings(), model);
  ASSERT_TRUE(engine.isOk());
  Engine& e = **engine;  // free field: the direct sound alone
  auto id = e.addSource({});
  ASSERT_TRUE(id.isOk());
  ASSERT_TRUE(e.setSourcePosition(*id, {-2, 0, -2}).isOk());  // 45 degrees left of forward (-z)
  ASSERT_TRUE(e.simulate().isOk());
  const size_t block = 256;
  Pcg32 rng(7, 8);
  std::vector<float> in(block), l(block), r(block);
  std::vector<const float*> inputs(test::fastSettings().maxSources, nullptr);
  inputs[*id] = in.data();
  auto ild = [&] {
    for (float& x : in) x = rng.uniform() - 0.5f;
    e.process(inputs.data(), l.data(), r.data(), block);
    return energyToDb(energy(l.data(), block) / energy(r.data(), block));
  };
  for (int i = 0; i < 20; ++i) ild();
  EXPECT_GT(ild(), 3.0);
  ASSERT_TRUE(e.setListener({0, 0, 0}, {{-1, 0, 0}, {0, 1, 0}}).isOk());  // turn left: the source is now 45 degrees right
  ild();
  EXPECT_LT(ild(), -3.0) << "second block after the turn";
}

// A game moves its sources and its listener at its own frame rate (60 Hz:
// every 800 frames at 48 kHz), while the audio thread runs blocks of 256.
// Following each new position within the next block made a staircase of
// delays: the Doppler shift three times over for one block, none for the
// next two, a 60 Hz modulation of the tone (-5.0 dB of a receding 1 kHz
// tone's energy off the Doppler-shifted tone). The engine spreads a pose's
// changes over the interval at which the game makes them (PoseGlide), so
// a source or listener receding at 10 m/s is heard as one tone at
// f c / (c + v), within -20 dB, whether the game updates it at 60 Hz with
// blocks of 256, at 90 Hz (a head tracker) with blocks of 128, or at 60 Hz
// with blocks of 1,024 (-16 dB; it was -12.2, the game's updates falling
// one or two to a block). A teleport in the middle of such motion is still
// one crossfade (DirectVoice), not a glide through the places between.
TEST(Engine, APoseUpdatedAtTheGamesFrameRateIsHeardAsSteadyDoppler) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  const size_t n = size_t(2.0 * kFs);
  const double f0 = 1000.0, v = 10.0, c = 343.0;
  // The left ear's output as the source (or the listener) recedes at v,
  // the game setting its position every `gameFrames`, the host processing
  // blocks of `block`; at `teleportFrame` the source jumps 30 m away.
  auto render = [&](bool moveListener, size_t block, size_t gameFrames, size_t teleportFrame = SIZE_MAX) {
    EngineSettings es = test::fastSettings();
    auto engine = Engine::create(es, model);
    EXPECT_TRUE(engine.isOk());
    Engine& e = **engine;  // free field: the direct sound alone
    auto id = e.addSource({});
    EXPECT_TRUE(id.isOk());
    const ListenerOrientation o{{0, 0, -1}, {0, 1, 0}};
    const Vec3d start{-1, 0, -3};  // ahead and a little to the left
    auto poseAt = [&](size_t frame) {
      const double d = v * double(frame) / kFs + (frame >= teleportFrame ? 30.0 : 0.0);
      if (moveListener) {
        EXPECT_TRUE(e.setSourcePosition(*id, start).isOk());
        EXPECT_TRUE(e.setListener({0, 0, d}, o).isOk());
      } else {
        EXPECT_TRUE(e.setSourcePosition(*id, start + Vec3d{0, 0, -d}).isOk());
        EXPECT_TRUE(e.setListener({0, 0, 0}, o).isOk());
      }
    };
    std::vector<float> in(n), l(n, 0.0f), r(n, 0.0f);
    for (size_t i = 0; i < n; ++i) in[i] = float(0.5 * std::sin(2 * kPi * f0 * double(i) / kFs));
    std::vector<const float*> inputs(es.maxSources, nullptr);
    size_t nextGameFrame = 0;
    for (size_t off = 0; off < n; off += block) {
      for (; nextGameFrame <= off; nextGameFrame += gameFrames) poseAt(nextGameFrame);
      inputs[*id] = in.data() + off;
      e.process(inputs.data(), l.data() + off, r.data() + off, std::min(block, n - off));
    }
    return l;
  };
  const double doppler = f0 * c / (c + v);
  const size_t from = size_t(0.5 * kFs), m = size_t(kFs);  // 0.5-1.5 s: steady
  struct Case {
    bool listener;
    size_t block, gameFrames;
    double limitDb;
  };
  for (const Case& k : {Case{false, 256, 800, -20.0}, Case{true, 256, 800, -20.0}, Case{true, 128, 533, -20.0},
                        Case{false, 1024, 800, -16.0}}) {
    const std::vector<float> everyBlock = render(k.listener, k.block, k.block),
                             gameRate = render(k.listener, k.block, k.gameFrames);
    const double ideal = offToneShareDb(everyBlock.data() + from, m, doppler, 20.0);
    const double heard = offToneShareDb(gameRate.data() + from, m, doppler, 20.0);
    std::printf("%s receding at %.0f m/s, blocks of %zu: energy off the %.1f Hz tone, updated every block %.1f dB, "
                "at %.0f Hz %.1f dB\n",
                k.listener ? "listener" : "source", v, k.block, doppler, ideal, kFs / double(k.gameFrames), heard);
    EXPECT_LT(ideal, -40.0);
    EXPECT_LT(heard, k.limitDb);
  }
  // The teleport: 30 m at 1.0 s (a game frame), heard from the first block after it.
  const size_t jump = 60 * 800, block = 256;
  const std::vector<float> t = render(false, block, 800, jump);
  const size_t jumpBlock = (jump + block - 1) / block * block;
  const double steady = highBandShareDb(t.data() + jumpBlock - 4 * block, block, 3000.0);
  const double atJump = highBandShareDb(t.data() + jumpBlock, block, 3000.0);
  // The block after the jump's is at the new place's level (a glide there
  // would pass the places between: louder by ~10 dB), as one 20 blocks on.
  const double after = energy(t.data() + jumpBlock + block, block),
               later = energy(t.data() + jumpBlock + 20 * block, block);
  std::printf("teleport while moving at 60 Hz: energy above 3 kHz, steady block %.1f dB, the jump's block %.1f dB; "
              "the next block against one 20 blocks on %+.2f dB\n",
              steady, atJump, energyToDb(after / later));
  EXPECT_LT(atJump, -30.0);
  EXPECT_NEAR(energyToDb(after / later), 0.0, 1.0);
}

// A source's sound already emitted is on its way: a source 34.3 m away is
// heard 100 ms after it plays. A game passes NULL for a source with
// nothing to play (the header: NULL plays silence) and releases a one-shot
// once its sound has ended. The direct voice was then not run at all: the
// last 100 ms of the sound never arrived, and came at the start of the
// source's next sound instead (or, after a release, not at all; a 50 ms
// burst from 34.3 m was not heard). A voice with sound in flight now runs
// on silence until that has arrived, and a new source takes another slot
// meanwhile where one is free: the output is the one with zeros, but
// for the shelves' IIR tail beyond that (-140 dB; it was 0 dB: all
// missing), with binaural and with AmbiX output.
TEST(Engine, SoundInFlightArrivesAfterTheInputStopsOrTheSourceIsReleased) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  const size_t block = 256, burst = size_t(0.05 * kFs), n = size_t(0.6 * kFs);
  enum class After { kZeros, kNull, kNullThenRelease, kRelease, kReleaseAndAdd };
  // The output's channels one after the other: two ears, or the 4 AmbiX
  // channels (the direct voice's ambisonic path).
  auto render = [&](After after, OutputFormat format) {
    EngineSettings es = test::fastSettings();
    es.output = format;
    const size_t channels = format == OutputFormat::kBinaural ? 2 : 4;
    auto engine = Engine::create(es, model);
    EXPECT_TRUE(engine.isOk());
    Engine& e = **engine;  // free field: the direct sound alone
    auto id = e.addSource({});
    EXPECT_TRUE(id.isOk());
    EXPECT_TRUE(e.setSourcePosition(*id, {-3, 0, -34.17}).isOk());  // 34.3 m: 100 ms
    std::vector<float> in(n, 0.0f), out(channels * n, 0.0f);
    Pcg32 rng(5, 3);
    for (size_t i = 0; i < burst; ++i) in[i] = rng.uniform() - 0.5f;
    std::vector<const float*> inputs(es.maxSources, nullptr);
    for (size_t off = 0; off < n; off += block) {
      const bool playing = off < burst;
      inputs[*id] = playing || after == After::kZeros ? in.data() + off : nullptr;
      if (after == After::kNullThenRelease && off == burst / block * block + 5 * block) {
        EXPECT_TRUE(e.removeSource(*id).isOk());  // a one-shot released a little after its end
      }
      if (after >= After::kRelease && off == burst / block * block + block) {
        EXPECT_TRUE(e.removeSource(*id).isOk());
        if (after == After::kReleaseAndAdd) {  // takes another slot: this one's sound is in flight
          auto other = e.addSource({});
          EXPECT_TRUE(other.isOk());
          EXPECT_NE(*other, *id);
          EXPECT_TRUE(e.setSourcePosition(*other, {3, 0, -2}).isOk());
        }
      }
      float* outs[4];
      for (size_t c = 0; c < channels; ++c) outs[c] = out.data() + c * n + off;
      e.process(inputs.data(), outs, std::min(block, n - off));
    }
    return out;
  };
  for (OutputFormat format : {OutputFormat::kBinaural, OutputFormat::kAmbisonic}) {
    const std::vector<float> zeros = render(After::kZeros, format);
    const double all = energy(zeros.data(), zeros.size());
    EXPECT_GT(all, 0.0);
    for (After after : {After::kNull, After::kNullThenRelease, After::kRelease, After::kReleaseAndAdd}) {
      const std::vector<float> out = render(after, format);
      ASSERT_EQ(out.size(), zeros.size());
      double difference = 0;
      for (size_t i = 0; i < out.size(); ++i) difference += (double(out[i]) - zeros[i]) * (double(out[i]) - zeros[i]);
      std::printf("%s, %s: the output's difference from zeros' %.1f dB of its energy\n",
                  format == OutputFormat::kBinaural ? "binaural" : "ambisonic",
                  after == After::kNull              ? "NULL input"
                  : after == After::kNullThenRelease ? "NULL input, then released"
                  : after == After::kRelease         ? "released"
                                                     : "released, a new source added",
                  energyToDb(difference / all + 1e-30));
      EXPECT_LT(energyToDb(difference / all + 1e-30), -100.0);
    }
  }
}

// A source plays from where it was added from its first block. A game
// that adds a source and then moves it (two calls) can have the audio
// thread play the source's first block in between, from where it was
// added, and glide from there: a one-shot in a slot whose last source was
// 34 m away arrived 100 ms late and swept in. addSource(settings) put a
// new source in a used slot where the slot's last source had been, not at
// the origin as documented; addSource(settings, position, forward) puts it
// where it is before the audio thread sees it.
TEST(Engine, ASourceAddedWhereItIsPlaysFromThereFromItsFirstBlock) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  const size_t block = 256, burst = size_t(0.05 * kFs), n = size_t(0.3 * kFs);
  const Vec3d at{3, 0, -2}, facing{0, 0, 1};  // a cardioid not facing the default way (0, 0, -1)
  SourceSettings ss;
  ss.directivityAlpha = 0.5;
  // kPlaced (the reference): added, then placed before its first block.
  enum class Add { kOrigin, kPlaced, kAt, kThenMoved };
  // The new source's output (both ears, or the 4 AmbiX channels) over
  // 0.3 s from its first block, in which it starts a 50 ms burst. With
  // `used`, the engine's one slot held a source 34.3 m away first, which
  // played and rang out.
  auto render = [&](OutputFormat format, bool used, Add add) {
    EngineSettings es = test::fastSettings();
    es.output = format;
    es.maxSources = 1;
    es.maxIrSeconds = 0.2;
    const size_t channels = format == OutputFormat::kBinaural ? 2 : 4;
    auto engine = Engine::create(es, model);
    EXPECT_TRUE(engine.isOk());
    Engine& e = **engine;  // free field: the direct sound alone
    EXPECT_TRUE(e.setListener({1, 0, 0}, {{0, 0, -1}, {0, 1, 0}}).isOk());
    std::vector<float> in(n, 0.0f), out(channels * n, 0.0f), scratch(channels * block);
    Pcg32 rng(5, 3);
    for (size_t i = 0; i < burst; ++i) in[i] = rng.uniform() - 0.5f;
    const float* inputs[1] = {nullptr};
    float* outs[4];
    auto play = [&](size_t blocks) {
      for (size_t c = 0; c < channels; ++c) outs[c] = scratch.data() + c * block;
      for (size_t b = 0; b < blocks; ++b) e.process(inputs, outs, block);
    };
    if (used) {
      auto last = e.addSource({});
      EXPECT_TRUE(last.isOk());
      EXPECT_TRUE(e.setSourcePosition(*last, {-3, 0, -34.17}).isOk());
      inputs[0] = in.data();  // its first 256 frames of noise
      play(1);
      inputs[0] = nullptr;
      EXPECT_TRUE(e.removeSource(*last).isOk());
      play(size_t(0.6 * kFs / block));  // its sound in flight and ring-out over
    }
    Result<uint32_t> id = add == Add::kAt ? e.addSource(ss, at, facing) : e.addSource(ss);
    EXPECT_TRUE(id.isOk());
    if (!id.isOk()) return out;
    EXPECT_EQ(*id, 0u);
    if (add == Add::kPlaced) {
      EXPECT_TRUE(e.setSourcePosition(*id, at).isOk());
      EXPECT_TRUE(e.setSourceOrientation(*id, facing).isOk());
    }
    for (size_t off = 0; off < n; off += block) {
      if (add == Add::kThenMoved && off == block) {  // the audio thread ran between the two calls
        EXPECT_TRUE(e.setSourcePosition(*id, at).isOk());
        EXPECT_TRUE(e.setSourceOrientation(*id, facing).isOk());
      }
      inputs[0] = in.data() + off;
      for (size_t c = 0; c < channels; ++c) outs[c] = out.data() + c * n + off;
      e.process(inputs, outs, std::min(block, n - off));
    }
    return out;
  };
  auto differenceDb = [](const std::vector<float>& a, const std::vector<float>& b) {
    double d = 0;
    for (size_t i = 0; i < a.size(); ++i) d += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    return energyToDb(d / energy(b.data(), b.size()) + 1e-30);
  };
  for (OutputFormat format : {OutputFormat::kBinaural, OutputFormat::kAmbisonic}) {
    const char* name = format == OutputFormat::kBinaural ? "binaural" : "ambisonic";
    const std::vector<float> placed = render(format, false, Add::kPlaced);
    ASSERT_GT(energy(placed.data(), placed.size()), 0.0);
    for (bool used : {false, true}) {
      const double atDb = differenceDb(render(format, used, Add::kAt), placed);
      const double movedDb = differenceDb(render(format, used, Add::kThenMoved), placed);
      std::printf("%s, %s slot: added where it is %.1f dB from the reference, added then moved %.1f dB\n", name,
                  used ? "a used" : "a fresh", atDb, movedDb);
      EXPECT_LT(atDb, -100.0) << name << (used ? ", used slot" : ", fresh slot");
      // (Binaural -44 dB, ambisonic -22 dB: a voice reads its delay line
      // at the output's latency, which with binaural output is longer by
      // a block and the decoder's delay, so the first block is mostly read
      // after the move.)
      EXPECT_GT(movedDb, -60.0) << name << ": its first block played from elsewhere (what the overload avoids)";
    }
    // Added without a place: at the origin (facing (0, 0, -1)), whatever
    // the slot held before.
    const std::vector<float> origin = render(format, false, Add::kOrigin);
    const double originDb = differenceDb(render(format, true, Add::kOrigin), origin);
    std::printf("%s: added without a place into a used slot, %.1f dB from one at the origin\n", name, originDb);
    EXPECT_LT(originDb, -100.0) << name;
    EXPECT_GT(differenceDb(origin, placed), -20.0) << name << ": the origin and `at` sound different";
  }
}

// A pose is set whole and read whole: two game threads store poses (each
// of nine equal numbers: 1 or 2 from one thread, 3 or 4 from the other) as
// fast as they can while the taker (the audio thread's part) takes them
// and a third reads them with load(): every take and load is one store's
// nine numbers, and the take after the writers stop is the last store.
// The same stores into nine separate atomics (how the engine kept poses)
// are read mixed, printed for scale: that depends on the scheduling, so it
// is not asserted.
TEST(LatestValues, ATakerGetsOneStoreWholeWhileOtherThreadsStore) {
  using Pose = std::array<double, 9>;
  auto filled = [](double x) {
    Pose p;
    p.fill(x);
    return p;
  };
  auto whole = [](const Pose& p) {
    bool ok = p[0] == 1.0 || p[0] == 2.0 || p[0] == 3.0 || p[0] == 4.0;
    for (double x : p) ok = ok && x == p[0];
    return ok;
  };
  LatestValues<Pose> pose(filled(1.0));
  std::atomic<double> separate[9];
  for (auto& x : separate) x.store(1.0);
  std::atomic<bool> stop{false};
  auto writer = [&](double a, double b) {
    for (uint64_t i = 0; !stop.load(std::memory_order_relaxed); ++i) {
      const double x = i % 2 ? b : a;
      pose.store(filled(x));
      for (auto& v : separate) v.store(x, std::memory_order_relaxed);
    }
  };
  std::atomic<uint64_t> loads{0}, loadsMixed{0};
  auto loader = [&] {
    while (!stop.load(std::memory_order_relaxed)) {
      loadsMixed.fetch_add(whole(pose.load()) ? 0 : 1, std::memory_order_relaxed);
      loads.fetch_add(1, std::memory_order_relaxed);
    }
  };
  std::thread w1(writer, 1.0, 2.0), w2(writer, 3.0, 4.0), l(loader);
  uint64_t mixed = 0, changed = 0, separateMixed = 0, takes = 0;
  const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(400);
  double last = 1.0;
  while (std::chrono::steady_clock::now() < until) {
    for (int k = 0; k < 256; ++k, ++takes) {
      const Pose& p = pose.take();
      mixed += whole(p) ? 0 : 1;
      changed += p[0] != last ? 1 : 0;
      last = p[0];
      double first = separate[0].load(std::memory_order_relaxed);
      for (int i = 1; i < 9; ++i) separateMixed += separate[i].load(std::memory_order_relaxed) != first ? 1 : 0;
    }
  }
  stop = true;
  w1.join();
  w2.join();
  l.join();
  std::printf("%llu takes (%llu of a newer store), %llu mixed; %llu loads, %llu mixed; nine separate atomics: "
              "%llu mixed numbers\n",
              (unsigned long long)takes, (unsigned long long)changed, (unsigned long long)mixed,
              (unsigned long long)loads.load(), (unsigned long long)loadsMixed.load(),
              (unsigned long long)separateMixed);
  EXPECT_GT(changed, 0u) << "the taker saw the stores";
  EXPECT_EQ(mixed, 0u) << "a take is one store's";
  EXPECT_GT(loads.load(), 0u);
  EXPECT_EQ(loadsMixed.load(), 0u) << "a load is one store's";
  EXPECT_EQ(pose.take(), pose.load()) << "the take after the last store is that store";
  pose.store(filled(7.0));
  EXPECT_EQ(pose.take(), filled(7.0));
  EXPECT_EQ(pose.take(), filled(7.0)) << "taken again, unchanged";
}

// update() changes numbers in place under the writers' lock: two threads
// each adding 1 to both of two numbers 1,000,000 times leave 2,000,000 in
// each (none lost), and the taker meanwhile sees the two equal.
TEST(LatestValues, UpdatesFromTwoThreadsAreNotLost) {
  LatestValues<std::array<double, 2>> counts({0.0, 0.0});
  constexpr int kEach = 1000000;
  std::atomic<bool> go{false}, done{false};
  auto add = [&] {
    while (!go.load()) std::this_thread::yield();  // both at once
    for (int i = 0; i < kEach; ++i)
      counts.update([](std::array<double, 2>& v) {
        v[0] += 1;
        v[1] += 1;
      });
  };
  uint64_t unequal = 0, takes = 0;
  std::thread taker([&] {
    while (!done.load()) {
      const auto& v = counts.take();
      ++takes;
      unequal += v[0] != v[1] ? 1 : 0;
    }
  });
  std::thread a(add), b(add);
  go = true;
  a.join();
  b.join();
  done = true;
  taker.join();
  const auto last = counts.load();
  std::printf("%llu takes while two threads updated\n", (unsigned long long)takes);
  EXPECT_EQ(last[0], 2.0 * kEach);
  EXPECT_EQ(last[1], 2.0 * kEach);
  EXPECT_EQ(unequal, 0u);
  EXPECT_EQ(counts.take(), last);
}

// Blocks each race plays: 27 s of audio, about a second of the audio
// thread's time; a fifth under ThreadSanitizer (its ~40x slower threads
// race all the same, and the suite has a time limit).
#if defined(__SANITIZE_THREAD__)
constexpr size_t kRaceBlocks = 8000;
#else
constexpr size_t kRaceBlocks = 40000;
#endif

// A source played 10 m from the listener (free field: the direct sound
// alone) for `blocks` blocks of 32 frames of noise, added with calls[0].
// With `racing`, two game threads set calls in turn as fast as they can
// (and a third sets the source's gain alone to `gainDb`, if given) while a
// fourth reads the controls back and counts those `whole` rejects.
struct ControlsRace {
  std::vector<float> out;  // the ears' blocks in turn
  uint64_t stores = 0, reads = 0, mixed = 0;
};
ControlsRace playWhileControlsAreSet(const std::vector<SourceSettings>& calls, bool glides, size_t blocks,
                                     bool racing, std::optional<double> gainDb,
                                     const std::function<bool(const SourceSettings&)>& whole) {
  constexpr size_t kBlock = 32;
  ControlsRace race;
  auto model = test::ku100();
  EXPECT_TRUE(model);
  if (!model) return race;
  EngineSettings es = test::fastSettings();
  es.maxSources = 1;
  es.maxIrSeconds = 0.2;
  es.blockFrames = kBlock;
  es.glideGameUpdates = glides;
  auto engine = Engine::create(es, model);
  EXPECT_TRUE(engine.isOk());
  if (!engine.isOk()) return race;
  Engine& e = **engine;
  EXPECT_TRUE(e.setListener({0, 0, 0}, {{0, 0, -1}, {0, 1, 0}}).isOk());
  auto id = e.addSource(calls[0], {10, 0, 0}, {-1, 0, 0});
  EXPECT_TRUE(id.isOk());
  if (!id.isOk()) return race;
  std::vector<float> in(kBlock);
  race.out.assign(2 * kBlock * blocks, 0.0f);
  Pcg32 rng(11, 2);
  std::atomic<bool> stop{false};
  std::atomic<uint64_t> stores{0}, reads{0}, mixed{0};
  auto writer = [&](size_t first) {
    for (size_t k = first; !stop.load(std::memory_order_relaxed); ++k) {
      EXPECT_TRUE(e.setSourceControls(*id, calls[k % calls.size()]).isOk());
      stores.fetch_add(1, std::memory_order_relaxed);
    }
  };
  auto gainWriter = [&] {
    while (!stop.load(std::memory_order_relaxed)) {
      EXPECT_TRUE(e.setSourceGainDb(*id, *gainDb).isOk());
      stores.fetch_add(1, std::memory_order_relaxed);
    }
  };
  auto reader = [&] {
    while (!stop.load(std::memory_order_relaxed)) {
      auto got = e.sourceControls(*id);
      EXPECT_TRUE(got.isOk());
      if (!got.isOk()) return;
      mixed.fetch_add(whole(*got) ? 0 : 1, std::memory_order_relaxed);
      reads.fetch_add(1, std::memory_order_relaxed);
    }
  };
  std::vector<std::thread> threads;
  if (racing) {
    threads.emplace_back(writer, 1);
    threads.emplace_back(writer, 2);
    if (gainDb) threads.emplace_back(gainWriter);
    threads.emplace_back(reader);
  }
  const float* inputs[1] = {in.data()};
  for (size_t b = 0; b < blocks; ++b) {
    for (auto& x : in) x = rng.uniform() - 0.5f;
    float* outs[2] = {race.out.data() + 2 * b * kBlock, race.out.data() + (2 * b + 1) * kBlock};
    e.process(inputs, outs, kBlock);
  }
  stop = true;
  for (auto& t : threads) t.join();
  race.stores = stores.load();
  race.reads = reads.load();
  race.mixed = mixed.load();
  if (racing) {
    std::printf("%llu stores on game threads, %llu read back (%llu mixed)\n", (unsigned long long)race.stores,
                (unsigned long long)race.reads, (unsigned long long)race.mixed);
    EXPECT_GT(race.stores, 0u);
    EXPECT_GT(race.reads, 0u);
  }
  return race;
}

// A source's controls are set whole and read whole. Three distance curves
// that all give full gain 10 m away (a linear curve flat at rolloff 0, an
// inverse curve still flat short of its 20 m minimum, a table) are set in
// turn by two game threads as fast as they can while the audio thread
// plays the source 10 m away and a third thread reads the controls back.
// Read whole, every block is the one the first curve alone gives, bit for
// bit; a read that mixed two calls is not (the linear curve with the
// others' rolloff 1 is silent there, the inverse curve with the linear
// one's 1 m minimum -20 dB). Each number an atomic of its own, mixes were
// heard and read back (the counts in the commit that made Controls).
TEST(Engine, ControlsSetOnGameThreadsAreHeardAndReadWhole) {
  std::vector<SourceSettings> curves(3);
  curves[0].distance.model = DistanceModel::kLinear;
  curves[0].distance.minDistance = 1.0;
  curves[0].distance.maxDistance = 2.0;
  curves[0].distance.rolloff = 0.0;
  curves[1].distance.model = DistanceModel::kInverse;
  curves[1].distance.minDistance = 20.0;
  curves[1].distance.maxDistance = 100.0;
  curves[1].distance.rolloff = 1.0;
  curves[2].distance.model = DistanceModel::kTable;
  curves[2].distance.minDistance = 1.0;
  curves[2].distance.maxDistance = 2.0;
  curves[2].distance.rolloff = 1.0;
  curves[2].distance.table = {{0.5, 1.0}, {15.0, 1.0}, {16.0, 0.5}};
  for (const auto& c : curves) ASSERT_EQ(distanceGain(c.distance, 10.0), 1.0);
  auto whole = [&](const SourceSettings& got) {
    const DistanceCurve& d = got.distance;
    for (const auto& c : curves)
      if (d.model == c.distance.model && d.minDistance == c.distance.minDistance &&
          d.maxDistance == c.distance.maxDistance && d.rolloff == c.distance.rolloff &&
          (d.model != DistanceModel::kTable || d.table == c.distance.table))
        return true;
    return false;
  };
  const size_t blocks = kRaceBlocks;
  const ControlsRace alone = playWhileControlsAreSet(curves, true, blocks, false, std::nullopt, whole);
  ASSERT_GT(energy(alone.out.data(), alone.out.size()), 0.0);
  const ControlsRace raced = playWhileControlsAreSet(curves, true, blocks, true, std::nullopt, whole);
  ASSERT_EQ(raced.out.size(), alone.out.size());
  const size_t block = alone.out.size() / blocks;
  size_t blocksDiffering = 0;
  for (size_t b = 0; b < blocks; ++b)
    blocksDiffering += std::equal(alone.out.begin() + std::ptrdiff_t(b * block),
                                  alone.out.begin() + std::ptrdiff_t((b + 1) * block),
                                  raced.out.begin() + std::ptrdiff_t(b * block))
                           ? 0
                           : 1;
  std::printf("%zu of %zu blocks differ from the first curve's alone\n", blocksDiffering, blocks);
  EXPECT_EQ(blocksDiffering, 0u) << "the audio thread heard a mix of two calls' controls";
  EXPECT_EQ(raced.mixed, 0u) << "sourceControls() read a mix of two calls' controls";
}

// The source's gain is read with the other controls. A game fades from a
// source's direct sound down (-120 dB) to the whole source down (-120 dB)
// and back, two game threads in turn, while a third sets the gain alone
// (-120 dB): each call is -120 dB, and so is every block heard (the glides
// off, so that every block has a call's product of the gains, not a path
// between two). A block that took one call's source gain (0 dB) and the
// other's direct gain (0 dB) is heard at full level.
TEST(Engine, GainsSetOnGameThreadsAreHeardWhole) {
  std::vector<SourceSettings> calls(2);
  calls[0].gainDb = -120.0;
  calls[1].directGainDb = -120.0;
  auto whole = [](const SourceSettings& got) {
    return (got.gainDb == -120.0 && got.directGainDb == 0.0) || (got.gainDb == -120.0 && got.directGainDb == -120.0) ||
           (got.gainDb == 0.0 && got.directGainDb == -120.0);
  };
  const size_t blocks = kRaceBlocks;
  std::vector<SourceSettings> unity(1);
  const ControlsRace full = playWhileControlsAreSet(unity, false, blocks, false, std::nullopt, whole);
  const ControlsRace raced = playWhileControlsAreSet(calls, false, blocks, true, -120.0, whole);
  ASSERT_EQ(raced.out.size(), full.out.size());
  const size_t block = full.out.size() / blocks;
  double worstDb = -400.0;
  size_t loudBlocks = 0, compared = 0;
  for (size_t b = 0; b < blocks; ++b) {
    const double reference = energy(full.out.data() + b * block, block);
    if (!(reference > 0)) continue;  // before the direct sound arrives
    ++compared;
    const double db = energyToDb(energy(raced.out.data() + b * block, block) / reference + 1e-30);
    worstDb = std::max(worstDb, db);
    loudBlocks += db > -60.0 ? 1 : 0;
  }
  std::printf("the loudest block %.1f dB from full level; %zu of %zu blocks above -60 dB\n", worstDb, loudBlocks,
              blocks);
  EXPECT_GT(compared, blocks * 9 / 10) << "the source at full level plays (else nothing is compared)";
  EXPECT_EQ(loudBlocks, 0u) << "a block heard one call's source gain with another's direct gain";
  EXPECT_EQ(raced.mixed, 0u) << "sourceControls() read a mix of two calls' gains";
}

// The direct path's occlusion, as simulations write it and the game reads
// it (and the audio thread takes it): whole. A 4 x 4 m gauze in the plane
// z = -1 lets sqrt(t_b) = 0.1 .. 0.7 of each band's pressure through; a
// simulation thread moves the source from behind it (0, 0, -3) to the clear
// side (0, 0, 3) and back and simulates each time, while the audio thread
// plays and a game thread reads the occlusion back: every read is one of
// the two states (or the blocked one the known answers below leave until
// the race's first simulation), never some bands of one with the rest of
// another's. Known answers along the way: the gauze's values
// (air excluded), clear is all 1, without transmission nothing gets
// through, and a new source in the slot is clear and not simulated until
// its first simulation.
TEST(Engine, OcclusionIsReportedWholeAsSimulated) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  auto materials = std::make_shared<MaterialTable>();
  Material gauze;
  gauze.name = "gauze";
  gauze.absorption = filledBands(0.6f);
  gauze.transmission = {0.01f, 0.04f, 0.09f, 0.16f, 0.25f, 0.36f, 0.49f};
  TriangleMesh quad;
  quad.positions = {{-2, -2, -1}, {2, -2, -1}, {2, 2, -1}, {-2, 2, -1}};
  quad.triangles = {{0, 1, 2}, {0, 2, 3}};
  quad.materialIds.assign(2, materials->add(gauze));
  auto tracer = RayTracer::create(quad);
  ASSERT_TRUE(tracer.isOk());
  EngineSettings es = test::fastSettings();
  es.simulation.rays = 64;
  es.simulation.bounces = 2;
  es.simulation.imageSourceOrder = 1;
  es.maxIrSeconds = 0.1;
  es.maxSources = 1;
  es.threads = 1;
  es.blockFrames = 64;
  auto engine = Engine::create(es, model);
  ASSERT_TRUE(engine.isOk());
  Engine& e = **engine;
  e.setScene(std::move(tracer.value()), materials);
  ASSERT_TRUE(e.setListener({0, 0, 0}, {{0, 0, -1}, {0, 1, 0}}).isOk());
  SourceSettings ss;
  ss.transmission = true;
  auto id = e.addSource(ss, {0, 0, -3}, {0, 0, 1});
  ASSERT_TRUE(id.isOk());
  auto occlusion = [&] {
    auto got = e.sourceOcclusion(*id);
    EXPECT_TRUE(got.isOk());
    return got.isOk() ? *got : SourceOcclusion{};
  };
  const SourceOcclusion before = occlusion();
  EXPECT_FALSE(before.simulated);
  EXPECT_TRUE(before.audible);
  for (double t : before.transmission) EXPECT_EQ(t, 1.0);
  EXPECT_FALSE(e.sourceOcclusion(*id + 1).isOk());

  ASSERT_TRUE(e.simulate().isOk());
  const SourceOcclusion behind = occlusion();
  EXPECT_TRUE(behind.simulated);
  EXPECT_TRUE(behind.audible);
  for (int b = 0; b < kNumBands; ++b)
    EXPECT_EQ(behind.transmission[b], std::sqrt(double(gauze.transmission[b]))) << "band " << b;
  ASSERT_TRUE(e.setSourcePosition(*id, {0, 0, 3}).isOk());
  ASSERT_TRUE(e.simulate().isOk());
  const SourceOcclusion clear = occlusion();
  EXPECT_TRUE(clear.simulated && clear.audible);
  for (double t : clear.transmission) EXPECT_EQ(t, 1.0);
  ss.transmission = false;
  ASSERT_TRUE(e.setSourceControls(*id, ss).isOk());
  ASSERT_TRUE(e.setSourcePosition(*id, {0, 0, -3}).isOk());
  ASSERT_TRUE(e.simulate().isOk());
  const SourceOcclusion blocked = occlusion();
  EXPECT_TRUE(blocked.simulated);
  EXPECT_FALSE(blocked.audible);
  for (double t : blocked.transmission) EXPECT_EQ(t, 0.0);
  ss.transmission = true;
  ASSERT_TRUE(e.setSourceControls(*id, ss).isOk());

  auto sameAs = [](const SourceOcclusion& a, const SourceOcclusion& b) {
    return a.transmission == b.transmission && a.audible == b.audible && a.simulated == b.simulated;
  };
  std::atomic<bool> stop{false};
  std::atomic<uint64_t> simulations{0}, reads{0}, mixed{0};
  std::thread simulation([&] {
    for (int k = 0; !stop.load(std::memory_order_relaxed); ++k) {
      EXPECT_TRUE(e.setSourcePosition(*id, {0, 0, k % 2 ? 3.0 : -3.0}).isOk());
      EXPECT_TRUE(e.simulate().isOk());
      simulations.fetch_add(1, std::memory_order_relaxed);
    }
  });
  std::thread reader([&] {
    while (!stop.load(std::memory_order_relaxed)) {
      const SourceOcclusion got = occlusion();
      mixed.fetch_add(sameAs(got, behind) || sameAs(got, clear) || sameAs(got, blocked) ? 0 : 1,
                      std::memory_order_relaxed);
      reads.fetch_add(1, std::memory_order_relaxed);
    }
  });
  std::vector<float> in(es.blockFrames), l(es.blockFrames), r(es.blockFrames);
  Pcg32 rng(5, 9);
  const float* inputs[1] = {in.data()};
  bool finite = true;
  const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(1500);
  while (simulations.load() < 200 && std::chrono::steady_clock::now() < until) {
    for (auto& x : in) x = rng.uniform() - 0.5f;
    e.process(inputs, l.data(), r.data(), in.size());
    for (size_t k = 0; k < in.size(); ++k) finite = finite && std::isfinite(l[k]) && std::isfinite(r[k]);
  }
  stop = true;
  simulation.join();
  reader.join();
  std::printf("%llu simulations, %llu reads (%llu mixed)\n", (unsigned long long)simulations.load(),
              (unsigned long long)reads.load(), (unsigned long long)mixed.load());
  EXPECT_TRUE(finite);
  EXPECT_GT(simulations.load(), 10u);
  EXPECT_GT(reads.load(), 0u);
  EXPECT_EQ(mixed.load(), 0u) << "a read took some bands of one simulation and the rest of another's";

  // A new source in the slot: clear, not simulated, until its own simulation.
  ASSERT_TRUE(e.removeSource(*id).isOk());
  auto next = e.addSource(ss, {0, 0, -3}, {0, 0, 1});
  ASSERT_TRUE(next.isOk());
  ASSERT_EQ(*next, *id);  // the one slot
  const SourceOcclusion fresh = occlusion();
  EXPECT_TRUE(sameAs(fresh, before));
  ASSERT_TRUE(e.simulate().isOk());
  EXPECT_TRUE(sameAs(occlusion(), behind));
}

// A game fades a source by setting its gain once a frame (60 Hz) while the
// audio thread runs blocks of 256: each step was ramped over the next block
// and held for the two after it, a 60 Hz staircase in level (a 1 kHz
// tone faded at 100 dB/s had -28.4 dB of its energy off the tone, at
// 30 dB/s -38.9 dB; set every block, -48 and -60 dB). The gain glides as
// the poses do (GainGlide): within 4 dB of the every-block fade. So do the
// other controls a game sets once a frame: the direct sound's gain (a
// game's own occlusion), the reflections' gain (a zone's reverberation
// faded), and the direction a directional source faces (a character
// turning), whose level toward the listener made the same staircase.
TEST(Engine, ControlsSetAtTheGamesFrameRateAreSmooth) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room;
  const double f0 = 1000.0;
  enum class Control { kGain, kDirectGain, kReflectionsGain, kFacing };
  // `rate`: dB/s for the gains, degrees/s for the facing.
  auto render = [&](Control control, size_t block, size_t gameFrames, double rate, size_t n) {
    EngineSettings es = test::fastSettings();
    auto engine = Engine::create(es, model);
    EXPECT_TRUE(engine.isOk());
    Engine& e = **engine;  // free field but for the reflections' case
    SourceSettings ss;
    if (control == Control::kReflectionsGain) ss.directGainDb = -120.0;  // the reflections alone
    if (control == Control::kFacing) ss.directivityAlpha = 0.5;          // a cardioid
    auto id = e.addSource(ss);
    EXPECT_TRUE(id.isOk());
    if (control == Control::kReflectionsGain) {
      e.setScene(room.tracer, room.materials);
      EXPECT_TRUE(e.setSourcePosition(*id, {2, 3, 1.5}).isOk());
      EXPECT_TRUE(e.setListener({7, 4, 1.6}, {{1, 0, 0}, {0, 0, 1}}).isOk());
      EXPECT_TRUE(e.simulate().isOk());
    } else {
      EXPECT_TRUE(e.setSourcePosition(*id, {-1, 0, -3}).isOk());
    }
    std::vector<float> in(n), l(n, 0.0f), r(n, 0.0f);
    for (size_t i = 0; i < n; ++i) in[i] = float(0.5 * std::sin(2 * kPi * f0 * double(i) / kFs));
    std::vector<const float*> inputs(es.maxSources, nullptr);
    size_t next = 0;
    for (size_t off = 0; off < n; off += block) {
      for (; next <= off; next += gameFrames) {
        const double t = double(next) / kFs;
        SourceSettings now = ss;
        switch (control) {
          case Control::kGain:
            EXPECT_TRUE(e.setSourceGainDb(*id, -rate * t).isOk());
            break;
          case Control::kDirectGain:
            now.directGainDb = -rate * t;
            EXPECT_TRUE(e.setSourceControls(*id, now).isOk());
            break;
          case Control::kReflectionsGain:
            now.reflectionsGainDb = -rate * t;
            EXPECT_TRUE(e.setSourceControls(*id, now).isOk());
            break;
          case Control::kFacing: {
            // From facing the listener (at (1, 0, 3) from the source) about
            // the vertical, turning away.
            const double a = std::atan2(1.0, 3.0) + rate * t * kPi / 180.0;
            EXPECT_TRUE(e.setSourceOrientation(*id, {std::sin(a), 0.0, std::cos(a)}).isOk());
            break;
          }
        }
      }
      inputs[*id] = in.data() + off;
      e.process(inputs.data(), l.data() + off, r.data() + off, std::min(block, n - off));
    }
    return l;
  };
  struct Case {
    Control control;
    const char* name;
    double rate;
    const char* unit;
    double seconds, from, to;  // rendered, and the window measured
  };
  const Case cases[] = {
      {Control::kGain, "source gain", 30.0, "dB/s", 0.4, 0.1, 0.35},
      {Control::kGain, "source gain", 100.0, "dB/s", 0.4, 0.1, 0.35},
      {Control::kDirectGain, "direct gain", 100.0, "dB/s", 0.4, 0.1, 0.35},
      {Control::kReflectionsGain, "reflections gain", 30.0, "dB/s", 0.8, 0.3, 0.8},
      {Control::kFacing, "cardioid facing", 180.0, "deg/s", 0.4, 0.1, 0.35},
  };
  for (const Case& c : cases) {
    const size_t n = size_t(std::lround(c.seconds * kFs)), from = size_t(std::lround(c.from * kFs)),
                 m = size_t(std::lround((c.to - c.from) * kFs));
    const std::vector<float> everyBlock = render(c.control, 256, 256, c.rate, n),
                             gameRate = render(c.control, 256, 800, c.rate, n);
    const double ideal = offToneShareDb(everyBlock.data() + from, m, f0, 20.0);
    const double heard = offToneShareDb(gameRate.data() + from, m, f0, 20.0);
    std::printf("%s at %.0f %s: energy off the tone, set every block %.1f dB, at 60 Hz %.1f dB\n", c.name, c.rate,
                c.unit, ideal, heard);
    EXPECT_LT(heard, ideal + 4.0) << c.name;
  }
}

// Round robin: simulate(1) visits the active sources in turn.
TEST(Engine, RoundRobinSimulatesOneSourceAtATime) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room;
  auto engine = Engine::create(test::fastSettings(), model);
  ASSERT_TRUE(engine.isOk());
  Engine& e = **engine;
  e.setScene(room.tracer, room.materials);
  for (int i = 0; i < 3; ++i) {
    auto id = e.addSource({});
    ASSERT_TRUE(id.isOk());
    ASSERT_TRUE(e.setSourcePosition(*id, {2.0 + i, 3, 1.5}).isOk());
  }
  for (int k = 0; k < 4; ++k) {
    ASSERT_TRUE(e.simulate(1).isOk());
    EXPECT_EQ(e.lastSimulation().sourcesSimulated, 1u);
  }
  ASSERT_TRUE(e.simulate().isOk());
  EXPECT_EQ(e.lastSimulation().sourcesSimulated, 3u);
}

// Issue 17: a NaN, Inf or absurd input sample mutes its source for that
// block and poisons nothing: the output is bit for bit the output of the same
// run with that block silent, before and after, for a moving (per-block
// direct) and a static (direct in the IR) source; the events are counted.
TEST(Engine, NonFiniteInputMutesItsBlockAndPoisonsNothing) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room;
  const size_t block = 256, blocks = 60, bad = 20;
  auto run = [&](DirectMode mode, float poison, bool silenceInstead, ContainmentStats* stats) {
    EngineSettings es = test::fastSettings();
    auto engine = Engine::create(es, model);
    EXPECT_TRUE(engine.isOk());
    Engine& e = **engine;
    e.setScene(room.tracer, room.materials);
    SourceSettings ss;
    ss.direct = mode;
    auto id = e.addSource(ss);
    EXPECT_TRUE(e.setSourcePosition(*id, {2, 3, 1.5}).isOk());
    EXPECT_TRUE(e.setListener({7, 4, 1.6}, {{1, 0, 0}, {0, 0, 1}}).isOk());
    EXPECT_TRUE(e.simulate().isOk());
    std::vector<float> dry(block * blocks), l(block * blocks), r(block * blocks);
    Pcg32 rng(4, 4);
    for (float& v : dry) v = rng.uniform() - 0.5f;
    if (silenceInstead) std::fill(dry.begin() + bad * block, dry.begin() + (bad + 1) * block, 0.0f);
    else dry[bad * block + 77] = poison;
    std::vector<const float*> inputs(es.maxSources, nullptr);
    for (size_t b = 0; b < blocks; ++b) {
      inputs[*id] = dry.data() + b * block;
      e.process(inputs.data(), l.data() + b * block, r.data() + b * block, block);
    }
    *stats = e.containment();
    l.insert(l.end(), r.begin(), r.end());
    return l;
  };
  for (DirectMode mode : {DirectMode::kPerBlock, DirectMode::kInImpulseResponse}) {
    ContainmentStats clean{}, poisoned{};
    const std::vector<float> reference = run(mode, 0.0f, true, &clean);
    EXPECT_EQ(clean.mutedSourceChunks, 0u);
    double energy = 0;
    for (float v : reference) energy += double(v) * v;
    ASSERT_GT(energy, 0.0);
    for (float poison : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), -3e30f}) {
      const std::vector<float> out = run(mode, poison, false, &poisoned);
      EXPECT_EQ(poisoned.mutedSourceChunks, 1u) << poison;
      EXPECT_EQ(poisoned.clearedOutputChunks, 0u);
      ASSERT_EQ(out.size(), reference.size());
      size_t differ = 0;
      for (size_t i = 0; i < out.size(); ++i) differ += (out[i] == reference[i]) ? 0 : 1;  // NaN differs too
      EXPECT_EQ(differ, 0u) << "poison " << poison << (mode == DirectMode::kPerBlock ? " per block" : " in IR");
    }
  }
}

TEST(Engine, BadArgumentsAreErrors) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  EngineSettings es = test::fastSettings();
  es.sampleRateHz = 44100;
  EXPECT_FALSE(Engine::create(es, model).isOk()) << "rate differs from the HRTF model";
  EXPECT_FALSE(Engine::create(test::fastSettings(), nullptr).isOk());
  es = test::fastSettings();
  es.simulation.rays = 100000000;  // ~12 GiB of trace state: refused now, not at every simulate()
  auto many = Engine::create(es, model);
  ASSERT_FALSE(many.isOk());
  EXPECT_EQ(many.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(many.status().message().find("simulation.rays 100000000"), std::string::npos) << many.status().message();
  EXPECT_NE(many.status().message().find("--max-memory"), std::string::npos) << many.status().message();
  for (double cap : {-1.0, 601.0, std::nan("")}) {
    es = test::fastSettings();
    es.simulation.maxLengthSeconds = cap;  // not replaced by the engine's own cut: an error
    auto capped = Engine::create(es, model);
    ASSERT_FALSE(capped.isOk()) << cap;
    EXPECT_NE(capped.status().message().find("maxLengthSeconds"), std::string::npos) << capped.status().message();
  }
  es = test::fastSettings();
  es.simulation.maxLengthSeconds = 0.5;  // below the cut (1.5 s): kept
  auto shorter = Engine::create(es, model);
  ASSERT_TRUE(shorter.isOk());
  EXPECT_EQ((*shorter)->settings().simulation.maxLengthSeconds, 0.5);
  es.simulation.maxLengthSeconds = 0;  // none: the cut and its fade
  auto cut = Engine::create(es, model);
  ASSERT_TRUE(cut.isOk());
  EXPECT_DOUBLE_EQ((*cut)->settings().simulation.maxLengthSeconds, 1.51);
  es = test::fastSettings();
  es.maxSources = 2;
  auto engine = Engine::create(es, model);
  ASSERT_TRUE(engine.isOk());
  Engine& e = **engine;
  EXPECT_FALSE(e.setSourcePosition(0, {0, 0, 0}).isOk()) << "no such source";
  auto a = e.addSource({});
  auto b = e.addSource({});
  ASSERT_TRUE(a.isOk() && b.isOk());
  EXPECT_FALSE(e.addSource({}).isOk()) << "all slots in use";
  EXPECT_FALSE(e.setSourcePosition(*a, {0, std::nan(""), 0}).isOk());
  EXPECT_FALSE(e.setSourceGainDb(*a, 1000).isOk());
  EXPECT_FALSE(e.setListener({0, 0, 0}, {{0, 0, -1}, {0, 0, 1}}).isOk()) << "parallel forward and up";
  EXPECT_TRUE(e.removeSource(*a).isOk());
  EXPECT_FALSE(e.removeSource(*a).isOk()) << "removed twice";
  EXPECT_TRUE(e.addSource({}).isOk()) << "the slot is free again";
}

#if defined(__GLIBC__)
// In use: in the heap's arenas and in chunks of their own (mmap).
double heapBytes() {
  const struct mallinfo2 m = mallinfo2();
  return double(m.uordblks) + double(m.hblkhd);
}
#endif

// Sets the memory limit (as --max-memory does) until it goes out of scope.
struct MemoryLimitFor {
  explicit MemoryLimitFor(uint64_t bytes) { setDefaultMaxMemoryBytes(bytes); }
  ~MemoryLimitFor() { setDefaultMaxMemoryBytes(0); }
};

// Binaural reflections (each source keeps its whole IR) of 2 s, IRs as long
// as the convolver takes.
EngineSettings slotTestSettings() {
  EngineSettings es = test::fastSettings();
  es.ambisonicOrder = 0;
  es.maxIrSeconds = 2;
  es.simulation.lengthSeconds = 2;
  es.maxSources = 64;
  es.traceMode = TraceMode::kShared;  // one or three sources: the same listener's paths kept
  return es;
}

// A slot's state is allocated when a source first uses it; the slots in
// use, each with what it may hold (sourceSlotBytes: its voice, convolution
// state, three IRs in the convolver and the IR kept for sourceIr()), stay
// within the memory limit: the source past it is refused before its slot
// allocates, a released slot is reused, a higher limit admits more.
TEST(Engine, SourceSlotsPastTheMemoryLimitAreRefusedBeforeTheyAllocate) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  auto engine = Engine::create(slotTestSettings(), model);
  ASSERT_TRUE(engine.isOk()) << engine.status().message();
  Engine& e = **engine;
  const size_t slot = e.sourceSlotBytes();
  const size_t irBytes = size_t(2 * kFs) * 2 * sizeof(float);
  EXPECT_GT(slot, 4 * irBytes) << "three IRs in the convolver and the one kept, at least their samples each";

  MemoryLimitFor limit(uint64_t(3.5 * double(slot)));
  std::vector<uint32_t> ids;
  for (int i = 0; i < 3; ++i) {
    auto id = e.addSource({});
    ASSERT_TRUE(id.isOk()) << i << ": " << id.status().message();
    ids.push_back(*id);
  }
  auto refused = e.addSource({});
  ASSERT_FALSE(refused.isOk()) << "a fourth slot passes 3.5 slots' bytes";
  EXPECT_EQ(refused.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(refused.status().message().find("4 source slots"), std::string::npos) << refused.status().message();
  EXPECT_NE(refused.status().message().find("--max-memory"), std::string::npos) << refused.status().message();
  ASSERT_TRUE(e.removeSource(ids[1]).isOk());
  EXPECT_TRUE(e.addSource({}).isOk()) << "a released slot's state is reused, not allocated";
  setDefaultMaxMemoryBytes(uint64_t(6.5 * double(slot)));  // (`limit` restores the default)
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(e.addSource({}).isOk()) << "under a higher limit: " << i;
  EXPECT_FALSE(e.addSource({}).isOk()) << "a seventh slot";
}

// EngineSettings::keepSourceIrs false (earshot render's): a slot keeps
// nothing for sourceIr(), its estimate is the kept IR's samples less
// (binaural), or the kept histogram's (shared tail); sourceIr() gives no
// IR, sourceIrInfo() still counts, and the source's reflections play.
TEST(Engine, WithoutKeptIrsASlotHoldsLessAndSourceIrGivesNone) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  EngineSettings keep = slotTestSettings(), none = keep;
  none.keepSourceIrs = false;
  auto slotOf = [](const EngineSettings& es) {
    auto b = Engine::sourceSlotBytes(es);
    EXPECT_TRUE(b.isOk());
    return b.isOk() ? *b : size_t(0);
  };
  EXPECT_EQ(slotOf(keep) - slotOf(none), size_t(2 * kFs) * 2 * sizeof(float)) << "a binaural IR of 2 s";
  EngineSettings keepTail = test::fastSettings(), noneTail = keepTail;
  noneTail.keepSourceIrs = false;
  EXPECT_GT(slotOf(keepTail), slotOf(noneTail)) << "the histogram a shared-tail IR is made from";

  test::Room room;
  for (const EngineSettings& es : {none, noneTail}) {
    auto engine = Engine::create(es, model);
    ASSERT_TRUE(engine.isOk()) << engine.status().message();
    Engine& e = **engine;
    e.setScene(room.tracer, room.materials);
    std::vector<uint32_t> ids;
    for (int i = 0; i < 2; ++i) {
      auto id = e.addSource({});
      ASSERT_TRUE(id.isOk());
      ids.push_back(*id);
      ASSERT_TRUE(e.setSourcePosition(*id, {2.0 + i, 3, 1.5}).isOk());
    }
    ASSERT_TRUE(e.setListener({7, 4, 1.6}, {}).isOk());
    ASSERT_TRUE(e.simulate().isOk());
    for (uint32_t id : ids) {
      EXPECT_FALSE(e.sourceIr(id).ir) << "nothing kept";
      EXPECT_EQ(e.sourceIrInfo(id).simulations, 1u);
    }
    // An impulse through the first source: its reflections arrive after
    // the direct sound's ~5 m (15 ms) and the latency.
    std::vector<float> in(256, 0.0f), silent(256, 0.0f), l(256), r(256);
    std::vector<const float*> inputs(es.maxSources, nullptr);
    inputs[ids[0]] = in.data();
    double late = 0;
    for (int b = 0; b < 100; ++b) {
      in[0] = b == 0 ? 1.0f : 0.0f;
      e.process(inputs.data(), l.data(), r.data(), 256);
      if (b * 256 > int(0.1 * kFs) + int(e.latencyFrames()))
        for (float v : l) late += double(v) * v;
    }
    EXPECT_GT(late, 1e-8) << "the reflections play (ambisonic order " << es.ambisonicOrder << ")";
  }
}

// Under a memory limit that leaves room for few sources' IRs in the making,
// a simulation goes through its sources in groups (each group's results
// are held at once): the same IRs, bit for bit, as in one group, the whole
// IRs of sources synthesised in part and the shared tail heard in the
// output too. Five sources, the trace mode auto: shared for the whole
// simulation, not per source for a group of two.
TEST(Engine, SourcesSimulatedInGroupsUnderTheMemoryLimitGiveTheSameIrs) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room;
  struct Run {
    std::vector<std::vector<float>> irs;
    std::vector<float> out;
    uint32_t groups = 0;
  };
  EngineSettings es = test::fastSettings();  // ambisonic reflections with a shared tail
  es.maxSources = 6;
  // IRs of up to 10 s, this room's ~0.75 s: a source's IR in the making is
  // counted at 10 s, so that a limit leaves room for a few of them and
  // for the synthesis of one (~11 MB).
  es.maxIrSeconds = 10;
  auto run = [&](uint64_t limit) {
    MemoryLimitFor scoped(limit);
    Run out;
    auto engine = Engine::create(es, model);
    EXPECT_TRUE(engine.isOk()) << engine.status().message();
    if (!engine.isOk()) return out;
    Engine& e = **engine;
    e.setScene(room.tracer, room.materials);
    EXPECT_TRUE(e.setListener({7, 3.5, 1.5}, {{-1, 0, 0}, {0, 0, 1}}).isOk());
    std::vector<uint32_t> ids;
    for (int i = 0; i < 5; ++i) {
      auto id = e.addSource({});
      EXPECT_TRUE(id.isOk()) << id.status().message();
      if (!id.isOk()) return out;
      ids.push_back(*id);
      EXPECT_TRUE(e.setSourcePosition(*id, {1.5 + i, 2.0 + 0.5 * i, 1.2}).isOk());
    }
    const Status simulated = e.simulate();
    EXPECT_TRUE(simulated.isOk()) << simulated.message();
    out.groups = e.lastSimulation().groups;
    for (uint32_t id : ids) {
      auto ir = e.sourceIr(id).ir;
      EXPECT_TRUE(ir);
      if (!ir) return out;
      for (const auto& ch : ir->channels) out.irs.push_back(ch);
    }
    Pcg32 rng(3, 4);
    std::vector<float> in(256), l(256), r(256);
    std::vector<const float*> inputs(es.maxSources, nullptr);
    for (uint32_t id : ids) inputs[id] = in.data();
    for (int b = 0; b < 40; ++b) {
      for (float& x : in) x = rng.uniform() - 0.5f;
      e.process(inputs.data(), l.data(), r.data(), 256);
      out.out.insert(out.out.end(), l.begin(), l.end());
      out.out.insert(out.out.end(), r.begin(), r.end());
    }
    return out;
  };
  // A limit with room for two and a half sources' IRs in the making (W up
  // to the IR's cut and 50 ms more, and their histograms) beside five
  // slots and two whole IRs (the last source's and the one sourceIr() made).
  auto slot = Engine::sourceSlotBytes(es);
  ASSERT_TRUE(slot.isOk());
  const double frames = (es.maxIrSeconds + 0.06) * kFs;
  const double making = frames * sizeof(float) + (frames / kFs / es.simulation.binSeconds + 1) *
                                                     EnergyHistogram::kStride * sizeof(double);
  const double limit = 5.0 * double(*slot) + 2 * frames * 4 * sizeof(float) + 2.5 * making;
  const Run one = run(0), parted = run(uint64_t(limit));
  EXPECT_EQ(one.groups, 1u);
  EXPECT_GE(parted.groups, 2u) << "the limit leaves room for two sources' IRs in the making";
  ASSERT_EQ(one.irs.size(), parted.irs.size());
  for (size_t c = 0; c < one.irs.size(); ++c) EXPECT_TRUE(one.irs[c] == parted.irs[c]) << "IR channel " << c;
  EXPECT_TRUE(one.out == parted.out) << "the output, the shared tail's included";
}

// sourceSlotBytes() is from above: what more simulated sources hold
// (glibc's heap count: an engine with more sources against one with fewer,
// each after two rounds of IRs with audio between, so that the convolver
// holds new IRs beside the ones it plays, and every source's IR asked for)
// is within their slots' estimate.
struct HeldCase {
  EngineSettings settings;
  float absorption;
  int fewer, more;
  bool oneAtATime;  // simulate(1) for every source: each is the last of its simulation
};
void expectHeldWithinTheEstimate(const HeldCase& c) {
#if !defined(__GLIBC__)
  GTEST_SKIP() << "heap measured with glibc's mallinfo2";
#else
  {
    const double before = heapBytes();
    std::vector<char> probe(1 << 20, 1);
    if (heapBytes() - before < 1e6) GTEST_SKIP() << "malloc is not glibc's (a sanitizer): mallinfo2 sees nothing";
  }
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room(c.absorption);
  // One thread: with two, the bytes held changed by 7.4 MB either way in
  // one run of three (a worker's synthesis scratch, spectral_synth.cpp's
  // thread_local ScratchStack, is made by whichever worker first
  // synthesises, and goes with the engine's threads).
  EngineSettings settings = c.settings;
  settings.threads = 1;
  size_t slot = 0;
  auto heldBy = [&](int sources) {
    const double start = heapBytes();
    auto engine = Engine::create(settings, model);
    EXPECT_TRUE(engine.isOk());
    if (!engine.isOk()) return 0.0;
    Engine& e = **engine;
    slot = e.sourceSlotBytes();
    e.setScene(room.tracer, room.materials);
    std::vector<float> in(256, 0.5f), l(256), r(256);
    std::vector<const float*> inputs(c.settings.maxSources, nullptr);
    std::vector<uint32_t> ids;
    for (int i = 0; i < sources; ++i) {
      auto id = e.addSource({});
      EXPECT_TRUE(id.isOk());
      ids.push_back(*id);
      inputs[*id] = in.data();
      EXPECT_TRUE(e.setSourcePosition(*id, {2.0 + i, 3, 1.5}).isOk());
    }
    auto simulate = [&] {
      if (c.oneAtATime) {
        for (uint32_t id : ids) EXPECT_TRUE(e.simulate(std::vector<uint32_t>{id}).isOk());
      } else {
        EXPECT_TRUE(e.simulate().isOk());
      }
    };
    simulate();
    for (int b = 0; b < 200; ++b) e.process(inputs.data(), l.data(), r.data(), 256);
    for (uint32_t id : ids) EXPECT_TRUE(e.setSourcePosition(id, {3.0, 4, 1.0}).isOk());
    simulate();
    for (int b = 0; b < 10; ++b) e.process(inputs.data(), l.data(), r.data(), 256);
    const size_t frames = size_t(std::ceil(c.settings.maxIrSeconds * kFs));
    for (uint32_t id : ids) {
      auto ir = e.sourceIr(id).ir;
      EXPECT_TRUE(ir && ir->frameCount() <= frames) << "IRs no longer than the convolver takes";
    }
    return heapBytes() - start;
  };
  heldBy(c.fewer);  // the process's caches (band noise, FFT plans), made once
  const double fewer = heldBy(c.fewer), more = heldBy(c.more);
  const double each = (more - fewer) / (c.more - c.fewer);
  EXPECT_LT(each, double(slot)) << "a source holds more than its slot's estimate";
  EXPECT_GT(each, double(slot) / 4) << "the estimate is far from what a source holds";
  std::printf("a simulated source holds %.2f MB, its slot's estimate %.2f MB\n", each / 1e6, double(slot) / 1e6);
#endif
}

// Binaural reflections of 2 s (each slot keeps its IR).
TEST(Engine, WhatASimulatedSourceHoldsIsWithinItsSlotsEstimate) {
  expectHeldWithinTheEstimate({slotTestSettings(), 0.2f, 1, 3, false});
}

// A reverberant room (absorption 0.003, T60 ~30 s), IRs of automatic
// length cut at 2 s: a kept IR held the capacity of its whole automatic
// length (here 15.86 MB against an estimate of 6.77 MB, with neither the
// simulation ending at the cut nor the cut releasing what it cuts).
TEST(Engine, WhatASourceHoldsInAReverberantRoomIsWithinItsSlotsEstimate) {
  EngineSettings es = slotTestSettings();
  es.simulation.lengthSeconds = 0;
  expectHeldWithinTheEstimate({es, 0.003f, 1, 3, false});
}

// Ambisonic reflections with a shared tail in the reverberant room, each
// source simulated on its own (so each was once the last of a simulation,
// synthesised whole) and its whole IR asked for: a slot keeps what its IR
// is made from, up to the cut (not the automatic length's 30 s), and the
// engine one whole IR, not one a slot (26 MB a source against an estimate
// of 0.94 MB before, at the engine's defaults).
TEST(Engine, WhatASourceWithASharedTailHoldsIsWithinItsSlotsEstimate) {
  EngineSettings es = test::fastSettings();  // ambisonic reflections with a shared tail
  es.maxSources = 8;
  es.maxIrSeconds = 3;
  es.traceMode = TraceMode::kShared;
  expectHeldWithinTheEstimate({es, 0.003f, 2, 5, true});
}

// A simulation step goes through its sources in groups
// (EngineSettings::simulationGroupSources), posting each group's IRs as it
// is done, and a source added while the step runs joins its next group: a
// one-shot waits for a group, not for the whole round in progress (32
// sources in the furnished room: 0.08 s against 0.39 s, `earshot bench
// runtime --one-shots-hz`). Groups of one here; the newcomer's IR is the one
// it gets when simulated with the others from the start.
TEST(Engine, ASourceAddedWhileASimulationRunsJoinsItsNextGroup) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room;
  EngineSettings es = test::fastSettings();
  es.maxSources = 16;
  es.simulationGroupSources = 1;
  const int n = 12;
  auto positionOf = [](int i) { return Vec3d{1.0 + 0.6 * i, 1.5 + 1.2 * (i % 4), 1.2}; };
  const Vec3d newcomerAt{8.5, 5.5, 1.6};
  auto start = [&](Engine& e) {
    e.setScene(room.tracer, room.materials);
    EXPECT_TRUE(e.setListener({5, 3.5, 1.5}, {{-1, 0, 0}, {0, 0, 1}}).isOk());
    std::vector<uint32_t> ids;
    for (int i = 0; i < n; ++i) {
      auto id = e.addSource({});
      EXPECT_TRUE(id.isOk());
      ids.push_back(*id);
      EXPECT_TRUE(e.setSourcePosition(*id, positionOf(i)).isOk());
    }
    return ids;
  };
  auto created = Engine::create(es, model);
  ASSERT_TRUE(created.isOk());
  Engine& e = **created;
  const std::vector<uint32_t> ids = start(e);
  ASSERT_TRUE(e.simulate().isOk());  // every source once: the next step is a round of n groups
  EXPECT_EQ(e.lastSimulation().groups, uint32_t(n));
  // The newcomer is added once the step has posted its first group's IR.
  // If then no more than n - 2 have posted, the last group has yet to
  // start (each starts after the one before it posted), so the newcomer
  // must be taken; on a machine so loaded that this thread saw the step
  // near its end, the step is tried again. `byName`: simulate(ids), a
  // step given its sources, which takes no newcomer.
  uint32_t newcomer = ~0u;
  auto addDuringAStep = [&](bool byName) {
    for (int attempt = 0; attempt < 20; ++attempt) {
      if (newcomer != ~0u) {
        EXPECT_TRUE(e.removeSource(newcomer).isOk());
      }
      newcomer = ~0u;
      std::vector<uint64_t> before;
      for (uint32_t id : ids) before.push_back(e.sourceIrInfo(id).simulations);
      auto posted = [&] {
        int k = 0;
        for (size_t i = 0; i < ids.size(); ++i) k += e.sourceIrInfo(ids[i]).simulations > before[i] ? 1 : 0;
        return k;
      };
      Status stepped = Status::ok();
      std::thread sim([&] { stepped = byName ? e.simulate(ids) : e.simulate(); });
      while (posted() == 0) std::this_thread::sleep_for(std::chrono::microseconds(200));
      auto id = e.addSource({});
      EXPECT_TRUE(id.isOk());
      if (id.isOk()) {
        newcomer = *id;
        EXPECT_TRUE(e.setSourcePosition(newcomer, newcomerAt).isOk());
      }
      const bool inTime = posted() <= n - 2;
      sim.join();
      EXPECT_TRUE(stepped.isOk()) << stepped.message();
      if (inTime) return e.lastSimulation().sourcesSimulated;
    }
    ADD_FAILURE() << "the step always ended before this thread could add the newcomer";
    return 0u;
  };
  EXPECT_EQ(addDuringAStep(/*byName=*/true), uint32_t(n));
  ASSERT_NE(newcomer, ~0u);
  EXPECT_EQ(e.sourceIrInfo(newcomer).simulations, 0u);
  EXPECT_EQ(addDuringAStep(/*byName=*/false), uint32_t(n + 1));
  ASSERT_NE(newcomer, ~0u);
  EXPECT_EQ(e.sourceIrInfo(newcomer).simulations, 1u);
  const SourceIr joined = e.sourceIr(newcomer);
  ASSERT_TRUE(joined.ir);

  auto fresh = Engine::create(es, model);
  ASSERT_TRUE(fresh.isOk());
  start(**fresh);
  auto id = (*fresh)->addSource({});
  ASSERT_TRUE(id.isOk());
  ASSERT_TRUE((*fresh)->setSourcePosition(*id, newcomerAt).isOk());
  ASSERT_TRUE((*fresh)->simulate().isOk());
  const SourceIr together = (*fresh)->sourceIr(*id);
  ASSERT_TRUE(together.ir);
  EXPECT_TRUE(joined.ir->channels == together.ir->channels) << "the newcomer's IR, joined or from the start";
}

// A one-shot: a source added and played at once (a 21 ms burst), whose
// first IR lands 0.1 s later (a simulation step). What it played meanwhile
// went into its convolution's history (and the shared tail, at the late
// level of the sources simulated before it), so once its first IR has
// faded in the output is what it is when the source was simulated before
// it played: the burst's reflections and reverberation, not silence. In a
// fresh slot and in one whose last source has rung out (its IR dropped),
// with binaural reflections and with ambisonic ones and the shared tail;
// and for a one-shot released once its burst is passed, before its first
// IR (the next simulate() makes that IR still, from where it was).
// Another source stands at the same place, so that the late level the
// newcomer's shared tail starts at is its own; its IR is the same.
TEST(Engine, WhatASourcePlaysBeforeItsFirstIrIsInItsReflections) {
  ASSERT_TRUE(test::ku100());
  test::Room room;
  const size_t block = 256;
  const Vec3d place{2.5, 3.0, 1.5};
  const int landsAt = 19;  // the block at which the first IR is posted (0.1 s)
  auto run = [&](int order, bool reuse, bool release, bool simulatedFirst, uint32_t* slot) {
    EngineSettings es = test::fastSettings();
    es.ambisonicOrder = order;
    es.maxSources = 2;
    auto created = Engine::create(es, test::ku100());
    EXPECT_TRUE(created.isOk()) << created.status().message();
    Engine& e = **created;
    e.setScene(room.tracer, room.materials);
    EXPECT_TRUE(e.setListener({7, 4, 1.6}, {{1, 0, 0}, {0, 0, 1}}).isOk());
    std::vector<float> in(block), silence(block, 0.0f), l(block), r(block), out;
    std::vector<const float*> inputs(es.maxSources, nullptr);
    auto resident = e.addSource({});
    EXPECT_TRUE(resident.isOk());
    EXPECT_TRUE(e.setSourcePosition(*resident, place).isOk());
    inputs[*resident] = silence.data();
    Pcg32 rng(5, 2);
    if (reuse) {
      // A source elsewhere plays 0.3 s of noise, is released and rings out.
      auto old = e.addSource({});
      EXPECT_TRUE(old.isOk());
      EXPECT_TRUE(e.setSourcePosition(*old, {8.5, 1.2, 1.1}).isOk());
      EXPECT_TRUE(e.simulate().isOk());
      inputs[*old] = in.data();
      for (int b = 0; b < 56; ++b) {
        for (float& x : in) x = float(rng.uniformDouble() - 0.5);
        e.process(inputs.data(), l.data(), r.data(), block);
      }
      EXPECT_TRUE(e.removeSource(*old).isOk());
      inputs[*old] = nullptr;
      for (int b = 0; b < 375; ++b) e.process(inputs.data(), l.data(), r.data(), block);  // 2 s
    } else {
      EXPECT_TRUE(e.simulate().isOk());
    }
    SourceSettings ss;
    ss.directGainDb = -120;  // the reflections are what counts
    auto s = e.addSource(ss);
    EXPECT_TRUE(s.isOk());
    *slot = *s;
    EXPECT_TRUE(e.setSourcePosition(*s, place).isOk());
    if (simulatedFirst) {
      EXPECT_TRUE(e.simulate(std::vector<uint32_t>{*s}).isOk());
    }
    inputs[*s] = in.data();
    for (int b = 0; b < 300; ++b) {  // 1.6 s
      for (float& x : in) x = b < 4 ? float(rng.uniformDouble() - 0.5) : 0.0f;
      if (release && b == 4) {
        // A one-shot released once its last sample is passed.
        EXPECT_TRUE(e.removeSource(*s).isOk());
        inputs[*s] = nullptr;
      }
      if (b == landsAt && release) {
        // The next step takes the released source too (and the resident).
        EXPECT_TRUE(e.simulate().isOk());
        EXPECT_EQ(e.lastSimulation().sourcesSimulated, simulatedFirst ? 1u : 2u);
      } else if (b == landsAt && !simulatedFirst) {
        EXPECT_TRUE(e.simulate(std::vector<uint32_t>{*s}).isOk());
      }
      e.process(inputs.data(), l.data(), r.data(), block);
      out.insert(out.end(), l.begin(), l.end());
      out.insert(out.end(), r.begin(), r.end());
    }
    return out;
  };
  struct Case {
    int order;
    bool reuse, release;
  };
  for (const Case& c : {Case{0, false, false}, Case{0, true, false}, Case{1, false, false}, Case{1, true, false},
                        Case{0, false, true}, Case{1, false, true}}) {
    const std::string label = "order " + std::to_string(c.order) + (c.reuse ? ", a rung-out slot" : ", a fresh slot") +
                              (c.release ? ", released after the burst" : "");
    uint32_t lateSlot = 0, firstSlot = 0;
    const std::vector<float> late = run(c.order, c.reuse, c.release, false, &lateSlot);
    const std::vector<float> first = run(c.order, c.reuse, c.release, true, &firstSlot);
    EXPECT_EQ(lateSlot, 1u);
    EXPECT_EQ(firstSlot, 1u);
    ASSERT_EQ(late.size(), first.size());
    // Energies from `from` to `to` seconds: the output's, the source
    // simulated first's and their difference.
    struct Energies {
      double late = 0, first = 0, difference = 0;
    };
    auto energies = [&](double from, double to) {
      Energies e;
      const size_t end = std::min(late.size(), size_t(to * kFs / block) * 2 * block);
      for (size_t i = size_t(from * kFs / block) * 2 * block; i < end; ++i) {
        e.late += double(late[i]) * late[i];
        e.first += double(first[i]) * first[i];
        e.difference += (double(late[i]) - first[i]) * (double(late[i]) - first[i]);
      }
      return e;
    };
    // The first IR lands at 0.1 s and fades in level by level, each at
    // its next block (the longest, for a 1.5 s binaural IR, blocks of
    // 8192 frames or fewer); from 0.6 s it is all in.
    const double landing = landsAt * double(block) / kFs;
    const Energies waiting = energies(0.0, landing), after = energies(0.6, 2.0), fading = energies(landing, 0.6);
    std::printf("%s: from 0.6 s the difference is %.1f dB of the output; from the IR's landing to 0.6 s the output "
                "is %.1f dB of the source simulated first's\n",
                label.c_str(), 10 * std::log10(after.difference / after.first + 1e-30),
                10 * std::log10(fading.late / fading.first + 1e-30));
    EXPECT_GT(after.first, 1e-12) << "the burst's reverberation is there to compare";
    // Before its IR, nothing of the source is heard through the IR the
    // slot held (the direct sound at -120 dB apart).
    EXPECT_LT(waiting.late, 1e-6 * waiting.first) << label;
    EXPECT_LT(after.difference, 1e-6 * after.first) << label;
    // While the IR fades in, most of the reflections are there: with the
    // ambisonic IR's short levels (0.17 s) -1.8 dB of them (a released
    // one-shot without its owed IR has the shared tail alone, -8.5 dB), with
    // the binaural 1.5 s IR's long levels -7.8 dB (none at all without the
    // history fed before the IR).
    EXPECT_GT(fading.late, (c.order == 1 ? 0.5 : 0.1) * fading.first) << label;
    EXPECT_LT(fading.late, 1.1 * fading.first) << label << ": a fade in, not more";
  }
}

// Until its first simulation a source's sound goes into the shared tail
// at the late level of the simulated source nearest to it: more likely in
// its room than the mean of all. Two sources are simulated, one in the room
// and one outside it (no reflection reaches the listener: no tail); a new
// source plays a burst near one of them and is simulated 0.1 s later. Near
// the one outside, none of its burst is heard in the tail (from 0.6 s, after
// its own IR's 0.17 s, the output is silence, as its own simulation says);
// near the one inside, the burst rings on in the tail.
TEST(Engine, ANewSourcesLateLevelIsTheNearestSimulatedSources) {
  ASSERT_TRUE(test::ku100());
  test::Room room;
  const size_t block = 256;
  auto lateEnergy = [&](const Vec3d& place) {
    EngineSettings es = test::fastSettings();
    es.maxSources = 3;
    auto created = Engine::create(es, test::ku100());
    EXPECT_TRUE(created.isOk()) << created.status().message();
    Engine& e = **created;
    e.setScene(room.tracer, room.materials);
    EXPECT_TRUE(e.setListener({6, 4, 1.5}, {{1, 0, 0}, {0, 0, 1}}).isOk());
    auto inside = e.addSource({}), outside = e.addSource({});
    EXPECT_TRUE(inside.isOk() && outside.isOk());
    EXPECT_TRUE(e.setSourcePosition(*inside, {3.0, 3.0, 1.5}).isOk());
    EXPECT_TRUE(e.setSourcePosition(*outside, {15.0, 3.5, 1.5}).isOk());
    EXPECT_TRUE(e.simulate().isOk());
    SourceSettings ss;
    ss.directGainDb = -120;
    auto s = e.addSource(ss);
    EXPECT_TRUE(s.isOk());
    EXPECT_TRUE(e.setSourcePosition(*s, place).isOk());
    std::vector<float> in(block), silence(block, 0.0f), l(block), r(block);
    std::vector<const float*> inputs(es.maxSources, silence.data());
    inputs[*s] = in.data();
    Pcg32 rng(2, 9);
    double late = 0;
    for (int b = 0; b < 300; ++b) {  // 1.6 s
      for (float& x : in) x = b < 4 ? float(rng.uniformDouble() - 0.5) : 0.0f;
      if (b == 19) {
        EXPECT_TRUE(e.simulate(std::vector<uint32_t>{*s}).isOk());
      }
      e.process(inputs.data(), l.data(), r.data(), block);
      if (b * double(block) / kFs >= 0.6)
        for (size_t k = 0; k < block; ++k) late += double(l[k]) * l[k] + double(r[k]) * r[k];
    }
    return late;
  };
  const double nearOutside = lateEnergy({14.0, 3.5, 1.5}), nearInside = lateEnergy({3.5, 3.0, 1.5});
  std::printf("the burst's energy in the shared tail from 0.6 s: near the source outside %.3g, inside %.3g\n",
              nearOutside, nearInside);
  EXPECT_EQ(nearOutside, 0.0);
  EXPECT_GT(nearInside, 1e-9);
}

// A new source that takes a slot whose last source still rings (every
// other slot in use): the last source's ring-out fades out, and nothing of
// what it played goes through the new source's IR. Binaural reflections
// (each source's whole IR in its slot: no shared tail rings on). The slot's
// last source plays 0.3 s of noise and is released; the new source, silent,
// is added at once and simulated 0.1 s later, after the last IR has faded
// out (~0.08 s here; an IR that lands before that still hears the rest of
// the old sound: engine.h, removeSource). Once the new IR has faded in,
// the output is silence. (Before, the old noise still in the slot's
// convolution history was heard through the new source's IR.)
TEST(Engine, ASourceInASlotThatStillRingsHearsNothingOfTheLastOnesSound) {
  ASSERT_TRUE(test::ku100());
  test::Room room;
  const size_t block = 256;
  EngineSettings es = test::fastSettings();
  es.ambisonicOrder = 0;
  es.maxSources = 2;
  auto created = Engine::create(es, test::ku100());
  ASSERT_TRUE(created.isOk()) << created.status().message();
  Engine& e = **created;
  e.setScene(room.tracer, room.materials);
  ASSERT_TRUE(e.setListener({7, 4, 1.6}, {{1, 0, 0}, {0, 0, 1}}).isOk());
  std::vector<float> in(block), silence(block, 0.0f), l(block), r(block);
  std::vector<const float*> inputs(es.maxSources, nullptr);
  auto resident = e.addSource({}), old = e.addSource({});
  ASSERT_TRUE(resident.isOk() && old.isOk());
  ASSERT_TRUE(e.setSourcePosition(*resident, {2.5, 3.0, 1.5}).isOk());
  ASSERT_TRUE(e.setSourcePosition(*old, {8.5, 1.2, 1.1}).isOk());
  ASSERT_TRUE(e.simulate().isOk());
  inputs[*resident] = silence.data();
  inputs[*old] = in.data();
  Pcg32 rng(9, 4);
  for (int b = 0; b < 56; ++b) {
    for (float& x : in) x = float(rng.uniformDouble() - 0.5);
    e.process(inputs.data(), l.data(), r.data(), block);
  }
  ASSERT_TRUE(e.removeSource(*old).isOk());
  auto s = e.addSource({});
  ASSERT_TRUE(s.isOk());
  EXPECT_EQ(*s, *old) << "the only free slot, still ringing";
  ASSERT_TRUE(e.setSourcePosition(*s, {4.0, 5.0, 1.2}).isOk());
  inputs[*s] = silence.data();
  double ringing = 0, after = 0;
  for (int b = 0; b < 300; ++b) {  // 1.6 s
    if (b == 19) {
      ASSERT_TRUE(e.simulate(std::vector<uint32_t>{*s}).isOk());
    }
    e.process(inputs.data(), l.data(), r.data(), block);
    double energy = 0;
    for (size_t k = 0; k < block; ++k) energy += double(l[k]) * l[k] + double(r[k]) * r[k];
    if (b < 19) {
      ringing += energy;
    } else if (b * double(block) / kFs >= 0.6) {
      after += energy;
    }
  }
  std::printf("the last source's ring-out until the new IR lands: %.3g; from 0.6 s: %.3g\n", ringing, after);
  EXPECT_GT(ringing, 1e-6) << "the slot rang when the new source took it";
  EXPECT_EQ(after, 0.0) << "nothing of the last source's sound through the new source's IR";
}

// Issue 16: sources whose geometry changed most since their IR are
// simulated first (after priority and never-simulated ones), equal ones in
// round robin; each IR carries when its poses were read.
TEST(Engine, SourcesThatMovedMostAreSimulatedFirst) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room;
  auto engine = Engine::create(test::fastSettings(), model);
  ASSERT_TRUE(engine.isOk());
  Engine& e = **engine;
  e.setScene(room.tracer, room.materials);
  std::vector<uint32_t> ids;
  for (int i = 0; i < 3; ++i) {
    auto id = e.addSource({});
    ASSERT_TRUE(id.isOk());
    ids.push_back(*id);
    ASSERT_TRUE(e.setSourcePosition(*id, {2.0 + i, 3, 1.5}).isOk());
  }
  ASSERT_TRUE(e.simulate().isOk());
  auto count = [&](int i) { return e.sourceIr(ids[size_t(i)]).simulations; };
  for (int i = 0; i < 3; ++i) EXPECT_EQ(count(i), 1u);
  const auto before = std::chrono::steady_clock::now();
  ASSERT_TRUE(e.setSourcePosition(ids[2], {4.0, 5, 1.5}).isOk());   // moved 2 m
  ASSERT_TRUE(e.setSourcePosition(ids[0], {2.0, 3.5, 1.5}).isOk());  // moved 0.5 m
  ASSERT_TRUE(e.simulate(1).isOk());
  EXPECT_EQ(count(2), 2u) << "the one that moved most first";
  EXPECT_GE(e.sourceIr(ids[2]).posed, before);
  EXPECT_LT(e.sourceIr(ids[1]).posed, before);
  ASSERT_TRUE(e.simulate(1).isOk());
  EXPECT_EQ(count(0), 2u) << "then the one that moved less";
  // Nothing moved since: round robin, the one not yet taken this time first.
  ASSERT_TRUE(e.simulate(1).isOk());
  EXPECT_EQ(count(1), 2u);
  // A listener move changes every source alike: still round robin.
  ASSERT_TRUE(e.setListener({6, 3.5, 1.5}, {}).isOk());
  for (int k = 0; k < 3; ++k) ASSERT_TRUE(e.simulate(1).isOk());
  for (int i = 0; i < 3; ++i) EXPECT_EQ(count(i), 3u) << i;
}

#if defined(__linux__)
// The simulation's worker threads run at a lower priority than the caller
// (nice + workerNice), and threads = 0 leaves the audio thread a core.
TEST(Engine, WorkersRunBelowTheAudioThread) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  auto niceOf = [](const std::string& statPath) {
    std::ifstream f(statPath);
    std::string line;
    std::getline(f, line);
    // Fields after the command (which may hold spaces) start at the last ')'.
    std::istringstream rest(line.substr(line.rfind(')') + 2));
    std::string field;
    for (int i = 3; i <= 19 && rest >> field; ++i)
      if (i == 19) return std::stoi(field);
    return 0;
  };
  const int mine = niceOf("/proc/thread-self/stat");
  auto count = [&](int nice) {
    int n = 0;
    for (const auto& task : std::filesystem::directory_iterator("/proc/self/task"))
      n += niceOf(task.path().string() + "/stat") == nice;
    return n;
  };
  const int before = count(std::min(19, mine + 5));
  EngineSettings s = test::fastSettings();
  s.threads = 3;  // the caller and two workers
  auto engine = Engine::create(s, model);
  ASSERT_TRUE(engine.isOk());
  // The workers lower themselves as they start.
  for (int tries = 0; tries < 200 && count(std::min(19, mine + 5)) < before + 2; ++tries)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_EQ(count(std::min(19, mine + 5)), before + 2);
  EXPECT_EQ(niceOf("/proc/thread-self/stat"), mine) << "the caller's thread is not changed";
  s.threads = 0;
  auto automatic = Engine::create(s, model);
  ASSERT_TRUE(automatic.isOk());
  EXPECT_EQ((*automatic)->settings().threads, std::max(2u, std::thread::hardware_concurrency()) - 1);
}
#endif

}  // namespace earshot::runtime
