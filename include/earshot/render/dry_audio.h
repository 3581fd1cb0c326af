#pragma once
/** @file A source's dry (anechoic) audio, ready to render: mono at the
 *  scene's sample rate. */
#include <string>
#include <vector>

#include "earshot/core/status.h"

namespace earshot {

struct DryAudio {
  std::vector<float> samples;    ///< mono, at sampleRateHz
  double sampleRateHz = 48000.0;
  double fileRateHz = 48000.0;   ///< the file's own rate
  size_t fileChannels = 1;       ///< the file's channel count (averaged into samples)
};

/** Reads any format libsndfile reads (readAudioFile), downmixes to mono (the
 *  mean of the channels, so identical channels keep their level) and
 *  resamples to `targetRateHz` (in [1000, 1e6] Hz) with the band-limited
 *  Kaiser-sinc resampler of earshot/dsp/resample.h (no added delay; same
 *  duration, round(frames * target / rate) samples). Samples are not
 *  normalised or clipped.
 *  `logLine` (may be null) receives what was done, e.g. `guitar.wav: 44100 Hz
 *  stereo -> 48000 Hz mono (mean of 2 channels, Kaiser sinc resampler)`.
 *  Errors name the file: unreadable or missing (kIoError), no frames
 *  (kInvalidArgument), non-finite samples (kParseError).
 *  Thread-safe (no shared state); allocates; not for the audio thread. */
Result<DryAudio> loadDryAudio(const std::string& path, double targetRateHz, std::string* logLine = nullptr);

}  // namespace earshot
