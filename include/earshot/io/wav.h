#pragma once
/** @file WAV (and any libsndfile format) reading and writing. */
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>
#include <string>

#include "earshot/core/audio_buffer.h"
#include "earshot/core/status.h"

namespace earshot {

/** The most samples (over all channels) readAudioFile reads unless told
 *  otherwise: a sixteenth of defaultInputLimits().maxMemoryBytes in floats
 *  (of 1 GiB: 16 M samples, 2.9 min of stereo at 48 kHz), leaving room for
 *  the buffer's growth and the copies its callers make (mono mix,
 *  resampling). */
size_t defaultMaxReadSamples();

/** Reads any format libsndfile reads, as float. Only a regular file is read
 *  (never a FIFO or device), and it is remembered as an input (outputs never
 *  replace it: input_file.h). A header that claims more than maxSamples is
 *  an error, not an allocation, and so is a file that decodes to more (a
 *  compressed file of silence). maxSamples 0: defaultMaxReadSamples().
 *  Errors name the file. */
Result<AudioBuffer> readAudioFile(const std::string& path, size_t maxSamples = 0);

/** Writes a 32-bit float WAV. Writes to a temporary file beside `path` and
 *  renames it over `path` only when everything was written, so an existing
 *  file is replaced only on success and no partial file is left. Refuses
 *  non-finite samples (naming channel and frame). */
Status writeWavFloat(const std::string& path, const AudioBuffer& audio);

/** Largest float WAV (RIFF sizes are 32-bit): renders longer than this
 *  holds are refused before they start. */
constexpr uint64_t kMaxWavBytes = (uint64_t(1) << 32) - 4096;

/** A 32-bit float WAV written block by block (a long render never holds its
 *  output in memory), to a temporary file beside the target that commit()
 *  renames over it; destroyed uncommitted, it removes the temporary file, so
 *  the target is never partial. The target is checked as writeWavFloat's
 *  (checkOutputPath) when opened and again at commit. */
class WavStreamWriter {
 public:
  static Result<std::unique_ptr<WavStreamWriter>> open(const std::string& path, size_t channels, double sampleRateHz);
  ~WavStreamWriter();
  WavStreamWriter(const WavStreamWriter&) = delete;
  WavStreamWriter& operator=(const WavStreamWriter&) = delete;

  /** Appends `frames` frames; channel c's samples at planar[c]. Non-finite
   *  samples are refused (naming the frame) and nothing more is written. */
  Status write(const float* const* planar, size_t frames);
  /** Closes the file and renames it over the target. */
  Status commit();
  uint64_t framesWritten() const { return mFrames; }

 private:
  WavStreamWriter() = default;
  std::string mPath, mTmp;
  size_t mChannels = 0;
  uint64_t mFrames = 0;
  void* mFile = nullptr;  // SNDFILE*
  std::vector<float> mInterleaved;
};

}  // namespace earshot
