#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "earshot/io/wav.h"

namespace earshot {
namespace fs = std::filesystem;

class WavTest : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("earshot_wav_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
  void SetUp() override { fs::create_directories(dir); }
  void TearDown() override { fs::remove_all(dir); }
};

TEST_F(WavTest, FloatRoundTripIsExact) {
  AudioBuffer a(2, 1000, 44100);
  for (size_t i = 0; i < 1000; ++i) {
    a.channels[0][i] = float(std::sin(0.01 * i)) * 3.0f;  // above full scale on purpose
    a.channels[1][i] = 1e-7f * float(i);
  }
  auto path = (dir / "a.wav").string();
  ASSERT_TRUE(writeWavFloat(path, a).isOk());
  auto b = readAudioFile(path);
  ASSERT_TRUE(b.isOk()) << b.status().message();
  EXPECT_EQ(b->sampleRateHz, 44100);
  ASSERT_EQ(b->channelCount(), 2u);
  EXPECT_EQ(b->channels, a.channels);
}

TEST_F(WavTest, NonFiniteSampleIsRefusedAndExistingFileKept) {
  auto path = (dir / "keep.wav").string();
  { std::ofstream(path) << "old"; }
  AudioBuffer a(1, 10, 48000);
  a.channels[0][3] = NAN;
  Status s = writeWavFloat(path, a);
  EXPECT_FALSE(s.isOk());
  EXPECT_NE(s.message().find("sample 3"), std::string::npos) << s.message();
  std::ifstream f(path);
  std::string content;
  f >> content;
  EXPECT_EQ(content, "old");
  // No temporary left behind.
  int files = 0;
  for (auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 1);
}

TEST_F(WavTest, MissingAndGarbageFilesGiveErrorsNamingTheFile) {
  auto missing = (dir / "missing.wav").string();
  auto r = readAudioFile(missing);
  ASSERT_FALSE(r.isOk());
  EXPECT_NE(r.status().message().find(missing), std::string::npos);
  auto junk = (dir / "junk.wav").string();
  { std::ofstream(junk) << "RIFF not really a wav"; }
  auto j = readAudioFile(junk);
  ASSERT_FALSE(j.isOk());
  EXPECT_NE(j.status().message().find(junk), std::string::npos);
}

}  // namespace earshot
