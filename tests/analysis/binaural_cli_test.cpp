// `earshot analyze` on binaural (2-channel) and mono files, run as a user
// would: the binaural section appears for two channels only, in text and JSON.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <random>

#include "../cli/cli_test_util.h"
#include "earshot/io/wav.h"

namespace earshot {
namespace {

using testing::runEarshot;
using testing::TempDir;

constexpr double kFs = 48000.0;

// Left: a Gaussian click (sigma 3 samples) at 10 ms; right: the same 7.3
// samples later at half amplitude (ITD 152.08 us, ILD 6.02 dB); then the same
// decaying noise in both ears from 20 ms (late IACC 1 in every band).
AudioBuffer binauralIr() {
  AudioBuffer a(2, size_t(0.8 * kFs), kFs);
  std::mt19937 rng(4);
  std::normal_distribution<double> g(0.0, 1.0);
  for (size_t i = 0; i < a.frameCount(); ++i) {
    const double u = (double(i) - 480.0) / 3.0, v = (double(i) - 487.3) / 3.0;
    const double tail = i >= 960 ? 0.05 * g(rng) * std::exp(-6.9 * double(i - 960) / kFs / 0.3) : 0.0;
    a.channels[0][i] = float(std::exp(-0.5 * u * u) + tail);
    a.channels[1][i] = float(0.5 * std::exp(-0.5 * v * v) + tail);
  }
  return a;
}

TEST(AnalyzeBinauralCli, TwoChannelsGetItdIldAndIaccInTextAndJson) {
  TempDir dir("analyze_binaural");
  const std::string path = dir / "binaural.wav";
  ASSERT_TRUE(writeWavFloat(path, binauralIr()).isOk());

  auto text = runEarshot("analyze '" + path + "'");
  ASSERT_EQ(text.exitCode, 0) << text.output;
  EXPECT_NE(text.output.find("channel 0 (left)"), std::string::npos) << text.output;  // ISO tables stay
  EXPECT_NE(text.output.find("channel 1 (right)"), std::string::npos);
  EXPECT_NE(text.output.find("ITD +152.1 us"), std::string::npos) << text.output;
  EXPECT_NE(text.output.find("ILD +6.02 dB"), std::string::npos) << text.output;
  EXPECT_NE(text.output.find("IACC_L"), std::string::npos);

  auto json = runEarshot("analyze '" + path + "' --json");
  ASSERT_EQ(json.exitCode, 0) << json.output;
  const auto doc = nlohmann::json::parse(json.output);
  ASSERT_EQ(doc.at("channels").size(), 2u);
  const auto& b = doc.at("binaural");
  EXPECT_NEAR(b.at("itd_us").get<double>(), 7.3 / kFs * 1e6, 5.0);
  EXPECT_NEAR(b.at("itd_s").get<double>(), 7.3 / kFs, 5e-6);
  EXPECT_NEAR(b.at("ild_db").get<double>(), 20 * std::log10(2.0), 0.05);
  EXPECT_FALSE(b.at("itd_at_search_limit").get<bool>());
  ASSERT_EQ(b.at("bands").size(), 8u);
  EXPECT_EQ(b.at("bands").at(7).at("band"), "broadband");
  for (const auto& band : b.at("bands")) EXPECT_NEAR(band.at("IACC_L").get<double>(), 1.0, 1e-6) << band.dump();
  EXPECT_NEAR(b.at("iacc_l3").get<double>(), 1.0, 1e-6);
}

TEST(AnalyzeBinauralCli, MonoFilesAndSingleChannelRunsHaveNoBinauralSection) {
  TempDir dir("analyze_mono");
  AudioBuffer both = binauralIr();
  AudioBuffer mono(1, both.frameCount(), kFs);
  mono.channels[0] = both.channels[0];
  const std::string monoPath = dir / "mono.wav", binauralPath = dir / "binaural.wav";
  ASSERT_TRUE(writeWavFloat(monoPath, mono).isOk());
  ASSERT_TRUE(writeWavFloat(binauralPath, both).isOk());

  auto text = runEarshot("analyze '" + monoPath + "'");
  ASSERT_EQ(text.exitCode, 0) << text.output;
  EXPECT_NE(text.output.find("channel 0 (mono)"), std::string::npos);
  EXPECT_EQ(text.output.find("binaural"), std::string::npos) << text.output;
  EXPECT_EQ(text.output.find("ITD"), std::string::npos);
  auto json = runEarshot("analyze '" + monoPath + "' --json");
  ASSERT_EQ(json.exitCode, 0);
  EXPECT_FALSE(nlohmann::json::parse(json.output).contains("binaural"));

  auto one = runEarshot("analyze '" + binauralPath + "' --channel 1 --json");
  ASSERT_EQ(one.exitCode, 0) << one.output;
  EXPECT_FALSE(nlohmann::json::parse(one.output).contains("binaural"));
}

TEST(AnalyzeBinauralCli, HelpDescribesTheBinauralCuesAndTheirJsonKeys) {
  auto help = runEarshot("analyze --help");
  EXPECT_EQ(help.exitCode, 0);
  for (const char* key : {"ITD", "ILD", "IACC_E", "IACC_L", "itd_us", "ild_db", "iacc_l3", "left ear leads"})
    EXPECT_NE(help.output.find(key), std::string::npos) << key << "\n" << help.output;
}

}  // namespace
}  // namespace earshot
