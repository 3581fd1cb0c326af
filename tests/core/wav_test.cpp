#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "earshot/io/input_file.h"
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


// One command's outputs: each may be written, and no two are one file.
TEST_F(WavTest, TwoOutputsOfOneCommandMustBeTwoFiles) {
  const std::string a = (dir / "a.wav").string(), b = (dir / "b.json").string();
  EXPECT_TRUE(checkOutputPaths({a, b}, {"-o", "--json"}).isOk());
  EXPECT_TRUE(checkOutputPaths({a, ""}, {"-o", "--json"}).isOk());  // an output not asked for
  // The same path, new or existing, and spelled differently.
  for (int exists = 0; exists < 2; ++exists) {
    // Earlier tests' inputs, deleted since, stay in this process's input
    // set: a new file may get one's inode (then it reads as an input). A
    // file that does is kept aside, so the next gets another inode.
    for (int k = 0; exists && k < 100; ++k) {
      std::ofstream(a) << "old";
      if (checkOutputPath(a).isOk()) break;
      fs::rename(a, dir / ("taken" + std::to_string(k)));
    }
    fs::create_directories(dir / "sub");
    for (const std::string& same : {a, (dir / "." / "a.wav").string(), (dir / "sub" / ".." / "a.wav").string()}) {
      Status s = checkOutputPaths({a, same}, {"-o", "--json"});
      ASSERT_FALSE(s.isOk()) << same;
      EXPECT_NE(s.message().find("--json"), std::string::npos) << s.message();
      EXPECT_NE(s.message().find("same file"), std::string::npos) << s.message();
    }
  }
  // Through a folder that does not exist: no file can be written there.
  Status missing = checkOutputPaths({a, (dir / "x" / ".." / "a.wav").string()}, {"-o", "--json"});
  ASSERT_FALSE(missing.isOk());
  EXPECT_NE(missing.message().find("does not exist"), std::string::npos) << missing.message();
  // A hard link and a symlink name the file too.
  fs::create_hard_link(a, dir / "hard.json");
  fs::create_symlink(a, dir / "soft.json");
  EXPECT_FALSE(checkOutputPaths({a, (dir / "hard.json").string()}, {"-o", "--json"}).isOk());
  EXPECT_FALSE(checkOutputPaths({(dir / "soft.json").string(), a}, {"-o", "--json"}).isOk());
  // Each output is still checked on its own, and says which option it is.
  Status device = checkOutputPaths({a, "/dev/null"}, {"-o", "--json"});
  ASSERT_FALSE(device.isOk());
  EXPECT_EQ(device.message().rfind("--json: ", 0), 0u) << device.message();
  EXPECT_FALSE(checkOutputPaths({a}, {}).isOk());  // a name per path
  std::ifstream f(a);
  std::string content;
  f >> content;
  EXPECT_EQ(content, "old");  // nothing written
}

}  // namespace earshot
