#pragma once
/** @file A binaural decoder for AmbiX signals (ACN, SN3D, orders 1-3) in the
 *  listener's frame (x forward, y left, z up), made from an HRTF set: one
 *  FIR per ambisonic channel and ear, ear = sum_c filter(c, ear) * channel c.
 *
 *  Design, per frequency bin (Zaunschirm, Schoerkhuber & Hoeldrich,
 *  "Binaural rendering of Ambisonic signals by head-related impulse response
 *  time alignment and a diffuseness constraint", JASA 143(6), 2018):
 *   - least squares: the decoder whose response to a plane wave from each
 *     measured direction is closest to that direction's HRTF, weighted by the
 *     solid angle each measurement serves (BinauralModel::measurementWeights);
 *   - below alignedAboveHz the full HRTFs (onset delays included: the
 *     interaural time difference); above it the time-aligned ones (every
 *     HRIR's onset at the same delay), whose smooth phase a low order can
 *     follow, so that the magnitudes (the level differences) are fitted
 *     instead of an interaural phase no order up to 3 can reproduce up there;
 *     a raised-cosine crossfade over the octave around the crossover. (A
 *     magnitude least squares fit with the phase continued from bin to bin
 *     was tried: its phase is rough, the filters fill their whole length and
 *     shortening them broke the constraint below: coherence -0.19 for 0.)
 *   - at every bin, the diffuse-field covariance constraint: a 2x2 mixing
 *     (Vilkamo, Baeckstroem & Kuntz, "Optimized covariance domain framework
 *     for time-frequency processing of spatial audio", JAES 61(6), 2013) so
 *     that a diffuse field (uncorrelated SH channels of SN3D energy 1/(2n+1))
 *     decodes to the head's diffuse-field ear spectra and interaural
 *     coherence, which the truncated order alone would overstate.
 *  The filters are delayed by delayFrames() so that the fit's acausal parts
 *  (the ears' negative onset delays, the fit's spread) stay in the FIR. */
#include <memory>
#include <vector>

#include "earshot/core/audio_buffer.h"
#include "earshot/core/status.h"
#include "earshot/ir/binaural_synthesis.h"

namespace earshot {

struct AmbisonicDecoderSettings {
  int order = 1;                  ///< [1, 3]
  double alignedAboveHz = 1500.0;  ///< full HRTFs below, time-aligned above (crossfade over an octave); > 0
  bool covarianceConstraint = true;
  size_t taps = 512;              ///< FIR length, a power of two in [128, 8192]
  size_t delayFrames = 96;        ///< bulk delay inside the FIR, < taps / 2
};

class AmbisonicDecoder {
 public:
  /** Designs the decoder for the model's HRTF set (tens of ms). Any thread
   *  but the audio thread. */
  static Result<std::shared_ptr<const AmbisonicDecoder>> create(const BinauralModel& model,
                                                               const AmbisonicDecoderSettings& settings);
  int order() const { return mSettings.order; }
  int channels() const { return ambisonicChannelsOf(mSettings.order); }
  size_t taps() const { return mSettings.taps; }
  /** What the filters add to every path's delay (frames). */
  size_t delayFrames() const { return mSettings.delayFrames; }
  double sampleRateHz() const { return mRate; }
  /** FIR of ACN channel `channel` to `ear` (0 left, 1 right): taps() floats. */
  const std::vector<float>& filter(int channel, int ear) const { return mFilters[size_t(channel) * 2 + size_t(ear)]; }
  /** The channel's two filters as a 2-channel IR (left, right). */
  AudioBuffer channelIr(int channel) const;
  /** Decodes an ambisonic buffer (channels() channels, listener frame) to
   *  two ears, offline (allocates): the output has the input's length plus
   *  taps() - 1 and lags by delayFrames(). */
  Result<AudioBuffer> decode(const AudioBuffer& ambisonic) const;

 private:
  static constexpr int ambisonicChannelsOf(int order) { return (order + 1) * (order + 1); }
  AmbisonicDecoderSettings mSettings;
  double mRate = 48000.0;
  std::vector<std::vector<float>> mFilters;  // [channel * 2 + ear]
};

}  // namespace earshot
