#pragma once
/** @file WAV (and any libsndfile format) reading and writing. */
#include <cstddef>
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

}  // namespace earshot
