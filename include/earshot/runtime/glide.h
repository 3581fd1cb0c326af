#pragma once
/** @file A position (or a gain) the game sets at its own rate, as the
 *  audio thread follows it block by block.
 *
 *  A game sets poses once a frame (60 Hz: every 800 frames at 48 kHz); an
 *  audio thread of 256-frame blocks sees a new one every third block or so.
 *  The direct sound's delay follows the position it is given across each
 *  block, so reaching each new position within one block made a staircase:
 *  the Doppler shift three times over for a block, none for the next two,
 *  a modulation of the tone at the game's frame rate (a 1 kHz tone receding
 *  at 10 m/s had -5 dB of its energy off the Doppler-shifted tone).
 *
 *  A glide spreads each change over about the interval at which the game
 *  makes them (a running mean of the intervals seen, times 1.5, plus twice
 *  their mean deviation): the audio thread sees a change only at a block's
 *  start, so the intervals it measures jitter by up to a block (768 and
 *  1,024 frames for the 800 above), and a game faster than the blocks may
 *  change a pose once or twice within one. The glide moves toward the
 *  latest position at the speed that reaches it in that time; a pose
 *  moving at steady speed is followed at that speed, one to two update
 *  intervals late (17-33 ms at 60 Hz; 0.17-0.33 m at 10 m/s). Measured on the
 *  same 1 kHz tone: -26 dB (Engine.APoseUpdatedAtTheGamesFrameRateIsHeardAsSteadyDoppler).
 *  A change is reached within the block, as before, when it is the first
 *  after kMaxGlideSeconds without one (a source put somewhere: no motion
 *  to follow), or when following it would be faster than the given speed
 *  (a teleport; the direct voice crossfades it).
 *
 *  A source's gain, faded by the game at its frame rate, made the same
 *  staircase in level (a 60 Hz modulation: -28 dB of a 1 kHz tone's energy
 *  off the tone in a fade of 100 dB/s); it glides the same way, with no
 *  speed limit (GainGlide), and so do the direct sound's and the
 *  reflections' gains, and the way a directional source faces (its level
 *  toward the listener, a staircase as it turned: Engine.ControlsSetAtTheGamesFrameRateAreSmooth).
 *
 *  Thread: the audio thread's state; no allocation, lock or exception. */
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "earshot/core/vec3.h"

namespace earshot::runtime {

/** The longest interval between a game's changes of a pose that is still
 *  followed as motion (a game or network tick of 10 Hz). */
constexpr double kMaxGlideSeconds = 0.1;

inline double glideDistance(const Vec3d& d) { return length(d); }
inline double glideDistance(double d) { return std::fabs(d); }

template <class T>
class Glide {
 public:
  /** The value to use at the end of the next `frames` frames, given the
   *  one the game has set now. `maxFrames`: the longest interval followed
   *  as motion (kMaxGlideSeconds in frames); `maxChangePerFrame`: a faster
   *  change is reached at once. */
  T next(const T& set, size_t frames, uint64_t maxFrames, double maxChangePerFrame) {
    if (!mStarted) {
      mHeard = mSet = set;
      mLeft = 0;
      mSince = maxFrames + 1;  // no earlier change to measure an interval from
      mStarted = true;
    } else if (!(set == mSet)) {
      const uint64_t interval = mSince;
      const T d = set - mHeard;
      mSet = set;
      mSince = 0;
      if (interval > maxFrames || glideDistance(d) > maxChangePerFrame * double(interval)) {
        mHeard = set;
        mLeft = 0;
        mInterval = -1.0;  // the next interval starts the mean afresh
      } else {
        if (mInterval < 0) {
          mInterval = double(interval);
          mDeviation = 0.0;
        } else {
          mDeviation += kMeanWeight * (std::fabs(double(interval) - mInterval) - mDeviation);
          mInterval += kMeanWeight * (double(interval) - mInterval);
        }
        const double glide = std::max(1.0, std::round(1.5 * mInterval + 2.0 * mDeviation));
        mStep = d / glide;
        mLeft = uint64_t(glide);
      }
    }
    mSince = std::min(mSince + frames, maxFrames + 1);
    if (mLeft > frames) {
      mHeard = mHeard + mStep * double(frames);
      mLeft -= frames;
    } else if (mLeft > 0) {
      mHeard = mSet;  // exactly where the game put it
      mLeft = 0;
    }
    return mHeard;
  }
  /** The next call starts at the value it is given. */
  void reset() { mStarted = false; }

 private:
  static constexpr double kMeanWeight = 0.125;  // of each new interval in the running means
  T mHeard{}, mSet{}, mStep{};
  uint64_t mLeft = 0, mSince = 0;
  double mInterval = -1.0, mDeviation = 0.0;  // frames; mInterval < 0: no mean yet
  bool mStarted = false;
};

using PoseGlide = Glide<Vec3d>;
using GainGlide = Glide<double>;

}  // namespace earshot::runtime
