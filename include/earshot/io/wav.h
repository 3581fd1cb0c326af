#pragma once
/** @file WAV (and any libsndfile format) reading and writing. */
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>
#include <string>

#include "earshot/core/audio_buffer.h"
#include "earshot/core/status.h"
#include "earshot/io/temp_files.h"

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

/** What an output file's extension names: .wav (or none) 32-bit float WAV;
 *  .flac 24-bit FLAC; .ogg/.oga Ogg Vorbis. Fixed-point and Vorbis output
 *  clips samples beyond full scale (|x| > 1), which the writers count. */
struct AudioFileFormat {
  int sndfileFormat = 0;          ///< libsndfile's SF_FORMAT_* major | subtype
  bool clipsAtFullScale = false;  ///< not float: |x| > 1 is clipped
  const char* name = "";          ///< e.g. "FLAC, 24-bit"
};
/** The format `path`'s extension names (case-insensitive); any other
 *  extension is an error (kUnsupported) naming the formats earshot writes. */
Result<AudioFileFormat> audioFormatForPath(const std::string& path);

/** Writes `audio` in the format its extension names (audioFormatForPath),
 *  as writeWavFloat does (temporary file, rename, non-finite refused).
 *  clippedSamples (if given): samples beyond full scale a FLAC or Vorbis
 *  file clipped (0 for WAV: float keeps them). */
Status writeAudioFile(const std::string& path, const AudioBuffer& audio, uint64_t* clippedSamples = nullptr);

/** Appends the audio of `path` (any libsndfile format, read in blocks: no
 *  length limit) to `out`, every sample times `gain`; the channel counts
 *  must match. For a second pass over a render (normalisation). */
Status appendScaled(const std::string& path, float gain, class WavStreamWriter& out);

/** Writes a 32-bit float WAV (a path naming another format is refused). Writes to a temporary file beside `path` and
 *  renames it over `path` only when everything was written, so an existing
 *  file is replaced only on success and no partial file is left. Refuses
 *  non-finite samples (naming channel and frame). */
Status writeWavFloat(const std::string& path, const AudioBuffer& audio);

/** Largest float WAV (RIFF sizes are 32-bit): renders longer than this
 *  holds are refused before they start. */
constexpr uint64_t kMaxWavBytes = (uint64_t(1) << 32) - 4096;

/** An audio file (format by extension: audioFormatForPath; 32-bit float WAV
 *  by default) written block by block (a long render never holds its
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
  size_t channels() const { return mChannels; }
  /** Samples clipped at full scale so far (FLAC, Vorbis; 0 for WAV). */
  uint64_t clippedSamples() const { return mClipped; }
  const AudioFileFormat& format() const { return mFormat; }

 private:
  WavStreamWriter() = default;
  std::string mPath, mTmp;
  size_t mChannels = 0;
  uint64_t mFrames = 0;
  uint64_t mClipped = 0;
  AudioFileFormat mFormat;
  void* mFile = nullptr;  // SNDFILE*
  std::vector<float> mInterleaved;
  std::unique_ptr<TempFileGuard> mTmpGuard;  // mTmp, while it exists
};

}  // namespace earshot
