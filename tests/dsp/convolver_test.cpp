// Known-answer tests of the streaming convolver and mixer against a direct
// double-precision convolution.
#include "earshot/dsp/convolver.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <map>
#include <optional>
#include <limits>

#if defined(__SSE__) || defined(__x86_64__)
#include <xmmintrin.h>
#endif

#include "test_signals.h"
#include "aligned_floats.h"
#include "mac_kernels.h"
#include "earshot/core/denormals.h"
#include "earshot/core/thread_pool.h"

namespace earshot {
namespace {

using test::decayingNoise;
using test::directConvolve;

struct Streamed {
  std::vector<std::vector<float>> out;  // [channel][frame]
};

// Streams `input` through `conv` in calls of nextBlock() frames each.
Streamed stream(Convolver& conv, const std::vector<float>& input, const std::function<size_t()>& nextBlock,
           const std::function<void(size_t)>& beforeCall = nullptr) {
  const size_t ch = conv.settings().channels;
  Streamed r;
  r.out.assign(ch, std::vector<float>(input.size(), 0.0f));
  size_t pos = 0;
  size_t call = 0;
  std::vector<float*> outs(ch);
  while (pos < input.size()) {
    size_t b = std::min(nextBlock(), input.size() - pos);
    if (beforeCall) beforeCall(call);
    for (size_t c = 0; c < ch; ++c) outs[c] = r.out[c].data() + pos;
    conv.process(input.data() + pos, outs.data(), b);
    pos += b;
    ++call;
  }
  return r;
}

std::unique_ptr<Convolver> makeConvolver(size_t latency, size_t maxIr, size_t channels, size_t fade = 0,
                                         bool compact = false) {
  ConvolverSettings s;
  s.latencyFrames = latency;
  s.maxIrFrames = maxIr;
  s.channels = channels;
  s.fadeFrames = fade;
  s.compactSpectra = compact;
  auto c = Convolver::create(s);
  EXPECT_TRUE(c.isOk()) << c.status().message();
  return std::move(*c);
}

std::shared_ptr<const PreparedIr> prepare(const std::vector<std::vector<float>>& ir, const PartitionLayout& layout) {
  auto p = PreparedIr::create(ir, layout);
  EXPECT_TRUE(p.isOk()) << p.status().message();
  return *p;
}

struct BlockCase {
  const char* name;
  size_t latency;
  size_t block;  // 0 = changes every call
};

// Host block sizes from the issue; latency = host block where the block is a
// valid partition size, else a small power of two.
const BlockCase kBlocks[] = {
    {"b1", 16, 1},       {"b7", 64, 7},          {"b64", 64, 64},     {"b256", 256, 256},
    {"b1000", 1000, 1000}, {"b1024", 1024, 1024}, {"b4096", 4096, 4096}, {"varying", 128, 0},
};

class ConvolverMatchesDirect : public ::testing::TestWithParam<size_t> {};

// Output equals the direct convolution delayed by latencyFrames, to 1e-5 of
// the output peak. Float FFT convolution error grows like eps * log2(nfft)
// relative to the signal energy in each bin (~1e-6 here); 1e-5 leaves margin.
TEST_P(ConvolverMatchesDirect, AllBlockSizes) {
  const size_t irLen = GetParam();
  std::vector<std::vector<float>> ir = {decayingNoise(irLen, 11), decayingNoise(irLen, 12)};
  // Input: two noise bursts so every partition sees signal, zeros elsewhere
  // (keeps the reference cheap for 4 s IRs).
  const size_t burst = 700;
  const size_t total = irLen + 2 * burst + 5000;
  std::vector<float> x(total, 0.0f);
  auto noise = decayingNoise(2 * burst, 99, 0.0);
  for (size_t i = 0; i < burst; ++i) {
    x[i] = noise[i];
    x[irLen / 2 + i] = noise[burst + i];
  }
  std::vector<std::vector<double>> ref = {directConvolve(x, ir[0], total), directConvolve(x, ir[1], total)};
  double peak = 0;
  for (auto& ch : ref)
    for (double v : ch) peak = std::max(peak, std::fabs(v));

  for (const BlockCase& bc : kBlocks) {
    auto conv = makeConvolver(bc.latency, irLen, 2);
    ASSERT_TRUE(conv);
    ASSERT_EQ(conv->latencyFrames(), bc.latency);
    ASSERT_TRUE(conv->setIr(prepare(ir, conv->layout())).isOk());
    Pcg32 rng(5, 7);
    auto next = [&]() -> size_t { return bc.block ? bc.block : 1 + (rng.next() % 600); };
    // The IR is picked up at the first latency step; feed silence until then
    // is not needed because the first step happens before any input frame
    // reaches the output (the convolver starts with an all-zero history).
    Streamed r = stream(*conv, x, next);
    const size_t lat = conv->latencyFrames();
    double worst = 0;
    size_t worstAt = 0;
    for (size_t c = 0; c < 2; ++c)
      for (size_t t = 0; t < total; ++t) {
        double want = t >= lat ? ref[c][t - lat] : 0.0;
        double err = std::fabs(r.out[c][t] - want);
        if (err > worst) {
          worst = err;
          worstAt = t;
        }
      }
    EXPECT_LE(worst, 1e-5 * peak) << "IR " << irLen << " block " << bc.name << " worst at frame " << worstAt;
  }
}

INSTANTIATE_TEST_SUITE_P(IrLengths, ConvolverMatchesDirect,
                         ::testing::Values(size_t{1}, size_t{100}, size_t{3001}, size_t{24000}, size_t{96000},
                                           size_t{192000}),
                         [](const auto& info) { return "ir" + std::to_string(info.param); });

// The stagger option shifts when each level does its work, never the
// result: still the direct convolution to 1e-5 of peak (see above).
TEST(Convolver, StaggeredPhaseIsStillExact) {
  const size_t irLen = 30000;
  std::vector<std::vector<float>> ir = {decayingNoise(irLen, 81), decayingNoise(irLen, 82)};
  std::vector<float> x = decayingNoise(irLen + 4000, 83, 0.0);
  std::fill(x.begin() + 3000, x.end(), 0.0f);
  std::vector<std::vector<double>> ref = {directConvolve(x, ir[0], x.size()), directConvolve(x, ir[1], x.size())};
  double peak = 0;
  for (auto& ch : ref)
    for (double v : ch) peak = std::max(peak, std::fabs(v));
  for (uint32_t phase : {1u, 5u, 37u, 1000u}) {
    ConvolverSettings s;
    s.latencyFrames = 64;
    s.maxIrFrames = irLen;
    s.channels = 2;
    s.phase = phase;
    auto conv = Convolver::create(s);
    ASSERT_TRUE(conv.isOk());
    ASSERT_GT((*conv)->layout().levels().size(), 1u);  // so the phase matters
    ASSERT_TRUE((*conv)->setIr(prepare(ir, (*conv)->layout())).isOk());
    Streamed r = stream(**conv, x, [] { return size_t{100}; });
    double worst = 0;
    for (size_t c = 0; c < 2; ++c)
      for (size_t t = 64; t < x.size(); ++t) worst = std::max(worst, std::fabs(r.out[c][t] - ref[c][t - 64]));
    EXPECT_LE(worst, 1e-5 * peak) << "phase " << phase;
  }
}

// An impulse in gives the IR out, exactly latencyFrames later, and nothing
// before. Tolerance: float FFT round-off relative to a unit-peak IR.
TEST(Convolver, ImpulseGivesIrAtLatency) {
  const size_t irLen = 5000;
  std::vector<std::vector<float>> ir = {decayingNoise(irLen, 3), decayingNoise(irLen, 4)};
  auto conv = makeConvolver(64, irLen, 2);
  ASSERT_TRUE(conv->setIr(prepare(ir, conv->layout())).isOk());
  std::vector<float> x(irLen + 1000, 0.0f);
  x[0] = 1.0f;
  Streamed r = stream(*conv, x, [] { return size_t{100}; });
  for (size_t c = 0; c < 2; ++c) {
    for (size_t t = 0; t < 64; ++t) EXPECT_EQ(r.out[c][t], 0.0f) << t;
    for (size_t t = 0; t < irLen; ++t) ASSERT_NEAR(r.out[c][64 + t], ir[c][t], 2e-6) << "channel " << c << " tap " << t;
    for (size_t t = 64 + irLen; t < x.size(); ++t) ASSERT_NEAR(r.out[c][t], 0.0f, 2e-6);
  }
}

// Processing in place (output 0 is the input buffer) gives the same samples
// as separate buffers.
TEST(Convolver, InPlaceEqualsOutOfPlace) {
  std::vector<std::vector<float>> ir = {decayingNoise(3000, 91), decayingNoise(3000, 92)};
  auto x = decayingNoise(10000, 93, 0.0);
  auto a = makeConvolver(64, 3000, 2), b = makeConvolver(64, 3000, 2);
  ASSERT_TRUE(a->setIr(prepare(ir, a->layout())).isOk());
  ASSERT_TRUE(b->setIr(prepare(ir, b->layout())).isOk());
  Streamed ref = stream(*a, x, [] { return size_t{77}; });
  std::vector<float> buf = x, right(x.size());
  for (size_t pos = 0; pos < x.size(); pos += 77) {
    size_t n = std::min<size_t>(77, x.size() - pos);
    float* outs[2] = {buf.data() + pos, right.data() + pos};
    b->process(buf.data() + pos, outs, n);
  }
  EXPECT_EQ(buf, ref.out[0]);
  EXPECT_EQ(right, ref.out[1]);
}

std::vector<float> sine(size_t frames, double hz, double amp) {
  std::vector<float> v(frames);
  for (size_t i = 0; i < frames; ++i) v[i] = static_cast<float>(amp * std::sin(2 * M_PI * hz * i / 48000.0));
  return v;
}

double maxStep(const std::vector<float>& y, size_t from) {
  double m = 0;
  for (size_t i = from + 1; i < y.size(); ++i) m = std::max(m, std::fabs(double(y[i]) - y[i - 1]));
  return m;
}

// Swapping between two different IRs on every host block of a steady sine
// never makes a sample-to-sample step larger than twice the largest step of
// the steady outputs with either IR alone: the crossfade is click-free.
TEST(Convolver, SwapEveryBlockIsClickFree) {
  const size_t irLen = 20000, block = 64, frames = 48000;
  std::vector<std::vector<float>> irA = {decayingNoise(irLen, 21), decayingNoise(irLen, 22)};
  std::vector<std::vector<float>> irB = {decayingNoise(irLen, 23, -30), decayingNoise(irLen, 24, -30)};
  for (auto& c : irB)
    for (float& v : c) v *= 0.5f;
  const auto x = sine(frames, 440.0, 0.5);
  auto steady = [&](const std::vector<std::vector<float>>& ir) {
    auto conv = makeConvolver(block, irLen, 2);
    EXPECT_TRUE(conv->setIr(prepare(ir, conv->layout())).isOk());
    return stream(*conv, x, [&] { return block; });
  };
  Streamed a = steady(irA), b = steady(irB);
  // Default fade (one block) and a fade longer than a block (1000 frames,
  // so a fade spans several blocks and new IRs wait for it to end).
  for (size_t fade : {size_t{0}, size_t{1000}}) {
    auto conv = makeConvolver(block, irLen, 2, fade);
    auto pa = prepare(irA, conv->layout()), pb = prepare(irB, conv->layout());
    Streamed s = stream(*conv, x, [&] { return block; },
                        [&](size_t call) { ASSERT_TRUE(conv->setIr(call % 2 ? pb : pa).isOk()); });
    const size_t from = irLen + 2 * block;  // past the build-up of the reverb tail
    for (size_t c = 0; c < 2; ++c) {
      double limit = 2.0 * std::max(maxStep(a.out[c], from), maxStep(b.out[c], from));
      EXPECT_LE(maxStep(s.out[c], from), limit) << "channel " << c << " fade " << fade;
      // And the swapping really changed the output (the test could fail).
      double diff = 0;
      for (size_t t = from; t < frames; ++t) diff = std::max(diff, std::fabs(double(s.out[c][t]) - a.out[c][t]));
      EXPECT_GT(diff, 1e-3) << "fade " << fade;
    }
  }
}

// Re-posting the same IR (the same object, or an identical one prepared
// again) changes no output sample at all: the fade difference is exactly 0.
TEST(Convolver, SwapToSameIrChangesNothing) {
  const size_t irLen = 30000, block = 128;
  std::vector<std::vector<float>> ir = {decayingNoise(irLen, 31), decayingNoise(irLen, 32)};
  auto x = decayingNoise(60000, 33, 0.0);
  auto plain = makeConvolver(block, irLen, 2);
  auto p0 = prepare(ir, plain->layout());
  ASSERT_TRUE(plain->setIr(p0).isOk());
  Streamed ref = stream(*plain, x, [&] { return block; });

  auto same = makeConvolver(block, irLen, 2);
  ASSERT_TRUE(same->setIr(p0).isOk());
  Streamed r1 = stream(*same, x, [&] { return block; }, [&](size_t) { ASSERT_TRUE(same->setIr(p0).isOk()); });

  auto again = makeConvolver(block, irLen, 2);
  ASSERT_TRUE(again->setIr(p0).isOk());
  Streamed r2 = stream(*again, x, [&] { return block; },
                  [&](size_t call) {
                    if (call % 7 == 3) {
                      ASSERT_TRUE(again->setIr(prepare(ir, again->layout())).isOk());
                    }
                  });
  for (size_t c = 0; c < 2; ++c) {
    EXPECT_EQ(r1.out[c], ref.out[c]) << "channel " << c;
    EXPECT_EQ(r2.out[c], ref.out[c]) << "channel " << c;
  }
}

// The same with compact (binary16) spectra: a fade from an IR to itself
// adds exactly nothing (the fading path's difference of equal halves is
// zero, and its main sum is the steady state's).
TEST(Convolver, SwapToSameCompactIrChangesNothing) {
  const size_t irLen = 30000, block = 128;
  std::vector<std::vector<float>> ir = {decayingNoise(irLen, 31), decayingNoise(irLen, 32)};
  auto x = decayingNoise(60000, 33, 0.0);
  auto plain = makeConvolver(block, irLen, 2, 0, true);
  auto p0 = prepare(ir, plain->layout());
  ASSERT_TRUE(p0->compact());
  ASSERT_TRUE(plain->setIr(p0).isOk());
  Streamed ref = stream(*plain, x, [&] { return block; });
  auto again = makeConvolver(block, irLen, 2, 0, true);
  ASSERT_TRUE(again->setIr(p0).isOk());
  Streamed r = stream(*again, x, [&] { return block; },
                      [&](size_t call) {
                        if (call % 7 == 3) {
                          ASSERT_TRUE(again->setIr(prepare(ir, again->layout())).isOk());
                        }
                      });
  for (size_t c = 0; c < 2; ++c) EXPECT_EQ(r.out[c], ref.out[c]) << "channel " << c;
}

// Fades between compact IRs follow the float mixer's to the storage's
// error: two sources whose IRs change every few blocks between a long one
// and a short one with leading silence (so that levels fade where only the
// old IR, or only the new one, has partitions), against the same swaps in
// a float mixer. Bound as in CompactSpectraErrorIsSmallAndBounded: the
// error's energy under 2^-22 of the output's (-66.2 dB).
TEST(ConvolutionMixer, CompactFadesFollowTheFloatMixersToTheStorageError) {
  const size_t channels = 4, irLen = 9000, block = 256, frames = 40000;
  std::vector<std::vector<float>> longIr, shortIr;
  for (size_t c = 0; c < channels; ++c) {
    longIr.push_back(decayingNoise(irLen, 80 + c));
    std::vector<float> s = decayingNoise(2000, 90 + c);
    s.insert(s.begin(), 1500, 0.0f);
    shortIr.push_back(std::move(s));
  }
  std::vector<std::vector<float>> inputs = {decayingNoise(frames, 101, 0.0), decayingNoise(frames, 102, 0.0)};
  auto run = [&](bool compact, bool swaps) {
    ConvolverSettings s;
    s.latencyFrames = block;
    s.maxIrFrames = irLen;
    s.channels = channels;
    s.compactSpectra = compact;
    auto mixer = ConvolutionMixer::create(s, 2);
    EXPECT_TRUE(mixer.isOk());
    ConvolutionMixer& m = **mixer;
    auto a = prepare(longIr, m.layout()), b = prepare(shortIr, m.layout());
    EXPECT_EQ(a->compact(), compact);
    EXPECT_TRUE(m.setIr(0, a).isOk());
    EXPECT_TRUE(m.setIr(1, b).isOk());
    std::vector<std::vector<float>> out(channels, std::vector<float>(frames));
    std::vector<const float*> ins(2);
    std::vector<float*> outs(channels);
    for (size_t pos = 0, call = 0; pos < frames; pos += block, ++call) {
      if (swaps && call % 5 == 2) {
        const bool flip = (call / 5) % 2 == 0;
        EXPECT_TRUE(m.setIr(0, flip ? b : a).isOk());
        EXPECT_TRUE(m.setIr(1, flip ? a : b).isOk());
      }
      for (size_t src = 0; src < 2; ++src) ins[src] = inputs[src].data() + pos;
      for (size_t c = 0; c < channels; ++c) outs[c] = out[c].data() + pos;
      m.process(ins.data(), outs.data(), std::min(block, frames - pos));
    }
    return out;
  };
  const auto want = run(false, true), got = run(true, true), steady = run(false, false);
  double signalEnergy = 0, errorEnergy = 0, swapEffect = 0;
  for (size_t c = 0; c < channels; ++c)
    for (size_t t = 0; t < frames; ++t) {
      const double e = double(want[c][t]) - got[c][t];
      signalEnergy += double(want[c][t]) * want[c][t];
      errorEnergy += e * e;
      swapEffect = std::max(swapEffect, std::fabs(double(want[c][t]) - steady[c][t]));
    }
  EXPECT_GT(swapEffect, 0.1);  // the swaps changed the output
  const double errorDb = 10 * std::log10(errorEnergy / signalEnergy);
  EXPECT_LE(errorDb, 20 * std::log10(std::ldexp(1.0, -11)));
  std::printf("compact fades: error energy %.1f dB of the output's\n", errorDb);
}

// A mixer of three sources equals the sum of three separate convolvers
// (to 1e-5 of peak, float round-off of differently ordered sums).
TEST(ConvolutionMixer, EqualsSumOfConvolvers) {
  const size_t irLen = 12000, block = 256, frames = 30000;
  ConvolverSettings s;
  s.latencyFrames = block;
  s.maxIrFrames = irLen;
  s.channels = 2;
  auto mixer = ConvolutionMixer::create(s, 3);
  ASSERT_TRUE(mixer.isOk());
  std::vector<std::vector<float>> inputs;
  std::vector<std::vector<float>> sum(2, std::vector<float>(frames, 0.0f));
  for (size_t src = 0; src < 3; ++src) {
    std::vector<std::vector<float>> ir = {decayingNoise(irLen, 40 + src), decayingNoise(irLen / (src + 1), 50 + src)};
    ir[1].resize(irLen, 0.0f);
    inputs.push_back(decayingNoise(frames, 60 + src, 0.0));
    ASSERT_TRUE((*mixer)->setIr(src, prepare(ir, (*mixer)->layout())).isOk());
    auto conv = makeConvolver(block, irLen, 2);
    ASSERT_TRUE(conv->setIr(prepare(ir, conv->layout())).isOk());
    Streamed r = stream(*conv, inputs.back(), [&] { return size_t{200}; });
    for (size_t c = 0; c < 2; ++c)
      for (size_t t = 0; t < frames; ++t) sum[c][t] += r.out[c][t];
  }
  std::vector<std::vector<float>> out(2, std::vector<float>(frames));
  for (size_t pos = 0; pos < frames; pos += 300) {
    size_t b = std::min<size_t>(300, frames - pos);
    const float* ins[3] = {inputs[0].data() + pos, inputs[1].data() + pos, inputs[2].data() + pos};
    float* outs[2] = {out[0].data() + pos, out[1].data() + pos};
    (*mixer)->process(ins, outs, b);
  }
  double peak = 0, worst = 0;
  for (size_t c = 0; c < 2; ++c)
    for (size_t t = 0; t < frames; ++t) {
      peak = std::max(peak, std::fabs(double(sum[c][t])));
      worst = std::max(worst, std::fabs(double(sum[c][t]) - out[c][t]));
    }
  EXPECT_GT(peak, 1.0);
  EXPECT_LE(worst, 1e-5 * peak);
}

// resetSource() (a slot taken by a new source): the source's IR is dropped
// at once and what it was fed is forgotten, the other sources untouched.
// Two sources play noise through their IRs; source 0 is reset and goes
// silent, with a new IR posted at once: from the reset on, the output is
// source 1's alone (as a mixer in which source 0 never played) within float
// rounding, nothing of the noise through either IR; an impulse through the
// new IR then gives that IR at the latency. holdsIr() says when a source
// has an IR.
TEST(ConvolutionMixer, AResetSourceForgetsItsIrAndWhatItPlayed) {
  const size_t irLen = 9000, block = 256, frames = 188 * block, resetAt = 80 * block, impulseAt = 120 * block;
  ConvolverSettings s;
  s.latencyFrames = block;
  s.maxIrFrames = irLen;
  s.channels = 1;
  auto both = ConvolutionMixer::create(s, 2), alone = ConvolutionMixer::create(s, 2);
  ASSERT_TRUE(both.isOk() && alone.isOk());
  const std::vector<std::vector<float>> irA = {decayingNoise(irLen, 71)}, irB = {decayingNoise(irLen, 72)},
                                        irC = {decayingNoise(irLen, 73)};
  ASSERT_TRUE((*both)->setIr(0, prepare(irA, (*both)->layout())).isOk());
  ASSERT_TRUE((*both)->setIr(1, prepare(irB, (*both)->layout())).isOk());
  ASSERT_TRUE((*alone)->setIr(1, prepare(irB, (*alone)->layout())).isOk());
  EXPECT_FALSE((*both)->holdsIr(0)) << "not taken up before the first block";
  const std::vector<float> noise0 = decayingNoise(frames, 74, 0.0), noise1 = decayingNoise(frames, 75, 0.0);
  std::vector<float> zeros(block, 0.0f), impulse(block, 0.0f), outBoth(frames), outAlone(frames);
  impulse[0] = 1.0f;
  for (size_t pos = 0; pos < frames; pos += block) {
    if (pos == resetAt) {
      EXPECT_TRUE((*both)->holdsIr(0));
      (*both)->resetSource(0);
      EXPECT_FALSE((*both)->holdsIr(0)) << "dropped at once";
      EXPECT_TRUE((*both)->holdsIr(1));
      // A new IR at once: had the noise stayed in source 0's history, it
      // would be heard through this IR as it fades in.
      ASSERT_TRUE((*both)->setIr(0, prepare(irC, (*both)->layout())).isOk());
    }
    const float* source0 = zeros.data();
    if (pos < resetAt) {
      source0 = noise0.data() + pos;
    } else if (pos == impulseAt + block) {
      source0 = impulse.data();
    }
    const float* insBoth[2] = {source0, noise1.data() + pos};
    const float* insAlone[2] = {nullptr, noise1.data() + pos};
    float* ob[1] = {outBoth.data() + pos};
    float* oa[1] = {outAlone.data() + pos};
    (*both)->process(insBoth, ob, block);
    (*alone)->process(insAlone, oa, block);
  }
  // From the reset (and its latency) to the impulse: source 1 alone.
  double peak = 0, worst = 0;
  for (size_t t = resetAt + block; t < impulseAt; ++t) {
    peak = std::max(peak, std::fabs(double(outAlone[t])));
    worst = std::max(worst, std::fabs(double(outBoth[t]) - outAlone[t]));
  }
  EXPECT_GT(peak, 0.1);
  EXPECT_LE(worst, 1e-5 * peak) << "nothing of source 0 after its reset";
  // The impulse, fed once the new IR has faded in, through irC: what source
  // 0 adds to source 1 is irC at the latency.
  const size_t at = impulseAt + block + block;  // the impulse's block, and the latency
  double irPeak = 0, irWorst = 0;
  for (size_t i = 0; i < irLen && at + i < frames; ++i) {
    irPeak = std::max(irPeak, std::fabs(double(irC[0][i])));
    irWorst = std::max(irWorst, std::fabs(double(outBoth[at + i]) - outAlone[at + i] - irC[0][i]));
  }
  EXPECT_LE(irWorst, 1e-4 * irPeak + 1e-5 * peak);
}

// postIr() frees nothing, so that a caller (the engine) can post under a
// lock of its own and free outside it: the IR it replaced comes back to the
// caller, and the IRs the audio thread retired wait for collectGarbage().
TEST(ConvolutionMixer, PostIrHandsBackWhatItReplacedAndFreesNothing) {
  const size_t irLen = 4000, block = 256;
  ConvolverSettings s;
  s.latencyFrames = block;
  s.maxIrFrames = irLen;
  s.channels = 1;
  auto mixer = ConvolutionMixer::create(s, 1);
  ASSERT_TRUE(mixer.isOk());
  ConvolutionMixer& m = **mixer;
  std::vector<float> in(block, 0.0f), out(block);
  const float* ins[1] = {in.data()};
  float* outs[1] = {out.data()};
  auto run = [&](size_t blocks) {
    for (size_t b = 0; b < blocks; ++b) m.process(ins, outs, block);
  };
  auto ir = [&](uint32_t seed) { return prepare({decayingNoise(irLen, seed)}, m.layout()); };
  std::shared_ptr<const PreparedIr> replaced;
  ASSERT_TRUE(m.postIr(0, ir(81), &replaced).isOk());
  EXPECT_EQ(replaced, nullptr) << "nothing was posted before";
  run(40);  // taken up and faded in
  EXPECT_TRUE(m.holdsIr(0));
  // An IR the audio thread takes and then retires, replaced by the next.
  std::weak_ptr<const PreparedIr> first;
  {
    auto a = ir(82);
    first = a;
    ASSERT_TRUE(m.postIr(0, std::move(a), &replaced).isOk());
  }
  run(40);
  std::weak_ptr<const PreparedIr> second;
  {
    auto b = ir(83);
    second = b;
    ASSERT_TRUE(m.postIr(0, std::move(b), &replaced).isOk());
  }
  run(40);  // the second replaces the first, which retires
  // Posted twice with no block between: the first comes back, the mixer
  // keeping no reference to it.
  auto waiting = ir(84);
  const PreparedIr* waitingAddress = waiting.get();
  ASSERT_TRUE(m.postIr(0, std::move(waiting), &replaced).isOk());
  ASSERT_TRUE(m.postIr(0, ir(85), &replaced).isOk());
  ASSERT_NE(replaced, nullptr);
  EXPECT_EQ(replaced.get(), waitingAddress);
  EXPECT_EQ(replaced.use_count(), 1) << "the caller's alone";
  replaced.reset();
  EXPECT_FALSE(first.expired()) << "retired by the audio thread, not freed by postIr";
  m.collectGarbage();
  EXPECT_TRUE(first.expired()) << "freed by collectGarbage";
  // setIr() still frees both at once: what the audio thread retired
  // (the second, once it takes the last one posted) and the pending IR it
  // replaces.
  run(40);
  EXPECT_FALSE(second.expired()) << "retired by the audio thread, not yet collected";
  std::weak_ptr<const PreparedIr> pending;
  {
    auto b = ir(86);
    pending = b;
    ASSERT_TRUE(m.setIr(0, std::move(b)).isOk());
  }
  EXPECT_TRUE(second.expired()) << "retired by the audio thread: freed by setIr";
  ASSERT_TRUE(m.setIr(0, ir(87)).isOk());
  EXPECT_TRUE(pending.expired()) << "replaced before the audio thread took it: freed by setIr";
}

// Several sources in a layout of more than one level, as the engine's
// ambisonic bus (short 4-channel IRs, many sources: the layout's levels are
// 256 and 1024 frames), each IR starting with silence of its own length (a
// reflection arrives after the sound's travel time): the mixer is the direct
// convolution to 1e-5 of the peak (as ConvolverMatchesDirect). Guards two
// things: each IR's leading silent partitions are skipped, exactly; and a
// source whose forward FFT runs in a later step of a level's block reads the
// frames that ended at the block's start (it read the newest ones, which
// shifted the output of every source but the first in levels after the
// first: an error of the output's own size).
TEST(ConvolutionMixer, SourcesInLaterLevelsAndLeadingSilenceAreExact) {
  const size_t sources = 8, channels = 4, irLen = 7682, block = 256, warmUp = 8192, signal = 6000;
  const size_t frames = warmUp + signal;
  ConvolverSettings s;
  s.latencyFrames = block;
  s.maxIrFrames = irLen;
  s.channels = channels;
  auto mixer = ConvolutionMixer::create(s, sources);
  ASSERT_TRUE(mixer.isOk());
  ConvolutionMixer& m = **mixer;
  ASSERT_EQ(m.layout().levels().size(), 2u);
  const PartitionLevel& l0 = m.layout().levels()[0];
  std::vector<std::vector<float>> inputs;
  std::vector<std::vector<double>> want(channels, std::vector<double>(frames, 0.0));
  for (size_t src = 0; src < sources; ++src) {
    // Silence of 0 to ~3500 frames (into the second level for some), one
    // channel silent 300 frames longer.
    const size_t silent = (src * 997) % 3600;
    std::vector<std::vector<float>> ir;
    for (size_t c = 0; c < channels; ++c) {
      std::vector<float> ch = decayingNoise(irLen, 100 + 7 * src + c);
      std::fill(ch.begin(), ch.begin() + long(silent + (c == 2 ? 300 : 0)), 0.0f);
      ir.push_back(std::move(ch));
    }
    auto prepared = prepare(ir, m.layout());
    EXPECT_EQ(prepared->firstActivePartition(0), std::min(l0.partitionCount, silent / l0.partitionFrames))
        << "source " << src;
    ASSERT_TRUE(m.setIr(src, prepared).isOk());
    // Silence first, so that every level has taken up the IR (fading in
    // from none) before the signal starts.
    std::vector<float> x = decayingNoise(signal, 300 + src, 0.0);
    for (size_t c = 0; c < channels; ++c) {
      auto y = directConvolve(x, ir[c], signal);
      for (size_t t = 0; t < signal; ++t) want[c][warmUp + t] += y[t];
    }
    x.insert(x.begin(), warmUp, 0.0f);
    inputs.push_back(std::move(x));
  }
  std::vector<std::vector<float>> out(channels, std::vector<float>(frames));
  std::vector<const float*> ins(sources);
  std::vector<float*> outs(channels);
  for (size_t pos = 0; pos < frames; pos += block) {
    const size_t b = std::min(block, frames - pos);
    for (size_t src = 0; src < sources; ++src) ins[src] = inputs[src].data() + pos;
    for (size_t c = 0; c < channels; ++c) outs[c] = out[c].data() + pos;
    m.process(ins.data(), outs.data(), b);
  }
  double peak = 0, worst = 0;
  for (size_t c = 0; c < channels; ++c)
    for (size_t t = block; t < frames; ++t) {
      peak = std::max(peak, std::fabs(want[c][t - block]));
      worst = std::max(worst, std::fabs(want[c][t - block] - out[c][t]));
    }
  EXPECT_GT(peak, 1.0);
  EXPECT_LE(worst, 1e-5 * peak);
}

// binary16 conversions: every half converts to a float and back to itself
// (NaNs stay NaNs); a float converts to the nearest half, ties to even.
TEST(CompactSpectra, HalfConversionsAreExactAndRoundToNearest) {
  for (uint32_t h = 0; h < 65536; ++h) {
    const float f = dsp_detail::halfToFloat(uint16_t(h));
    if (std::isnan(f)) {
      EXPECT_TRUE(std::isnan(dsp_detail::halfToFloat(dsp_detail::floatToHalf(f)))) << h;
      continue;
    }
    ASSERT_EQ(dsp_detail::floatToHalf(f), uint16_t(h)) << h;
  }
  EXPECT_EQ(dsp_detail::halfToFloat(dsp_detail::floatToHalf(65504.0f)), 65504.0f);
  EXPECT_TRUE(std::isinf(dsp_detail::halfToFloat(dsp_detail::floatToHalf(65520.0f))));
  EXPECT_EQ(dsp_detail::floatToHalf(1e-9f), 0u);
  Pcg32 rng(3, 4);
  for (int i = 0; i < 200000; ++i) {
    // Log-uniform magnitudes over the subnormal and normal range (below 2^15.9,
    // where rounding to 65504 or infinity is checked above), both signs.
    const float v = float((rng.next() & 1 ? -1.0 : 1.0) * std::exp2(-26.0 + 41.9 * rng.uniformDouble()));
    const uint16_t h = dsp_detail::floatToHalf(v);
    const double got = dsp_detail::halfToFloat(h);
    // No other half is nearer (the neighbours one step either way).
    for (int step : {-1, 1}) {
      const uint16_t n = uint16_t(h + step);
      if (((n ^ h) & 0x8000u) || (n & 0x7C00u) == 0x7C00u) continue;
      const double other = dsp_detail::halfToFloat(n);
      const double dGot = std::fabs(got - double(v)), dOther = std::fabs(other - double(v));
      ASSERT_TRUE(dGot < dOther || (dGot == dOther && (h & 1u) == 0))
          << v << " -> " << h << " (" << got << "), neighbour " << n << " (" << other << ")";
    }
  }
}

// floatsToHalves (F16C where the CPU has it, as here) gives every value the
// software's floatToHalf(v / scale), with the denormal flags off and on (the
// audio thread's), over all values whose quotient is a half subnormal or
// rounds near a tie, and log-uniform ones; peakMagnitude is the scalar max.
TEST(CompactSpectra, VectorHalfConversionEqualsTheSoftwareOne) {
  std::vector<float> in;
  for (uint32_t h = 0; h < 0x7C00u; ++h) {  // every finite half, the ties beside it, both signs
    const float f = dsp_detail::halfToFloat(uint16_t(h));
    const float next = dsp_detail::halfToFloat(uint16_t(h + 1));
    for (float v : {f, 0.5f * (f + next), std::nextafter(0.5f * (f + next), 0.0f),
                    std::nextafter(0.5f * (f + next), 1e9f)})
      for (float sign : {1.0f, -1.0f}) in.push_back(sign * v);
  }
  Pcg32 rng(8, 9);
  for (int i = 0; i < 100000; ++i)
    in.push_back(float((rng.next() & 1 ? -1.0 : 1.0) * std::exp2(-160.0 + 176.0 * rng.uniformDouble())));
  in.push_back(std::numeric_limits<float>::denorm_min());
  for (float scale : {1.0f, 0.25f, 1024.0f, std::numeric_limits<float>::min()}) {
    for (bool flush : {false, true}) {
      std::optional<ScopedFlushDenormals> ftz;
      if (flush) ftz.emplace();
      std::vector<uint16_t> fast(in.size()), slow(in.size());
      const size_t n = in.size() - 3;  // a tail beyond the 8-value steps
      dsp_detail::floatsToHalves(in.data(), scale, fast.data(), n);
      dsp_detail::floatsToHalvesPortable(in.data(), scale, slow.data(), n);
      size_t differ = 0;
      for (size_t i = 0; i < n; ++i) differ += fast[i] != slow[i];
      EXPECT_EQ(differ, 0u) << "scale " << scale << (flush ? ", flush to zero" : "");
    }
  }
  for (size_t n : {size_t(0), size_t(3), size_t(4), size_t(17), in.size()}) {
    float peak = 0.0f;
    for (size_t i = 0; i < n; ++i) peak = std::max(peak, std::fabs(in[i]));
    EXPECT_EQ(dsp_detail::peakMagnitude(in.data(), n), peak) << n;
  }
}

// The binary16 multiply-accumulate (AVX2 + F16C where the CPU has it, as
// here) over tile-interleaved spectra equals the float kernel on the same
// values (converted), and its portable loop, to float rounding: partitions
// 2..6 of a level of 7 with 264 bins (32-bin tiles and an 8-bin tile);
// compactPartitionToFloats gives each partition's values back.
TEST(CompactSpectra, MultiplyAccumulateEqualsTheFloatKernel) {
  const size_t partitions = 7, stride = 264, k0 = 2, parts = 5;
  Pcg32 rng(8, 9);
  std::vector<std::vector<float>> x(parts, std::vector<float>(2 * stride)), hf(partitions);
  std::vector<uint16_t> block(partitions * 2 * stride);
  for (auto& v : x)
    for (auto& e : v) e = float(rng.uniformDouble() * 2 - 1);
  for (size_t k = 0; k < partitions; ++k) {
    hf[k].resize(2 * stride);
    for (size_t i = 0; i < stride; i += dsp_detail::compactTileWidth(i, stride)) {
      const size_t w = dsp_detail::compactTileWidth(i, stride);
      uint16_t* t = block.data() + dsp_detail::compactTileOffset(i, k, partitions, stride);
      for (size_t b = 0; b < 2 * w; ++b) {
        t[b] = dsp_detail::floatToHalf(float(rng.uniformDouble() * 2 - 1));
        hf[k][(b < w ? 0 : stride) + i + b % w] = 0.125f * dsp_detail::halfToFloat(t[b]);
      }
    }
    std::vector<float> back(2 * stride), portable(2 * stride);
    dsp_detail::compactPartitionToFloats(block.data(), k, partitions, stride, 0.125f, back.data());
    dsp_detail::compactPartitionToFloatsPortable(block.data(), k, partitions, stride, 0.125f, portable.data());
    ASSERT_EQ(back, hf[k]) << "partition " << k;
    ASSERT_EQ(portable, hf[k]) << "partition " << k;
  }
  std::vector<const float*> xs, hs;
  for (size_t j = 0; j < parts; ++j) {
    xs.push_back(x[j].data());
    hs.push_back(hf[k0 + j].data());
  }
  std::vector<float> a(2 * stride, 0.25f), b(2 * stride, 0.25f), c(2 * stride, 0.25f);
  dsp_detail::complexMacBatchHalf(a.data(), a.data() + stride, xs.data(), block.data(), k0, parts, partitions, stride,
                                  0.125f);
  dsp_detail::complexMacBatchHalfPortable(b.data(), b.data() + stride, xs.data(), block.data(), k0, parts, partitions,
                                          stride, 0.125f);
  dsp_detail::complexMacBatch(c.data(), c.data() + stride, xs.data(), hs.data(), parts, stride, stride);
  double worst = 0, sum = 0;
  for (size_t i = 0; i < 2 * stride; ++i) {
    worst = std::max({worst, std::fabs(double(a[i]) - c[i]), std::fabs(double(b[i]) - c[i])});
    sum += std::fabs(double(c[i]) - 0.25);
  }
  EXPECT_GT(sum, 10.0);  // the products were added
  EXPECT_LE(worst, 1e-6);
}

// The fading difference over binary16 spectra (AVX2 + F16C here) equals
// the float kernel on the converted differences, and its portable loop, to
// float rounding; for equal spectra and scales it adds exactly nothing.
TEST(CompactSpectra, DifferenceMultiplyAccumulateEqualsTheFloatKernel) {
  const size_t partitions = 7, stride = 264, k0 = 1, parts = 6;
  const float sp = 0.125f, sc = 0.5f;
  Pcg32 rng(18, 19);
  std::vector<std::vector<float>> x(parts, std::vector<float>(2 * stride)), d(partitions);
  std::vector<uint16_t> p(partitions * 2 * stride), c(partitions * 2 * stride);
  for (auto& v : x)
    for (auto& e : v) e = float(rng.uniformDouble() * 2 - 1);
  for (size_t k = 0; k < partitions; ++k) {
    d[k].resize(2 * stride);
    for (size_t i = 0; i < stride; i += dsp_detail::compactTileWidth(i, stride)) {
      const size_t w = dsp_detail::compactTileWidth(i, stride);
      const size_t off = dsp_detail::compactTileOffset(i, k, partitions, stride);
      for (size_t b = 0; b < 2 * w; ++b) {
        p[off + b] = dsp_detail::floatToHalf(float(rng.uniformDouble() * 2 - 1));
        c[off + b] = dsp_detail::floatToHalf(float(rng.uniformDouble() * 2 - 1));
        d[k][(b < w ? 0 : stride) + i + b % w] =
            sp * dsp_detail::halfToFloat(p[off + b]) - sc * dsp_detail::halfToFloat(c[off + b]);
      }
    }
  }
  std::vector<const float*> xs, ds;
  for (size_t j = 0; j < parts; ++j) {
    xs.push_back(x[j].data());
    ds.push_back(d[k0 + j].data());
  }
  std::vector<float> a(2 * stride, 0.25f), b(2 * stride, 0.25f), ref(2 * stride, 0.25f);
  dsp_detail::complexMacDiffBatchHalf(a.data(), a.data() + stride, xs.data(), p.data(), sp, c.data(), sc, k0, parts,
                                      partitions, stride);
  dsp_detail::complexMacDiffBatchHalfPortable(b.data(), b.data() + stride, xs.data(), p.data(), sp, c.data(), sc, k0,
                                              parts, partitions, stride);
  dsp_detail::complexMacBatch(ref.data(), ref.data() + stride, xs.data(), ds.data(), parts, stride, stride);
  double worst = 0, sum = 0;
  for (size_t i = 0; i < 2 * stride; ++i) {
    worst = std::max({worst, std::fabs(double(a[i]) - ref[i]), std::fabs(double(b[i]) - ref[i])});
    sum += std::fabs(double(ref[i]) - 0.25);
  }
  EXPECT_GT(sum, 10.0);  // the products were added
  EXPECT_LE(worst, 1e-6);  // measured 2.4e-7
  // Equal spectra under equal scales: the accumulator unchanged, bit for bit.
  std::vector<float> same(2 * stride, 0.25f), samePortable(2 * stride, 0.25f);
  dsp_detail::complexMacDiffBatchHalf(same.data(), same.data() + stride, xs.data(), p.data(), sp, p.data(), sp, k0,
                                      parts, partitions, stride);
  dsp_detail::complexMacDiffBatchHalfPortable(samePortable.data(), samePortable.data() + stride, xs.data(), p.data(),
                                              sp, p.data(), sp, k0, parts, partitions, stride);
  EXPECT_EQ(same, std::vector<float>(2 * stride, 0.25f));
  EXPECT_EQ(samePortable, std::vector<float>(2 * stride, 0.25f));
}

// The ambisonic bus stores its IR spectra as binary16 (compactSpectra):
// 8 sources of 4-channel IRs with leading silence, one of them swapped
// mid-stream (the fading path converts the halves), against the direct
// convolution. Bound: each spectrum value keeps 11 significant bits
// (relative error <= 2^-11), so the output's error, a sum of those errors
// weighted as the output itself is, has at most 2^-22 of the output's
// energy (-66.2 dB) as long as the products do not cancel in the output
// (they add incoherently in a reverberant sum); asserted, measured -74 dB
// (the errors spread uniformly below their bound). The largest error is
// asserted below 2^-11 of the peak. The float mixer
// on the same input stays at float precision (1e-5 of the peak), so the
// difference is the storage.
TEST(ConvolutionMixer, CompactSpectraErrorIsSmallAndBounded) {
  const size_t sources = 8, channels = 4, irLen = 7682, block = 256, warmUp = 8192, signal = 6000;
  const size_t frames = warmUp + signal;
  for (bool compact : {false, true}) {
    ConvolverSettings s;
    s.latencyFrames = block;
    s.maxIrFrames = irLen;
    s.channels = channels;
    s.compactSpectra = compact;
    auto mixer = ConvolutionMixer::create(s, sources);
    ASSERT_TRUE(mixer.isOk());
    ConvolutionMixer& m = **mixer;
    ASSERT_EQ(m.layout().compactSpectra(), compact);
    std::vector<std::vector<float>> inputs;
    std::vector<std::vector<double>> want(channels, std::vector<double>(frames, 0.0));
    std::vector<std::vector<float>> lastIr;
    for (size_t src = 0; src < sources; ++src) {
      const size_t silent = (src * 997) % 3600;
      std::vector<std::vector<float>> ir;
      for (size_t c = 0; c < channels; ++c) {
        std::vector<float> ch = decayingNoise(irLen, 500 + 7 * src + c);
        std::fill(ch.begin(), ch.begin() + long(silent), 0.0f);
        for (float& v : ch) v *= c == 0 ? 1.0f : 0.3f;  // the directional channels quieter, as in a room
        ir.push_back(std::move(ch));
      }
      auto prepared = prepare(ir, m.layout());
      ASSERT_EQ(prepared->compact(), compact);
      ASSERT_TRUE(m.setIr(src, prepared).isOk());
      std::vector<float> x = decayingNoise(signal, 700 + src, 0.0);
      for (size_t c = 0; c < channels; ++c) {
        auto y = directConvolve(x, ir[c], signal);
        for (size_t t = 0; t < signal; ++t) want[c][warmUp + t] += y[t];
      }
      x.insert(x.begin(), warmUp, 0.0f);
      inputs.push_back(std::move(x));
      lastIr = ir;
    }
    std::vector<std::vector<float>> out(channels, std::vector<float>(frames));
    std::vector<const float*> ins(sources);
    std::vector<float*> outs(channels);
    for (size_t pos = 0; pos < frames; pos += block) {
      // Halfway through the warm-up (silence), the last source's IR is set
      // again: every level fades from it to itself, through the fading path.
      if (pos == warmUp / 2) {
        ASSERT_TRUE(m.setIr(sources - 1, prepare(lastIr, m.layout())).isOk());
      }
      for (size_t src = 0; src < sources; ++src) ins[src] = inputs[src].data() + pos;
      for (size_t c = 0; c < channels; ++c) outs[c] = out[c].data() + pos;
      m.process(ins.data(), outs.data(), std::min(block, frames - pos));
    }
    double peak = 0, worst = 0, signalEnergy = 0, errorEnergy = 0;
    for (size_t c = 0; c < channels; ++c)
      for (size_t t = block; t < frames; ++t) {
        const double e = want[c][t - block] - out[c][t];
        peak = std::max(peak, std::fabs(want[c][t - block]));
        worst = std::max(worst, std::fabs(e));
        signalEnergy += want[c][t - block] * want[c][t - block];
        errorEnergy += e * e;
      }
    const double errorDb = 10 * std::log10(errorEnergy / signalEnergy);
    EXPECT_GT(peak, 1.0);
    if (compact) {
      EXPECT_LE(errorDb, 20 * std::log10(std::ldexp(1.0, -11)));  // -66.2 dB
      EXPECT_LE(worst, std::ldexp(1.0, -11) * peak);
      EXPECT_GT(errorDb, -100.0);  // the storage is really binary16 (float would be ~-130 dB)
    } else {
      EXPECT_LE(worst, 1e-5 * peak);
    }
    std::printf("compact=%d: error energy %.1f dB of the output's, largest error %.2e of the peak\n", int(compact),
                errorDb, worst / peak);
  }
  // An IR prepared for the float layout does not fit a compact mixer.
  ConvolverSettings s;
  s.latencyFrames = block;
  s.maxIrFrames = irLen;
  s.channels = channels;
  auto floatMixer = ConvolutionMixer::create(s, sources);
  s.compactSpectra = true;
  auto compactMixer = ConvolutionMixer::create(s, sources);
  ASSERT_TRUE(floatMixer.isOk() && compactMixer.isOk());
  std::vector<std::vector<float>> ir(channels, decayingNoise(irLen, 9));
  EXPECT_FALSE((*compactMixer)->setIr(0, prepare(ir, (*floatMixer)->layout())).isOk());
}

// An IR of denormal taps (its spectrum's peak under 2^-136) prepared as
// compact spectra: the channel's scale is a normal float and every half is
// finite (a zero scale made 0 / 0 NaN halves), and a mixer plays it as
// silence.
TEST(CompactSpectra, AnIrOfDenormalsGivesFiniteHalves) {
  ConvolverSettings s;
  s.latencyFrames = 256;
  s.maxIrFrames = 4096;
  s.channels = 1;
  s.compactSpectra = true;
  auto mixer = ConvolutionMixer::create(s, 1);
  ASSERT_TRUE(mixer.isOk());
  std::vector<std::vector<float>> ir(1, std::vector<float>(4096, 0.0f));
  ir[0][0] = 1e-39f;  // subnormal: its spectrum's values, 1e-39 / 2P, are under 2^-136
  ir[0][100] = -3e-40f;
  auto prepared = PreparedIr::create(ir, (*mixer)->layout());
  ASSERT_TRUE(prepared.isOk()) << prepared.status().message();
  const PreparedIr& p = **prepared;
  ASSERT_TRUE(p.compact());
  for (size_t l = 0; l < (*mixer)->layout().levels().size(); ++l) {
    EXPECT_TRUE(std::isnormal(p.spectrumScale(l, 0))) << "level " << l;
    const PartitionLevel& lv = (*mixer)->layout().levels()[l];
    const uint16_t* h = p.compactSpectra(l, 0);
    const size_t n = lv.partitionCount * 2 * dsp_detail::padBins(lv.partitionFrames + 1);
    for (size_t i = 0; i < n; ++i) ASSERT_TRUE(std::isfinite(dsp_detail::halfToFloat(h[i]))) << "level " << l << " " << i;
  }
  ASSERT_TRUE((*mixer)->reserveSource(0).isOk());
  ASSERT_TRUE((*mixer)->setIr(0, *prepared).isOk());
}

// A pool's threads share the levels and channels of PreparedIr::create and
// give the bits of the caller alone, compact or float spectra. The IR has
// leading silence (skipped partitions), a decaying tail and a subnormal tap
// (its spectrum is subnormal: the pool's threads run with denormals flushed
// unless they take the caller's mode, and then the bits differ).
TEST(PreparedIr, AThreadPoolGivesTheCallersBits) {
  for (const bool compact : {false, true}) {
    ConvolverSettings s;
    s.latencyFrames = 64;
    s.maxIrFrames = 60000;
    s.channels = 4;
    s.compactSpectra = compact;
    auto mixer = ConvolutionMixer::create(s, 1);
    ASSERT_TRUE(mixer.isOk());
    const PartitionLayout& layout = (*mixer)->layout();
    ASSERT_GE(layout.levels().size(), 2u);
    std::vector<std::vector<float>> ir;
    for (size_t c = 0; c < 4; ++c) {
      ir.push_back(decayingNoise(50000, 7 + c));
      std::fill(ir.back().begin(), ir.back().begin() + 700 + 300 * c, 0.0f);
      ir.back()[5000] = 1e-39f;
    }
    ir[3].assign(50000, 0.0f);  // a silent channel
    ir[3][47000] = 2e-39f;
    auto alone = PreparedIr::create(ir, layout);
    ASSERT_TRUE(alone.isOk()) << alone.status().message();
    for (unsigned threads : {2u, 3u}) {
      ThreadPool pool(threads);
      auto shared = PreparedIr::create(ir, layout, &pool);
      ASSERT_TRUE(shared.isOk()) << shared.status().message();
      const PreparedIr& a = **alone;
      const PreparedIr& b = **shared;
      ASSERT_EQ(a.compact(), compact);
      ASSERT_EQ(b.compact(), compact);
      for (size_t l = 0; l < layout.levels().size(); ++l) {
        ASSERT_EQ(a.activePartitions(l), b.activePartitions(l));
        ASSERT_EQ(a.firstActivePartition(l), b.firstActivePartition(l));
        const size_t n = layout.levels()[l].partitionCount * 2 * a.binStride(l);
        for (size_t c = 0; c < 4; ++c) {
          if (compact) {
            EXPECT_EQ(a.spectrumScale(l, c), b.spectrumScale(l, c)) << "level " << l << " channel " << c;
            EXPECT_EQ(0, std::memcmp(a.compactSpectra(l, c), b.compactSpectra(l, c), n * sizeof(uint16_t)))
                << "level " << l << " channel " << c << ", " << threads << " threads";
          } else {
            EXPECT_EQ(0, std::memcmp(a.spectrum(l, c, 0), b.spectrum(l, c, 0), n * sizeof(float)))
                << "level " << l << " channel " << c << ", " << threads << " threads";
          }
        }
      }
    }
  }
}

// After loud noise, silence through an IR whose tail decays to 1e-40
// (subnormal territory) leaves no subnormal number anywhere in the state:
// process() flushes denormals. It also restores the caller's FP mode.
TEST(Convolver, NoDenormalsAfterLoudNoise) {
  const size_t irLen = 24000, block = 256;
  std::vector<std::vector<float>> ir = {decayingNoise(irLen, 71, -800), decayingNoise(irLen, 72, -800)};
  auto conv = makeConvolver(block, irLen, 2);
  ASSERT_TRUE(conv->setIr(prepare(ir, conv->layout())).isOk());
  std::vector<float> x = decayingNoise(48000, 73, 0.0);
  x.resize(48000 * 3, 0.0f);
#if defined(__SSE__) || defined(__x86_64__)
  const unsigned before = _mm_getcsr();
#endif
  std::vector<std::vector<float>> out(2, std::vector<float>(block));
  float* outs[2] = {out[0].data(), out[1].data()};
  size_t checks = 0;
  for (size_t pos = 0; pos + block <= x.size(); pos += block) {
    conv->process(x.data() + pos, outs, block);
    if ((pos / block) % 37 == 0) {
      ASSERT_EQ(conv->countSubnormalsInState(), 0u) << "frame " << pos;
      ++checks;
    }
    for (size_t c = 0; c < 2; ++c)
      for (float v : out[c]) ASSERT_NE(std::fpclassify(v), FP_SUBNORMAL) << "frame " << pos;
  }
  EXPECT_GT(checks, 10u);
#if defined(__SSE__) || defined(__x86_64__)
  EXPECT_EQ(_mm_getcsr(), before);
#endif
}

TEST(Convolver, RejectsBadSettingsAndMismatchedIrs) {
  ConvolverSettings s;
  s.latencyFrames = 7;
  EXPECT_FALSE(Convolver::create(s).isOk());
  s.latencyFrames = 14;  // prime factor 7: KissFFT would allocate in process
  EXPECT_FALSE(Convolver::create(s).isOk());
  s.latencyFrames = 64;
  s.channels = 0;
  EXPECT_FALSE(Convolver::create(s).isOk());
  s.channels = 2;
  s.maxIrFrames = 1000;
  auto conv = Convolver::create(s);
  ASSERT_TRUE(conv.isOk());
  auto mono = PreparedIr::create(std::vector<std::vector<float>>{std::vector<float>(10, 1.0f)}, (*conv)->layout());
  ASSERT_TRUE(mono.isOk());
  EXPECT_FALSE((*conv)->setIr(*mono).isOk());
  auto tooLong = PreparedIr::create(std::vector<std::vector<float>>(2, std::vector<float>(1000000, 1.0f)),
                                    (*conv)->layout());
  EXPECT_FALSE(tooLong.isOk());
  std::vector<std::vector<float>> nan(2, std::vector<float>(10, 0.0f));
  nan[1][3] = NAN;
  auto bad = PreparedIr::create(nan, (*conv)->layout());
  ASSERT_FALSE(bad.isOk());
  EXPECT_NE(bad.status().message().find("tap 3"), std::string::npos);
}

}  // namespace
}  // namespace earshot

