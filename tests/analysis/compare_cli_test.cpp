// The `earshot analyze` and `earshot compare` commands, run as a user would
// (the built executable, EARSHOT_CLI), checking exit codes and what they name.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <random>
#include <vector>

#include "earshot/io/wav.h"

namespace earshot {
namespace {

// Temporary files, unique per test process (ctest may run these tests in
// parallel), removed when the process ends.
struct TempFiles {
  std::vector<std::string> paths;
  ~TempFiles() {
    for (const auto& p : paths) std::remove(p.c_str());
  }
};
TempFiles gTemp;

std::string tempPath(const std::string& name) {
  gTemp.paths.push_back(testing::TempDir() + "/earshot_analysis_" + std::to_string(getpid()) + "_" + name);
  return gTemp.paths.back();
}

struct CliRun {
  int exitCode = -1;
  std::string out, err;
};

CliRun run(const std::string& args) {
  const std::string errPath = tempPath("stderr.txt");
  const std::string cmd = std::string("'") + EARSHOT_CLI + "' " + args + " 2>'" + errPath + "'";
  CliRun r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n = 0;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int status = pclose(p);
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream err(errPath);
  r.err.assign(std::istreambuf_iterator<char>(err), {});
  return r;
}

// A 1 s noise IR (48 kHz) whose energy decays 60 dB in tS seconds, direct
// sound at 10 ms; the same seed gives the same noise, so two of them differ
// only in decay rate.
std::string writeDecay(const std::string& name, double tS) {
  const double fs = 48000.0;
  AudioBuffer a(1, size_t(fs), fs);
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  for (size_t i = 480; i < a.frameCount(); ++i)
    a.channels[0][i] = float(0.5 * g(rng) * std::exp(-6.9 * double(i - 480) / fs / tS));
  const std::string path = tempPath(name);
  EXPECT_TRUE(writeWavFloat(path, a).isOk());
  return path;
}

int countLines(const std::string& s) { return int(std::count(s.begin(), s.end(), '\n')); }

TEST(CompareCli, IdenticalFilesAreWithinTolerance) {
  const std::string a = writeDecay("cli_a.wav", 0.5);
  CliRun r = run("compare '" + a + "' '" + a + "'");
  EXPECT_EQ(r.exitCode, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("PASS"), std::string::npos) << r.out;
}

// T30 scaled by 1.15 is 3 JND (5 % each) away: exit 1 and the failure names
// T30. A tolerance file that disables everything but T30 and allows 4 JND
// turns it into a pass; restricting --bands to broadband keeps the failure.
TEST(CompareCli, AScaledDecayFailsNamingT30) {
  const std::string a = writeDecay("cli_a.wav", 0.5), b = writeDecay("cli_b.wav", 0.5 * 1.15);
  CliRun r = run("compare '" + b + "' '" + a + "'");
  EXPECT_EQ(r.exitCode, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("FAIL channel 0 T30 broadband"), std::string::npos) << r.out;

  CliRun j = run("compare '" + b + "' '" + a + "' --json --bands broadband");
  EXPECT_EQ(j.exitCode, 1);
  auto doc = nlohmann::json::parse(j.out);
  EXPECT_FALSE(doc.at("within_tolerance").get<bool>());
  bool sawT30 = false;
  for (const auto& row : doc.at("channels").at(0).at("rows"))
    if (row.at("metric") == "T30") {
      sawT30 = true;
      EXPECT_EQ(row.at("verdict"), "fail");
      EXPECT_NEAR(row.at("difference_jnd").get<double>(), 3.0, 0.6);  // 15 % = 3 JND, +- noise-decay scatter
    }
  EXPECT_TRUE(sawT30);

  const std::string tol = tempPath("cli_tol.json");
  std::ofstream(tol) << R"({"metrics": {"EDT": false, "T20": false, "C50": false, "C80": false,
                                        "D50": false, "Ts": false, "T30": 4}})";
  CliRun t = run("compare '" + b + "' '" + a + "' --tolerance '" + tol + "'");
  EXPECT_EQ(t.exitCode, 0) << t.out << t.err;
}

TEST(CompareCli, ErrorsAreOneLineAndExitTwo) {
  const std::string a = writeDecay("cli_a.wav", 0.5);
  CliRun missing = run("compare '" + a + "' /nonexistent/ref.wav");
  EXPECT_EQ(missing.exitCode, 2);
  EXPECT_EQ(countLines(missing.err), 1) << missing.err;
  EXPECT_NE(missing.err.find("/nonexistent/ref.wav"), std::string::npos);

  CliRun badBand = run("compare '" + a + "' '" + a + "' --bands 300");
  EXPECT_EQ(badBand.exitCode, 2);
  EXPECT_NE(badBand.err.find("300"), std::string::npos);

  CliRun badWindow = run("compare '" + a + "' '" + a + "' --window 0.5,0.1");
  EXPECT_EQ(badWindow.exitCode, 2);

  const std::string notAudio = tempPath("cli_not_audio.wav");
  std::ofstream(notAudio) << "this is not audio";
  CliRun na = run("analyze '" + notAudio + "'");
  EXPECT_EQ(na.exitCode, 2);
  EXPECT_EQ(countLines(na.err), 1) << na.err;

  CliRun gone = run("analyze /nonexistent/ir.wav");
  EXPECT_EQ(gone.exitCode, 2);
  EXPECT_EQ(countLines(gone.err), 1) << gone.err;

  const std::string empty = tempPath("cli_empty.wav");
  EXPECT_TRUE(writeWavFloat(empty, AudioBuffer(1, 0, 48000.0)).isOk());
  CliRun e = run("analyze '" + empty + "'");
  EXPECT_EQ(e.exitCode, 2);
  EXPECT_EQ(countLines(e.err), 1) << e.err;
}

TEST(AnalyzeCli, JsonHasEveryBandOfEveryChannel) {
  const double fs = 48000.0;
  AudioBuffer a(2, size_t(fs), fs);
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  for (size_t c = 0; c < 2; ++c)
    for (size_t i = 480 + c * 20; i < a.frameCount(); ++i)
      a.channels[c][i] = float(0.5 * g(rng) * std::exp(-6.9 * double(i) / fs / 0.4));
  const std::string path = tempPath("cli_binaural.wav");
  ASSERT_TRUE(writeWavFloat(path, a).isOk());
  CliRun r = run("analyze '" + path + "' --json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  auto doc = nlohmann::json::parse(r.out);
  ASSERT_EQ(doc.at("channels").size(), 2u);
  EXPECT_EQ(doc.at("channels").at(1).at("label"), "right");
  ASSERT_EQ(doc.at("channels").at(0).at("bands").size(), 8u);
  const auto& bb = doc.at("channels").at(0).at("bands").at(7);
  EXPECT_EQ(bb.at("band"), "broadband");
  EXPECT_NEAR(bb.at("T30").get<double>(), 0.4, 0.02);  // 5 %: ISO 3382-2 scatter is < 1 % broadband
  EXPECT_NEAR(doc.at("channels").at(1).at("bands").at(7).at("onset_s").get<double>(), 0.01 + 20 / fs, 2e-3);

  CliRun table = run("analyze '" + path + "' --channel 1");
  EXPECT_EQ(table.exitCode, 0);
  EXPECT_NE(table.out.find("channel 1 (right)"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("broadband"), std::string::npos);
}

}  // namespace
}  // namespace earshot
