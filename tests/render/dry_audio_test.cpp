// Dry audio: any libsndfile file to mono at the scene rate, with a log line
// saying what was done.
#include "earshot/render/dry_audio.h"

#include <gtest/gtest.h>

#include <cmath>

#include "../cli/cli_test_util.h"
#include "earshot/core/math.h"
#include "earshot/io/wav.h"

namespace earshot {
namespace {

using testing::TempDir;

TEST(DryAudio, Stereo44100IsAveragedToMonoAndResampledTo48000) {
  TempDir dir("render_dry");
  // Left 0.5 sin, right 0.3 sin of 1 kHz: the mean is 0.4 sin.
  const double fs = 44100.0;
  AudioBuffer in(2, 22050, fs);
  for (size_t i = 0; i < in.frameCount(); ++i) {
    const double s = std::sin(2 * kPi * 1000.0 * double(i) / fs);
    in.channels[0][i] = float(0.5 * s);
    in.channels[1][i] = float(0.3 * s);
  }
  ASSERT_TRUE(writeWavFloat(dir / "guitar.wav", in).isOk());
  std::string log;
  auto r = loadDryAudio(dir / "guitar.wav", 48000.0, &log);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(log, "guitar.wav: 44100 Hz stereo -> 48000 Hz mono (mean of 2 channels, Kaiser sinc resampler)");
  EXPECT_EQ(r->fileChannels, 2u);
  EXPECT_EQ(r->fileRateHz, 44100.0);
  EXPECT_EQ(r->sampleRateHz, 48000.0);
  ASSERT_EQ(r->samples.size(), 24000u);  // the same 0.5 s
  // Away from the edges, the output is the same sine at the new rate: same
  // phase (no delay), amplitude 0.4 within 0.001 dB.
  double maxErr = 0;
  for (size_t m = 480; m < 24000 - 480; ++m)
    maxErr = std::max(maxErr, std::abs(r->samples[m] - 0.4 * std::sin(2 * kPi * 1000.0 * double(m) / 48000.0)));
  EXPECT_LT(maxErr, 0.4 * (dbToGain(0.001) - 1));
}

TEST(DryAudio, MonoAtTheSceneRateIsUsedAsIs) {
  TempDir dir("render_dry_as_is");
  AudioBuffer in(1, 100, 48000.0);
  for (size_t i = 0; i < 100; ++i) in.channels[0][i] = float(i) / 100.0f - 0.5f;
  ASSERT_TRUE(writeWavFloat(dir / "voice.wav", in).isOk());
  std::string log;
  auto r = loadDryAudio(dir / "voice.wav", 48000.0, &log);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(log, "voice.wav: 48000 Hz mono (used as is)");
  EXPECT_EQ(r->samples, in.channels[0]);

  // Four channels at the scene rate: averaged, not resampled.
  AudioBuffer quad(4, 3, 48000.0);
  for (size_t c = 0; c < 4; ++c) quad.channels[c] = {float(c), 1.0f, -float(c)};
  ASSERT_TRUE(writeWavFloat(dir / "quad.wav", quad).isOk());
  auto q = loadDryAudio(dir / "quad.wav", 48000.0, &log);
  ASSERT_TRUE(q.isOk());
  EXPECT_EQ(log, "quad.wav: 48000 Hz 4 channels -> 48000 Hz mono (mean of 4 channels)");
  EXPECT_EQ(q->samples, (std::vector<float>{1.5f, 1.0f, -1.5f}));
}

TEST(DryAudio, ErrorsNameTheFile) {
  TempDir dir("render_dry_errors");
  auto missing = loadDryAudio(dir / "nope.wav", 48000.0);
  ASSERT_FALSE(missing.isOk());
  EXPECT_NE(missing.status().message().find(dir / "nope.wav"), std::string::npos) << missing.status().message();

  std::ofstream(dir / "text.wav") << "not audio";
  auto text = loadDryAudio(dir / "text.wav", 48000.0);
  ASSERT_FALSE(text.isOk());
  EXPECT_NE(text.status().message().find(dir / "text.wav"), std::string::npos);

  AudioBuffer empty(1, 0, 48000.0);
  ASSERT_TRUE(writeWavFloat(dir / "empty.wav", empty).isOk());
  auto e = loadDryAudio(dir / "empty.wav", 48000.0);
  ASSERT_FALSE(e.isOk());
  EXPECT_EQ(e.status().message(), dir / "empty.wav" + ": no audio frames (an empty file)");

  auto rate = loadDryAudio(dir / "empty.wav", 0.0);
  ASSERT_FALSE(rate.isOk());
  EXPECT_NE(rate.status().message().find("target sample rate"), std::string::npos);
}

}  // namespace
}  // namespace earshot
