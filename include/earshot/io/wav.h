#pragma once
/** @file WAV (and any libsndfile format) reading and writing. */
#include <cstddef>
#include <string>

#include "earshot/core/audio_buffer.h"
#include "earshot/core/status.h"

namespace earshot {

/** Largest file we agree to read unless the caller says otherwise: a header
 *  that claims more is an error, not an allocation (2^40 frames, say). */
constexpr size_t kDefaultMaxReadSamples = size_t(1) << 31;  // samples over all channels

/** Reads any format libsndfile reads, as float. Errors name the file. */
Result<AudioBuffer> readAudioFile(const std::string& path, size_t maxSamples = kDefaultMaxReadSamples);

/** Writes a 32-bit float WAV. Writes to a temporary file beside `path` and
 *  renames it over `path` only when everything was written, so an existing
 *  file is replaced only on success and no partial file is left. Refuses
 *  non-finite samples (naming channel and frame). */
Status writeWavFloat(const std::string& path, const AudioBuffer& audio);

}  // namespace earshot
