#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "earshot/io/temp_files.h"

namespace earshot {
namespace fs = std::filesystem;

class TempFiles : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("earshot_tempfiles_" + std::to_string(::getpid()));
  void SetUp() override { fs::create_directories(dir); }
  void TearDown() override { fs::remove_all(dir); }
  std::string make(const std::string& name) {
    const std::string p = (dir / name).string();
    std::ofstream(p) << "partial";
    return p;
  }
};

TEST_F(TempFiles, RegisteredFilesAreRemovedOnceAndEndedGuardsFilesAreNot) {
  const std::string a = make("a.tmp"), b = make("b.tmp"), kept = make("kept.wav");
  {
    TempFileGuard ended(kept);
    ASSERT_TRUE(ended.registered());
  }
  TempFileGuard ga(a), gb(b);
  ASSERT_TRUE(ga.registered() && gb.registered());
  EXPECT_EQ(removeTempFilesNow(), 2);
  EXPECT_FALSE(fs::exists(a));
  EXPECT_FALSE(fs::exists(b));
  EXPECT_TRUE(fs::exists(kept));  // its guard had ended: an output, not a temporary file
  // Removed once: a file made again under the name is not removed again
  // while the same guard lives.
  make("a.tmp");
  EXPECT_EQ(removeTempFilesNow(), 0);
  EXPECT_TRUE(fs::exists(a));
}

TEST_F(TempFiles, SlotsAreReusedAndBeyondTheLimitNothingBreaks) {
  // Many more guards over time than slots: each ended guard frees its slot,
  // also one whose file a removal took.
  for (int round = 0; round < 3 * TempFileGuard::kMaxTempFiles; ++round) {
    const std::string p = make("r.tmp");
    TempFileGuard g(p);
    ASSERT_TRUE(g.registered()) << round;
    if (round % 7 == 0) {
      EXPECT_EQ(removeTempFilesNow(), 1);
      EXPECT_FALSE(fs::exists(p));
    }
  }
  std::vector<std::unique_ptr<TempFileGuard>> all;
  for (int i = 0; i < TempFileGuard::kMaxTempFiles + 5; ++i)
    all.push_back(std::make_unique<TempFileGuard>(make("f" + std::to_string(i) + ".tmp")));
  int registered = 0;
  for (const auto& g : all) registered += g->registered();
  EXPECT_EQ(registered, TempFileGuard::kMaxTempFiles);
  EXPECT_EQ(removeTempFilesNow(), TempFileGuard::kMaxTempFiles);
  all.clear();
  // Paths a slot cannot hold are not registered.
  EXPECT_FALSE(TempFileGuard(std::string(5000, 'x')).registered());
  EXPECT_FALSE(TempFileGuard("").registered());
  EXPECT_TRUE(TempFileGuard((dir / "n.tmp").string()).registered());
}

}  // namespace earshot
