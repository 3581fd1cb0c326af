// The direct sound of a moving source: see direct_voice.h.
#include "earshot/runtime/direct_voice.h"

#include "earshot/hrtf/coordinates.h"
#include "earshot/ir/spherical_harmonics.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>

#include "earshot/core/math.h"
#include "earshot/core/target_clones.h"
#include "earshot/dsp/fir.h"

namespace earshot::runtime {

namespace {

// Frames per inner chunk: bounds the scratch buffers whatever the host block.
constexpr size_t kChunk = 256;
// Shortest delay the interpolator supports (it reads four samples ahead).
constexpr double kMinDelaySamples = 6.0;
constexpr int kTaps = 8, kPhases = 512;

}  // namespace

// Fractional-delay interpolator: 8-tap Kaiser-windowed sinc (beta 6), in 512
// phases, each normalised to unit DC gain. Flatter than a cubic: Catmull-Rom
// at half a sample loses 1 dB at 12 kHz and 3 dB at 16 kHz; this loses about
// 0.1 dB at 12 kHz (tested through the HRTF's broadband energy).
struct SincTable {
  float taps[kPhases + 1][kTaps];
  SincTable() {
    auto bessel0 = [](double x) {
      double sum = 1, term = 1;
      for (int k = 1; k < 30; ++k) {
        term *= (x / (2 * k)) * (x / (2 * k));
        sum += term;
      }
      return sum;
    };
    const double beta = 6.0;
    for (int p = 0; p <= kPhases; ++p) {
      const double frac = double(p) / kPhases;  // position between tap 3 and tap 4
      double sum = 0, v[kTaps];
      for (int k = 0; k < kTaps; ++k) {
        const double x = double(k - 3) - frac;  // distance from the read position
        const double sinc = std::fabs(x) < 1e-12 ? 1.0 : std::sin(kPi * x) / (kPi * x);
        const double w = x / (kTaps / 2.0);
        const double win = std::fabs(w) >= 1 ? 0.0 : bessel0(beta * std::sqrt(1 - w * w)) / bessel0(beta);
        v[k] = sinc * win;
        sum += v[k];
      }
      for (int k = 0; k < kTaps; ++k) taps[p][k] = float(v[k] / sum);
    }
  }
};

namespace {
const SincTable& sincTable() {
  static const SincTable table;
  return table;
}
// 8-float vectors for the delayed reads below (which get an AVX2+FMA clone
// where the CPU has it: EARSHOT_CLONES).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
typedef float FirV8 __attribute__((vector_size(32)));
#pragma GCC diagnostic pop

// The delayed, gain-ramped reads of a chunk for one or two outputs (the
// ears, or the head centre): out_e[i] = g_i * x(base + i - d_e,i), x read by
// the 8-tap windowed sinc at its fractional position, with d_e,i and g_i
// ramping linearly from (d0, g0) to (d0 + dd, g0 + dg) at i = total - offset
// - 1 (as DirectVoice::processChunk's crossfade). The ring has kTaps guard
// floats after its end that mirror its start, so the 8 taps of a read are
// contiguous; a phase's taps are interpolated and multiplied with them as
// one 8-float vector, and the two outputs' sums reduced together (a scalar
// loop of dependent adds per ear was a fifth of the audio thread with 32
// sources).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
struct DelayRamp {
  double d0[2], dd[2], g0, dg;
  size_t offset, total;
};
static inline void sincProduct(const float* __restrict ring, size_t mask, const float* __restrict table,
                               double position, FirV8& product) {
  const double fl = std::floor(position);
  const double p = (position - fl) * kPhases;
  const int phase = std::min(int(p), kPhases - 1);
  const float f = float(p - phase);
  // Taps at fl - 3 .. fl + 4; fl may be negative before the line fills
  // (the ring reads zeros there): wrap it through a signed integer.
  const size_t start = size_t(int64_t(fl) - 3) & mask;
  FirV8 ta, tb, x;
  std::memcpy(&ta, table + size_t(phase) * kTaps, sizeof ta);
  std::memcpy(&tb, table + size_t(phase + 1) * kTaps, sizeof tb);
  std::memcpy(&x, ring + start, sizeof x);
  product = (ta + f * (tb - ta)) * x;
}
EARSHOT_CLONES
void delayedReads(const float* __restrict ring, size_t mask, const float* __restrict table, size_t base,
                  const DelayRamp& r, float* __restrict out0, float* __restrict out1, size_t frames) {
  const double total = double(r.total);
  for (size_t i = 0; i < frames; ++i) {
    const double a = double(r.offset + i + 1) / total;
    const double now = double(base + i);
    const double g = r.g0 + r.dg * a;
    FirV8 p0, p1;
    sincProduct(ring, mask, table, now - (r.d0[0] + r.dd[0] * a), p0);
    if (!out1) {
      out0[i] = float(g * double(((p0[0] + p0[4]) + (p0[1] + p0[5])) + ((p0[2] + p0[6]) + (p0[3] + p0[7]))));
      continue;
    }
    sincProduct(ring, mask, table, now - (r.d0[1] + r.dd[1] * a), p1);
    // Both sums at once: halves side by side, then pairs, then neighbours.
    // (__builtin_shufflevector: GCC >= 12 and clang; __builtin_shuffle is GCC's only.)
    FirV8 u = __builtin_shufflevector(p0, p1, 0, 1, 2, 3, 8, 9, 10, 11) +
              __builtin_shufflevector(p0, p1, 4, 5, 6, 7, 12, 13, 14, 15);
    u += __builtin_shufflevector(u, u, 2, 3, 0, 1, 6, 7, 4, 5);
    u += __builtin_shufflevector(u, u, 1, 0, 3, 2, 5, 4, 7, 6);
    out0[i] = float(g * double(u[0]));
    out1[i] = float(g * double(u[4]));
  }
}
#pragma GCC diagnostic pop

// The smallest turn of a source's direction (in the head's frame) that
// changes its HRIR: 0.25 degrees, a quarter of the smallest angle a
// listener tells apart (about 1 degree, straight ahead).
const double kMinHrirTurnCos = std::cos(0.25 * kPi / 180.0);

// A jump: the delay changes by more than this fraction of the block's frames
// (a source or listener faster than half the speed of sound: a teleport,
// not motion). Ramping the delay across it would read the line at many
// times its rate, an aliased chirp; the block crossfades instead from the
// line read at the old delay to the line read at the new one.
constexpr double kJumpDelayPerFrame = 0.5;

// Reads the line at both ends of a jump (each at its own fixed delay and
// gain) and crossfades them into out0/out1, linearly over the block as the
// ramp would have gone (weight (offset + i + 1) / total of the new end).
// other0/other1: chunk-sized scratch.
void jumpReads(const float* ring, size_t mask, const float* table, size_t base, const DelayRamp& r, float* out0,
               float* out1, float* other0, float* other1, size_t frames) {
  const DelayRamp from{{r.d0[0], r.d0[1]}, {0.0, 0.0}, r.g0, 0.0, r.offset, r.total};
  const DelayRamp to{{r.d0[0] + r.dd[0], r.d0[1] + r.dd[1]}, {0.0, 0.0}, r.g0 + r.dg, 0.0, r.offset, r.total};
  delayedReads(ring, mask, table, base, from, out0, out1, frames);
  delayedReads(ring, mask, table, base, to, other0, out1 ? other1 : nullptr, frames);
  for (size_t i = 0; i < frames; ++i) {
    const float w = float(double(r.offset + i + 1) / double(r.total));
    out0[i] += w * (other0[i] - out0[i]);
    if (out1) out1[i] += w * (other1[i] - out1[i]);
  }
}

bool isJump(const double from[2], const double to[2], size_t frames, int ears) {
  for (int e = 0; e < ears; ++e)
    if (std::fabs(to[e] - from[e]) > kJumpDelayPerFrame * double(frames)) return true;
  return false;
}

// Shelf corners, Hz.
constexpr double kLowShelfHz = 250.0, kHighShelfHz = 4000.0;

size_t nextPow2(size_t n) {
  size_t p = 1;
  while (p < n) p *= 2;
  return p;
}

// RBJ Audio EQ Cookbook shelving filters, shelf slope S = 1.
void setShelf(float& b0, float& b1, float& b2, float& a1, float& a2, double fs, double f0, double gainDb, bool high) {
  const double A = std::pow(10.0, gainDb / 40.0);
  const double w0 = 2.0 * kPi * std::min(f0, 0.45 * fs) / fs, cw = std::cos(w0), sw = std::sin(w0);
  const double alpha = sw / 2.0 * std::sqrt(2.0);
  const double sq = 2.0 * std::sqrt(A) * alpha;
  double nb0, nb1, nb2, na0, na1, na2;
  if (!high) {
    nb0 = A * ((A + 1) - (A - 1) * cw + sq);
    nb1 = 2 * A * ((A - 1) - (A + 1) * cw);
    nb2 = A * ((A + 1) - (A - 1) * cw - sq);
    na0 = (A + 1) + (A - 1) * cw + sq;
    na1 = -2 * ((A - 1) + (A + 1) * cw);
    na2 = (A + 1) + (A - 1) * cw - sq;
  } else {
    nb0 = A * ((A + 1) + (A - 1) * cw + sq);
    nb1 = -2 * A * ((A - 1) + (A + 1) * cw);
    nb2 = A * ((A + 1) + (A - 1) * cw - sq);
    na0 = (A + 1) - (A - 1) * cw + sq;
    na1 = 2 * ((A - 1) - (A + 1) * cw);
    na2 = (A + 1) - (A - 1) * cw - sq;
  }
  b0 = float(nb0 / na0);
  b1 = float(nb1 / na0);
  b2 = float(nb2 / na0);
  a1 = float(na1 / na0);
  a2 = float(na2 / na0);
}

// Pressure ratio in dB, with silence clamped to -120 dB.
double ratioDb(double num, double den) {
  if (!(den > 0)) return 0.0;
  return gainToDb(std::max(num / den, 1e-6));
}

double maxDelayFrames(const DirectVoiceSettings& s) {
  return s.maxDelaySeconds * s.sampleRateHz + double(s.extraDelayFrames);
}

// The delay line: the delay plus the HRTF's largest onset (|delay| < 2 ms
// for any head) plus margins, in a power of two.
size_t ringFrames(const DirectVoiceSettings& s) {
  return nextPow2(size_t(maxDelayFrames(s) + 0.002 * s.sampleRateHz) + kChunk + 16);
}

}  // namespace

size_t DirectVoice::stateBytes(const DirectVoiceSettings& s) {
  const size_t hrirTaps = hrtf::HrirPair::kMaxTaps;  // any HRTF set's
  const size_t floats = ringFrames(s) + kTaps + 2 * (3 * hrirTaps - 1 + kChunk) + 3 * kChunk;
  return floats * sizeof(float) + 2 * sizeof(hrtf::HrirPair) + sizeof(DirectVoice);
}

Result<std::unique_ptr<DirectVoice>> DirectVoice::create(const DirectVoiceSettings& s,
                                                         std::shared_ptr<const hrtf::HrtfSet> hrtf) {
  if (!hrtf) return invalidArgument("direct voice: no HRTF set");
  if (!(s.sampleRateHz >= 8000 && s.sampleRateHz <= 384000))
    return invalidArgument("direct voice: sample rate " + std::to_string(s.sampleRateHz) + " Hz is outside [8000, 384000]");
  if (std::fabs(hrtf->sampleRateHz() - s.sampleRateHz) > 1e-6)
    return invalidArgument("direct voice: the HRTF set is at " + std::to_string(hrtf->sampleRateHz()) + " Hz, not " +
                           std::to_string(s.sampleRateHz));
  if (!(s.speedOfSound >= 1 && s.speedOfSound <= 10000)) return invalidArgument("direct voice: speed of sound out of range");
  if (!(s.maxDelaySeconds > 0 && s.maxDelaySeconds <= 60)) return invalidArgument("direct voice: max delay outside (0, 60] s");
  if (s.extraDelayFrames > size_t(1) << 20) return invalidArgument("direct voice: extra delay over 2^20 frames");
  if (!(s.minDistanceMeters > 0)) return invalidArgument("direct voice: min distance must be > 0");
  EARSHOT_RETURN_IF_ERROR(validate(s.air));
  std::unique_ptr<DirectVoice> v(new DirectVoice());
  v->mSettings = s;
  v->mSincTable = &sincTable();
  v->mHrtf = std::move(hrtf);
  v->mAirDbPerMeter = s.air.enabled ? airAttenuationDbPerMeter(s.air) : filledBands(0.0);
  v->mMaxDelay = maxDelayFrames(s);
  v->mRing.assign(ringFrames(s) + kTaps, 0.0f);  // + a guard mirroring the start (delayedReads)
  v->mRingMask = ringFrames(s) - 1;
  v->mHrir = std::make_unique<hrtf::HrirPair>();
  v->mHrirNext = std::make_unique<hrtf::HrirPair>();
  const size_t taps = v->mHrtf->hrirLength();
  for (int e = 0; e < 2; ++e) {
    v->mTaps[e].assign(taps, 0.0f);
    v->mTapsNext[e].assign(taps, 0.0f);
    v->mHistory[e].assign(taps - 1 + kChunk, 0.0f);
  }
  v->mScratch.assign(kChunk, 0.0f);
  v->mScratchNext.assign(kChunk, 0.0f);
  v->mFade.assign(kChunk, 0.0f);
  return v;
}

size_t DirectVoice::ringOutFrames() const {
  if (!mStarted) return 0;
  return size_t(std::ceil(std::max(mDelay[0], mDelay[1]))) + size_t(kTaps) + mTaps[0].size();
}

void DirectVoice::reset() {
  std::fill(mRing.begin(), mRing.end(), 0.0f);
  for (auto& h : mHistory) std::fill(h.begin(), h.end(), 0.0f);
  mLow.z1 = mLow.z2 = mHigh.z1 = mHigh.z2 = 0;
  mShelfFade = false;
  mShelvesSet = false;
  mStarted = false;
}

DirectVoice::Params DirectVoice::paramsFor(const DirectTarget& t, Vec3f& headDirection, bool centre) const {
  Params p;
  const Vec3d d = t.source - t.listener;
  const double r = length(d);
  const Vec3d dir = r > 1e-9 ? d / r : normalize(t.orientation.forward);
  headDirection = Vec3f(toHeadFrame(dir, t.orientation));
  mHrtf->lookup(headDirection, *mHrirNext);
  const double fs = mSettings.sampleRateHz;
  const double travel = std::min(r / mSettings.speedOfSound, mSettings.maxDelaySeconds);
  const double ear[2] = {centre ? 0.0 : mHrirNext->leftDelaySeconds, centre ? 0.0 : mHrirNext->rightDelaySeconds};
  for (int e = 0; e < 2; ++e)
    p.delay[e] = std::clamp(std::max(0.0, travel + ear[e]) * fs + double(mSettings.extraDelayFrames), kMinDelaySamples,
                            mMaxDelay);
  BandArrayD g;
  for (int b = 0; b < kNumBands; ++b)
    g[b] = t.audible ? std::pow(10.0, -mAirDbPerMeter[b] * r / 20.0) * std::max(0.0, t.transmission[b]) : 0.0;
  const double spreading = 1.0 / std::max(r, mSettings.minDistanceMeters);
  const double g1k = g[3];
  p.gain = std::isfinite(t.gain) ? t.gain * spreading * g1k : 0.0;
  p.lowDb = ratioDb(g[0], g1k);
  p.highDb = ratioDb(g[kNumBands - 1], g1k);
  return p;
}

void DirectVoice::setShelves(const Params& to) {
  const double fs = mSettings.sampleRateHz;
  // A shelf that changes by more than this (an occluder came or went, a
  // door closed) is crossfaded over the block: switching the coefficients
  // of a running biquad at once made a tick (a 200 Hz tone's block after
  // a 20 dB change had -27 dB of its energy above 2 kHz). Smaller changes
  // (air absorption as a source moves) switch at once, as before.
  constexpr double kShelfFadeDb = 0.5;
  mShelfFade = mShelvesSet && (std::fabs(to.lowDb - mShelfDb[0]) > kShelfFadeDb ||
                               std::fabs(to.highDb - mShelfDb[1]) > kShelfFadeDb);
  if (mShelfFade) {  // the new filters start from the old ones' state
    mLowNext = mLow;
    mHighNext = mHigh;
  }
  Biquad& low = mShelfFade ? mLowNext : mLow;
  Biquad& high = mShelfFade ? mHighNext : mHigh;
  setShelf(low.b0, low.b1, low.b2, low.a1, low.a2, fs, kLowShelfHz, to.lowDb, false);
  setShelf(high.b0, high.b1, high.b2, high.a1, high.a2, fs, kHighShelfHz, to.highDb, true);
  mShelfDb[0] = to.lowDb;
  mShelfDb[1] = to.highDb;
  mShelvesSet = true;
}

void DirectVoice::endShelfFade() {
  if (!mShelfFade) return;
  mLow = mLowNext;
  mHigh = mHighNext;
  mShelfFade = false;
}

size_t DirectVoice::pushInput(const float* input, size_t frames, size_t offset, size_t total) {
  const size_t base = mWrite;
  // The shelves as locals: with them in the object, each ring store may
  // alias their state, which then went to memory and back every sample.
  // The same operations in the same order.
  Biquad low = mLow, high = mHigh;
  float* ring = mRing.data();
  const size_t mask = mRingMask;
  size_t write = mWrite;
  if (mShelfFade) {
    // Both filters run; the output fades from the old to the new linearly
    // over the whole block (offset: this chunk's place in it).
    Biquad lowNext = mLowNext, highNext = mHighNext;
    for (size_t i = 0; i < frames; ++i) {
      const float x = input ? input[i] : 0.0f;
      const size_t w = (write++) & mask;
      const float y0 = high.run(low.run(x));
      const float y1 = highNext.run(lowNext.run(x));
      const float y = y0 + float(double(offset + i + 1) / double(total)) * (y1 - y0);
      ring[w] = y;
      if (w < size_t(kTaps)) ring[w + mask + 1] = y;
    }
    mLowNext = lowNext;
    mHighNext = highNext;
  } else {
    for (size_t i = 0; i < frames; ++i) {
      const float x = input ? input[i] : 0.0f;
      const size_t w = (write++) & mask;
      const float y = high.run(low.run(x));
      ring[w] = y;
      if (w < size_t(kTaps)) ring[w + mask + 1] = y;
    }
  }
  mWrite = write;
  mLow = low;
  mHigh = high;
  return base;
}

void DirectVoice::processChunk(const float* input, float* left, float* right, size_t frames, const Params& from,
                               const Params& to, size_t offset, size_t total, bool crossfade, bool jump) {
  const size_t base = pushInput(input, frames, offset, total);
  const size_t taps = mTaps[0].size();
  float* out[2] = {left, right};
  const DelayRamp ramp{{from.delay[0], from.delay[1]},
                       {to.delay[0] - from.delay[0], to.delay[1] - from.delay[1]},
                       from.gain,
                       to.gain - from.gain,
                       offset,
                       total};
  if (jump)
    jumpReads(mRing.data(), mRingMask, &mSincTable->taps[0][0], base, ramp, mHistory[0].data() + taps - 1,
              mHistory[1].data() + taps - 1, mScratch.data(), mScratchNext.data(), frames);
  else
    delayedReads(mRing.data(), mRingMask, &mSincTable->taps[0][0], base, ramp, mHistory[0].data() + taps - 1,
                 mHistory[1].data() + taps - 1, frames);
  float* fade = mFade.data();  // the same weights for both ears
  if (crossfade)
    for (size_t i = 0; i < frames; ++i) fade[i] = float(double(offset + i + 1) / double(total));
  for (int e = 0; e < 2; ++e) {
    float* hist = mHistory[e].data();
    auto fir = [&](const float* h, float* y) { firInto(h, taps, hist, y, frames); };
    float* y = mScratch.data();
    fir(mTaps[e].data(), y);
    if (crossfade) {
      float* yn = mScratchNext.data();
      fir(mTapsNext[e].data(), yn);
      for (size_t i = 0; i < frames; ++i) y[i] += fade[i] * (yn[i] - y[i]);
    }
    for (size_t i = 0; i < frames; ++i) out[e][i] += y[i];
    std::memmove(hist, hist + frames, (taps - 1) * sizeof(float));
  }
}

void DirectVoice::process(const float* input, float* left, float* right, size_t frames, const DirectTarget& target) {
  if (frames == 0) return;
  Vec3f head;
  const Params to = paramsFor(target, head);  // looks up mHrirNext
  const size_t taps = mTaps[0].size();
  for (size_t j = 0; j < taps; ++j) {
    mTapsNext[0][j] = mHrirNext->left[taps - 1 - j];
    mTapsNext[1][j] = mHrirNext->right[taps - 1 - j];
  }
  // A turn of less than 0.25 degrees (kMinHrirTurnCos) keeps the HRIR (the ears' onset
  // delays follow every change): a source gliding across the blocks would
  // otherwise crossfade two HRIRs every block for changes far below what
  // anyone hears; the HRIR follows once the turn adds up.
  const bool crossfade = mStarted && double(dot(head, mHeadDirection)) < kMinHrirTurnCos;
  if (!mStarted) {
    mCurrent = to;
    mHeadDirection = head;
    mTaps[0] = mTapsNext[0];  // same size: no allocation
    mTaps[1] = mTapsNext[1];
    mStarted = true;
  }
  setShelves(to);
  const bool jump = isJump(mCurrent.delay, to.delay, frames, 2);
  for (size_t off = 0; off < frames; off += kChunk) {
    const size_t n = std::min(kChunk, frames - off);
    processChunk(input ? input + off : nullptr, left + off, right + off, n, mCurrent, to, off, frames, crossfade,
                 jump);
  }
  endShelfFade();
  mCurrent = to;
  if (crossfade) {
    mHeadDirection = head;
    std::swap(mTaps[0], mTapsNext[0]);
    std::swap(mTaps[1], mTapsNext[1]);
  }
  mDelay[0] = to.delay[0];
  mDelay[1] = to.delay[1];
}

void DirectVoice::processAmbisonic(const float* input, float* const* out, int order, size_t frames,
                                   const DirectTarget& target) {
  if (frames == 0) return;
  Vec3f head;
  const Params to = paramsFor(target, head, true);
  // Head frame (+x right, +y up, -z forward) to the ambisonic frame.
  float sh[16];
  realSphericalHarmonics(hrtf::headToSofa(head), order, sh);
  const int channels = ambisonicChannels(order);
  if (!mStarted) {
    mCurrent = to;
    std::copy(sh, sh + channels, mHarmonics);
    mStarted = true;
  }
  setShelves(to);
  float* y = mScratch.data();
  const bool jump = isJump(mCurrent.delay, to.delay, frames, 1);
  for (size_t off = 0; off < frames; off += kChunk) {
    const size_t n = std::min(kChunk, frames - off);
    const size_t base = pushInput(input ? input + off : nullptr, n, off, frames);
    const DelayRamp ramp{{mCurrent.delay[0], 0.0}, {to.delay[0] - mCurrent.delay[0], 0.0}, mCurrent.gain,
                         to.gain - mCurrent.gain, off, frames};
    if (jump)
      jumpReads(mRing.data(), mRingMask, &mSincTable->taps[0][0], base, ramp, y, nullptr, mScratchNext.data(), nullptr,
                n);
    else
      delayedReads(mRing.data(), mRingMask, &mSincTable->taps[0][0], base, ramp, y, nullptr, n);
    for (int c = 0; c < channels; ++c) {
      const float from = mHarmonics[c], step = (sh[c] - from) / float(frames);
      float* o = out[c] + off;
      for (size_t i = 0; i < n; ++i) o[i] += (from + step * float(off + i + 1)) * y[i];
    }
  }
  endShelfFade();
  mCurrent = to;
  std::copy(sh, sh + channels, mHarmonics);
  mHeadDirection = head;
  mDelay[0] = mDelay[1] = to.delay[0];
}

}  // namespace earshot::runtime
