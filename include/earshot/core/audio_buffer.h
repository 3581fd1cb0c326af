#pragma once
/** @file Multichannel float audio, channel-major (planar). */
#include <cstddef>
#include <vector>

namespace earshot {

struct AudioBuffer {
  double sampleRateHz = 48000.0;
  std::vector<std::vector<float>> channels;  ///< channels[c][frame]

  AudioBuffer() = default;
  AudioBuffer(size_t channelCount, size_t frames, double rateHz)
      : sampleRateHz(rateHz), channels(channelCount, std::vector<float>(frames, 0.0f)) {}
  size_t channelCount() const { return channels.size(); }
  size_t frameCount() const { return channels.empty() ? 0 : channels[0].size(); }
};

}  // namespace earshot
