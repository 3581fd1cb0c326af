#include "earshot/render/dry_audio.h"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "earshot/dsp/resample.h"
#include "earshot/io/input_file.h"
#include "earshot/io/wav.h"

namespace earshot {

namespace {

std::string rateText(double hz) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g Hz", hz);
  return buf;
}

std::string channelsText(size_t n) {
  if (n == 1) return "mono";
  if (n == 2) return "stereo";
  return std::to_string(n) + " channels";
}

}  // namespace

Result<DryAudio> loadDryAudio(const std::string& path, double targetRateHz, std::string* logLine) {
  if (!(targetRateHz >= 1000.0 && targetRateHz <= 1e6))
    return invalidArgument(path + ": target sample rate " + rateText(targetRateHz) + " is outside [1000, 1e6] Hz");
  auto file = readAudioFile(path);
  if (!file) return file.status();
  const AudioBuffer& in = *file;
  const size_t ch = in.channelCount(), frames = in.frameCount();
  if (frames == 0) return invalidArgument(path + ": no audio frames (an empty file)");

  DryAudio out;
  out.fileRateHz = in.sampleRateHz;
  out.fileChannels = ch;
  out.sampleRateHz = targetRateHz;

  // What resampling would make, before making it: a 1 Hz file of a few
  // frames is billions of samples at 48 kHz.
  const double outSamples = double(frames) * targetRateHz / in.sampleRateHz;
  const uint64_t budget = defaultInputLimits().maxMemoryBytes;
  if (!(outSamples * 2 * sizeof(float) <= double(budget)))
    return outOfRange(path + ": " + std::to_string(frames) + " frames at " + rateText(in.sampleRateHz) + " become " +
                      std::to_string(uint64_t(std::min(outSamples, 1.8e19))) + " samples at " +
                      rateText(targetRateHz) + ", over the memory limit of " + formatBytes(budget) +
                      " (--max-memory)");

  std::vector<float> mono(frames);
  if (ch == 1) {
    mono = in.channels[0];
  } else {
    for (size_t i = 0; i < frames; ++i) {
      double sum = 0.0;
      for (size_t c = 0; c < ch; ++c) sum += in.channels[c][i];
      mono[i] = static_cast<float>(sum / double(ch));
    }
  }
  const bool resampled = in.sampleRateHz != targetRateHz;
  out.samples = resampled ? resample(mono.data(), mono.size(), in.sampleRateHz, targetRateHz) : std::move(mono);

  if (logLine) {
    std::string what;
    if (ch > 1) what = "mean of " + std::to_string(ch) + " channels";
    if (resampled) what += std::string(what.empty() ? "" : ", ") + "Kaiser sinc resampler";
    *logLine = std::filesystem::path(path).filename().string() + ": " + rateText(in.sampleRateHz) + " " +
               channelsText(ch) +
               (what.empty() ? " (used as is)" : " -> " + rateText(targetRateHz) + " mono (" + what + ")");
  }
  return out;
}

}  // namespace earshot