namespace earshot {
namespace {

// A mixer's per-source state is allocated only for sources reserved or given
// an IR (issue 19: lazy context creation); a source without state is not
// heard, and one reserved mid-stream starts from silence.
TEST(ConvolutionMixer, SourceStateIsAllocatedOnFirstUse) {
  ConvolverSettings s;
  s.latencyFrames = 128;
  s.maxIrFrames = 4000;
  s.channels = 2;
  auto mixer = ConvolutionMixer::create(s, 64);
  ASSERT_TRUE(mixer.isOk());
  ConvolutionMixer& m = **mixer;
  EXPECT_EQ(m.reservedSources(), 0u);
  std::vector<std::vector<float>> ir = {std::vector<float>(4000, 0.0f), std::vector<float>(4000, 0.0f)};
  ir[0][0] = ir[1][10] = 1.0f;  // left: identity, right: 10 frames late
  ASSERT_TRUE(m.setIr(5, prepare(ir, m.layout())).isOk());
  EXPECT_EQ(m.reservedSources(), 1u);
  ASSERT_TRUE(m.reserveSource(5).isOk());  // idempotent
  EXPECT_EQ(m.reservedSources(), 1u);
  EXPECT_FALSE(m.reserveSource(64).isOk());
  EXPECT_FALSE(m.setIr(64, nullptr).isOk());

  std::vector<float> x = decayingNoise(2048, 11, 0.0);
  std::vector<const float*> ins(64, x.data());  // every source fed the same input
  std::vector<std::vector<float>> out(2, std::vector<float>(2048));
  float* outs[2] = {out[0].data(), out[1].data()};
  m.process(ins.data(), outs, 2048);
  // Only source 5 has state: the output is x through its IR, not 64 x.
  for (size_t t = 0; t + 128 < 2048; ++t) {
    ASSERT_NEAR(out[0][t + 128], x[t], 1e-5) << t;
    if (t >= 10) {
      ASSERT_NEAR(out[1][t + 128], x[t - 10], 1e-5) << t;
    }
  }
  // Reserved while streaming: source 9 joins from silence, then is heard
  // once it has an IR.
  ASSERT_TRUE(m.reserveSource(9).isOk());
  EXPECT_EQ(m.reservedSources(), 2u);
  ASSERT_TRUE(m.setIr(9, prepare(ir, m.layout())).isOk());
  for (int rep = 0; rep < 4; ++rep) m.process(ins.data(), outs, 2048);
  for (size_t t = 0; t + 128 < 2048; ++t) ASSERT_NEAR(out[0][t + 128], 2 * x[t], 1e-5) << t;
}

}  // namespace
}  // namespace earshot
