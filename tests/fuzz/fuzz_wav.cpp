// libFuzzer target: readAudioFile (libsndfile: WAV, RF64, W64, AIFF, CAF, FLAC,
// ...) on arbitrary bytes through a temp file, with a small sample limit so a
// lying header must be refused rather than allocated.
#include <cmath>
#include <cstdint>

#include "earshot/io/wav.h"
#include "fuzz_temp_file.h"

namespace {
constexpr size_t kMaxSamples = size_t(1) << 20;  // 4 MB of float
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static earshot::fuzz::TempFile file("in.wav");
  const std::string& path = file.write(data, size);
  auto result = earshot::readAudioFile(path, kMaxSamples);
  if (!result.isOk()) {
    EARSHOT_FUZZ_CHECK(earshot::fuzz::oneLine(result.status().message()));
    return 0;
  }
  const earshot::AudioBuffer& audio = result.value();
  EARSHOT_FUZZ_CHECK(audio.sampleRateHz > 0.0);
  EARSHOT_FUZZ_CHECK(audio.channelCount() * audio.frameCount() <= kMaxSamples);
  for (const auto& ch : audio.channels) {
    EARSHOT_FUZZ_CHECK(ch.size() == audio.frameCount());
    for (float v : ch) EARSHOT_FUZZ_CHECK(std::isfinite(v));
  }
  return 0;
}
