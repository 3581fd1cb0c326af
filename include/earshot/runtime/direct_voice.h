#pragma once
/** @file The direct sound of one moving source, rendered block by block on
 *  the audio thread from the latest poses: a delay line read at the
 *  propagation delay r/c (plus each ear's HRTF onset delay), interpolated
 *  across the block so that motion is heard as Doppler, never as a click
 *  (a jump faster than half the speed of sound, a teleport, is a crossfade
 *  across the block from the old delay to the new: no aliased chirp);
 *  1/r spreading; air absorption and transmission (occlusion) as a low and a
 *  high shelf around the 1 kHz band's gain (a shelf change over 0.5 dB, an
 *  occluder coming or going, crossfaded over the block); and each ear's minimum-phase HRIR
 *  for the current head-frame direction, crossfaded over the block when the
 *  direction has changed by 0.25 degrees or more since the HRIR was last
 *  changed (head rotation is heard within one block; smaller turns add up).
 *
 *  Why shelves and not the seven bands: per-block filtering must be cheap
 *  (dozens of sources on one core). Air absorption and wall transmission are
 *  smooth in frequency, mostly a high-frequency tilt, which a low shelf at
 *  250 Hz and a high shelf at 4 kHz (RBJ cookbook, S = 1) follow to within
 *  about 1-2 dB in the octave bands. The offline IR (`earshot ir`) applies the
 *  seven bands exactly; a static source in `earshot render` uses that IR.
 *
 *  Threading: create() on any thread; process() on the audio thread only,
 *  which never allocates, locks or throws (all buffers are sized at create). */
#include <array>
#include <cstddef>
#include <memory>
#include <vector>

#include "earshot/core/bands.h"
#include "earshot/core/status.h"
#include "earshot/core/vec3.h"
#include "earshot/hrtf/hrtf_set.h"
#include "earshot/ir/binaural_synthesis.h"
#include "earshot/propagation/air_absorption.h"

namespace earshot::runtime {

/** What the direct sound depends on, read at the start of every block. */
struct DirectTarget {
  Vec3d source;                       ///< world position, metres
  Vec3d listener;                     ///< world position, metres
  ListenerOrientation orientation;    ///< valid (validate())
  double gain = 1.0;                  ///< linear pressure factor (source gain); 0 silences
  BandArrayD transmission = filledBands(1.0);  ///< pressure factor per band through occluders
  bool audible = true;                ///< false: the direct path is blocked entirely
};

struct DirectVoiceSettings {
  double sampleRateHz = 48000.0;
  double speedOfSound = 343.0;
  AirConditions air;
  double minDistanceMeters = 0.1;   ///< 1/r is clamped here
  double maxDelaySeconds = 1.0;     ///< longer propagation delays are clamped (343 m at 343 m/s)
  size_t extraDelayFrames = 0;      ///< added to every delay (aligns with a convolver's latency)
};

struct SincTable;  // the fractional-delay interpolator's table (direct_voice.cpp)

class DirectVoice {
 public:
  /** Allocates the delay line and the filters. Thread: not the audio thread. */
  static Result<std::unique_ptr<DirectVoice>> create(const DirectVoiceSettings& settings,
                                                     std::shared_ptr<const hrtf::HrtfSet> hrtf);

  /** What create() allocates for these settings (as create() accepts
   *  them) and any HRTF set (up to hrtf::HrirPair::kMaxTaps taps). */
  static size_t stateBytes(const DirectVoiceSettings& settings);

  /** Renders `frames` frames of `input` (mono, nullptr = silence) and ADDS the
   *  two ears to left and right. Parameters move from the previous call's
   *  target to `target` across these frames. Thread: audio only; no
   *  allocation, lock or exception. */
  void process(const float* input, float* left, float* right, size_t frames, const DirectTarget& target);

