// samples/game_loop.c runs (plain C against the shared library) and writes
// 10 s of finite, non-silent binaural audio at 48 kHz; the door it swings
// open at 3-4 s and shut at 7-8 s changes what the listener hears.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "earshot/io/wav.h"

namespace earshot {

TEST(GameLoopSample, WritesTenSecondsOfFiniteBinauralAudio) {
  const std::string src = EARSHOT_SOURCE_DIR;
  const std::string out = std::string(EARSHOT_CAPI_TEST_OUT_DIR) + "/game_loop_test.wav";
  std::remove(out.c_str());
  const std::string rooms = src + "/samples/two_rooms/";
  const std::string cmd = std::string("\"") + EARSHOT_GAME_LOOP + "\" \"" + rooms + "two_rooms.gltf\" \"" + rooms +
                          "materials_map.json\" \"" + out + "\"";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;

  auto wav = readAudioFile(out);
  ASSERT_TRUE(wav.isOk()) << wav.status().message();
  EXPECT_EQ(wav->channelCount(), 2u);
  EXPECT_EQ(wav->sampleRateHz, 48000.0);
  EXPECT_EQ(wav->frameCount(), 480000u);
  double total[2] = {0, 0};
  for (size_t c = 0; c < wav->channelCount(); ++c) {
    for (float v : wav->channels[c]) {
      ASSERT_TRUE(std::isfinite(v));
      total[c] += double(v) * v;
    }
  }
  // Below full scale (issue 19: it peaked at +5.9 dBFS).
  float peak = 0;
  for (const auto& ch : wav->channels)
    for (float v : ch) peak = std::max(peak, std::fabs(v));
  EXPECT_LT(peak, 1.0f);
  // Both ears hear it (the source circles the listener).
  EXPECT_GT(total[0], 0.0);
  EXPECT_GT(total[1], 0.0);
  // Not silent at any second (the source never stops).
  for (size_t second = 0; second < 10; ++second) {
    double e = 0;
    const std::vector<float>& left = wav->channels[0];
    for (size_t i = second * 48000; i < (second + 1) * 48000; ++i) e += double(left[i]) * left[i];
    EXPECT_GT(e, 0.0) << "second " << second;
  }
  std::remove(out.c_str());
}

}  // namespace earshot