  /** Ambisonic output (issue 15): the same delay line, spreading and shelves,
   *  read at the head centre's delay (no ear onsets, no HRIR), ADDED to the
   *  (order+1)^2 AmbiX channels (ACN, SN3D) `out` in the listener's frame (x
   *  forward, y left, z up), the harmonics of the source's direction
   *  interpolated across the frames from the previous call's. order in
   *  [1, 3]. A voice renders one way or the other (reset() between).
   *  Thread: audio only; no allocation, lock or exception. */
  void processAmbisonic(const float* input, float* const* out, int order, size_t frames, const DirectTarget& target);

  /** Forgets the signal history and parameters (next call starts afresh). Thread: audio. */
  void reset();

  /** Frames of silent input after which everything already put in has
   *  come out (the longer ear's delay at the end of the last call, the
   *  interpolator's reach and the HRIR): how long a voice whose source
   *  stopped playing still sounds. 0 before the first call. Thread: audio. */
  size_t ringOutFrames() const;

  /** The total delay (seconds, including extraDelayFrames) each ear used at the end of the last call. */
  double lastDelaySeconds(int ear) const { return mDelay[ear] / mSettings.sampleRateHz; }

 private:
  struct Biquad {
    float b0 = 1, b1 = 0, b2 = 0, a1 = 0, a2 = 0;
    float z1 = 0, z2 = 0;
    float run(float x) {
      const float y = b0 * x + z1;
      z1 = b1 * x - a1 * y + z2;
      z2 = b2 * x - a2 * y;
      return y;
    }
  };
  struct Params {
    double delay[2] = {0, 0};  // samples
    double gain = 0;           // broadband pressure factor (1 kHz band)
    double lowDb = 0, highDb = 0;
  };
  DirectVoice() = default;
  // centre: the head centre's delay for both "ears" (ambisonic output).
  Params paramsFor(const DirectTarget& t, Vec3f& headDirection, bool centre = false) const;
  void processChunk(const float* input, float* left, float* right, size_t frames, const Params& from,
                    const Params& to, size_t offset, size_t total, bool crossfade, bool jump);
  // The shelves for `to` (air, transmission around the 1 kHz band).
  void setShelves(const Params& to);
  // After a block whose shelves were crossfaded: the new ones go on.
  void endShelfFade();
  // `frames` of input (nullptr: silence) through the shelves into the delay
  // line; returns the absolute index of the first.
  size_t pushInput(const float* input, size_t frames, size_t offset, size_t total);

  DirectVoiceSettings mSettings;
  const SincTable* mSincTable = nullptr;
  std::shared_ptr<const hrtf::HrtfSet> mHrtf;
  BandArrayD mAirDbPerMeter{};
  std::vector<float> mRing;     // delay line: a power of two (mRingMask + 1), then 8 floats mirroring its start
  size_t mRingMask = 0;
  size_t mWrite = 0;            // total samples written
  double mMaxDelay = 0;         // samples
  std::unique_ptr<hrtf::HrirPair> mHrir, mHrirNext;
  std::vector<float> mTaps[2], mTapsNext[2];   // reversed HRIR taps per ear
  std::vector<float> mHistory[2];              // per ear: last taps-1 delayed samples, then the chunk
  std::vector<float> mScratch, mScratchNext;  // per chunk: FIR outputs of the current and the next HRIR
  std::vector<float> mFade;                   // per chunk: the crossfade's weight of the next HRIR, both ears
  Biquad mLow, mHigh;
  Biquad mLowNext, mHighNext;  // a block crossfading its shelves: the new ones (setShelves)
  bool mShelfFade = false, mShelvesSet = false;
  double mShelfDb[2] = {0, 0};  // the shelves' gains last set (low, high)
  Params mCurrent;
  Vec3f mHeadDirection;
  bool mStarted = false;
  double mDelay[2] = {0, 0};
  float mHarmonics[16] = {};  // ambisonic output: the direction's SH at the end of the last call
};

}  // namespace earshot::runtime
