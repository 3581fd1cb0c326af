// `earshot tradeoff` end to end: a tiny sweep and a --presets run against a
// reference IR made first with `earshot ir`, and the error paths (exit 2, no
// partial output).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "earshot/ir/ir_pipeline.h"

namespace {

namespace fs = std::filesystem;

struct RunResult {
  int exitCode = -1;
  std::string output;  // stdout and stderr together
};

RunResult runEarshot(const std::string& args) {
  RunResult r;
  const std::string cmd = std::string("'") + EARSHOT_CLI + "' " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int status = pclose(p);
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name) {
    path = fs::temp_directory_path() / ("earshot_tradeoff_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
  std::string operator/(const std::string& f) const { return (path / f).string(); }
};

const std::string kShoebox = std::string(EARSHOT_SOURCE_DIR) + "/samples/shoebox/";
const std::string kScene = "'" + kShoebox + "shoebox.gltf' --material-map '" + kShoebox +
                           "materials_map.json' --source 2,3.5,1.5 --listener 7,3.5,1.5 --threads 2";
const std::string kHeader = "rays,bounces,seconds_median,edt_jnd,t20_jnd,t30_jnd,c50_jnd,c80_jnd,d50_jnd,ts_jnd,max_jnd";

std::vector<std::vector<std::string>> readCsv(const std::string& path, std::string& header) {
  std::ifstream f(path);
  std::vector<std::vector<std::string>> rows;
  std::getline(f, header);
  std::string line;
  while (std::getline(f, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

/** Checks a CSV row's numbers from `first` on (seconds_median, the seven
 *  <metric>_jnd, max_jnd): time > 0, errors finite and >= 0, max_jnd the
 *  worst of the seven. Returns max_jnd. */
double expectSaneNumbers(const std::vector<std::string>& row, size_t first) {
  EXPECT_GT(std::stod(row.at(first)), 0.0) << "a run takes some time";
  double worst = 0;
  for (size_t c = first + 1; c <= first + 8; ++c) {
    const double v = std::stod(row.at(c));
    EXPECT_TRUE(std::isfinite(v)) << row[0] << " column " << c << ": " << row[c];
    EXPECT_GE(v, 0.0) << row[0] << " column " << c;
    if (c < first + 8) worst = std::max(worst, v);
  }
  const double maxJnd = std::stod(row.at(first + 8));
  EXPECT_DOUBLE_EQ(maxJnd, worst) << "max_jnd is the worst of the seven metrics";
  return maxJnd;
}

/** Makes a reference IR of `referenceRays` rays with `earshot ir` in `dir`,
 *  runs `earshot tradeoff <scene> <args>` against it and reads the CSV. A
 *  failed command is a test failure and gives no rows. */
std::vector<std::vector<std::string>> tradeoffAgainstAReference(const TempDir& dir, int referenceRays,
                                                                const std::string& args, std::string& header) {
  auto ref = runEarshot("ir " + kScene + " --receiver omni --rays " + std::to_string(referenceRays) + " -o '" +
                        dir / "ref.wav'");
  if (ref.exitCode != 0) {
    ADD_FAILURE() << "earshot ir: " << ref.output;
    return {};
  }
  auto r = runEarshot("tradeoff " + kScene + " " + args + " --reference '" + dir / "ref.wav' -o '" + dir / "out.csv'");
  if (r.exitCode != 0) {
    ADD_FAILURE() << "earshot tradeoff: " << r.output;
    return {};
  }
  return readCsv(dir / "out.csv", header);
}

TEST(TradeoffCli, TinySweepAgainstAGivenReference) {
  TempDir dir("sweep");
  std::string header;
  auto rows = tradeoffAgainstAReference(dir, 20000, "--rays 500,2000 --bounces 4 --repeats 1", header);
  EXPECT_EQ(header, kHeader);
  ASSERT_EQ(rows.size(), 2u);
  double maxJnd[2] = {0, 0};
  for (size_t i = 0; i < rows.size(); ++i) {
    ASSERT_EQ(rows[i].size(), 11u);
    EXPECT_EQ(rows[i][0], i == 0 ? "500" : "2000");
    EXPECT_EQ(rows[i][1], "4");
    maxJnd[i] = expectSaneNumbers(rows[i], 2);
  }
  // Monte Carlo noise falls as 1/sqrt(rays): 4x the rays should about halve
  // the random part of the error (the 4-bounce bias is the same in both).
  // 3x leaves room for one unlucky seed without hiding an error that grows
  // with the ray count.
  EXPECT_LE(maxJnd[1], 3.0 * maxJnd[0]) << "2000 rays: " << maxJnd[1] << ", 500 rays: " << maxJnd[0];
}

TEST(TradeoffCli, PresetsGiveOneRowPerPresetWithItsSettings) {
  TempDir dir("presets");
  std::string header;
  auto rows = tradeoffAgainstAReference(dir, 4000, "--presets draft,balanced --repeats 1", header);
  EXPECT_EQ(header, "preset," + kHeader);
  ASSERT_EQ(rows.size(), 2u);
  const char* names[2] = {"draft", "balanced"};
  for (size_t i = 0; i < rows.size(); ++i) {
    ASSERT_EQ(rows[i].size(), 12u);
    EXPECT_EQ(rows[i][0], names[i]) << "rows in the order given";
    auto preset = earshot::qualityPreset(names[i]);
    ASSERT_TRUE(preset.isOk());
    EXPECT_EQ(rows[i][1], std::to_string(preset->rays)) << "the preset's own ray count, not the grid's";
    EXPECT_EQ(rows[i][2], std::to_string(preset->bounces));
    expectSaneNumbers(rows[i], 3);
  }
}

TEST(TradeoffCli, UnknownPresetOrPresetsWithAGridAreExit2BeforeAnyWork) {
  TempDir dir("badpreset");
  auto r = runEarshot("tradeoff " + kScene + " --presets draft,ultra -o '" + dir / "out.csv'");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("--presets"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"ultra\""), std::string::npos) << "names the bad preset: " << r.output;
  EXPECT_NE(r.output.find("draft, balanced, high, reference"), std::string::npos) << "lists the valid ones: "
                                                                                    << r.output;
  EXPECT_EQ(r.output.find("reference run"), std::string::npos) << "no work before the error: " << r.output;
  EXPECT_FALSE(fs::exists(dir / "out.csv"));
  r = runEarshot("tradeoff " + kScene + " --presets draft, -o '" + dir / "out.csv'");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("--presets"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "out.csv"));
  r = runEarshot("tradeoff " + kScene + " --presets draft --rays 500 -o '" + dir / "out.csv'");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("--rays"), std::string::npos) << "the grid and --presets exclude each other: " << r.output;
  EXPECT_FALSE(fs::exists(dir / "out.csv"));
}

TEST(TradeoffCli, MissingGeometryIsExit2AndNoCsv) {
  TempDir dir("missing");
  auto r = runEarshot("tradeoff '" + dir / "nope.gltf' --source 2,3.5,1.5 --listener 7,3.5,1.5 -o '" +
                      dir / "out.csv'");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_FALSE(fs::exists(dir / "out.csv"));
}

TEST(TradeoffCli, BadListAndMissingPlotScriptAreExit2BeforeAnyWork) {
  TempDir dir("bad");
  auto r = runEarshot("tradeoff " + kScene + " --rays 500,x -o '" + dir / "out.csv'");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("--rays"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "out.csv"));
  r = runEarshot("tradeoff " + kScene + " --rays 500 --bounces 4 --plot '" + dir / "out.svg' --plot-script '" +
                 dir / "none.py' -o '" + dir / "out.csv'");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("--plot-script"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "out.csv"));
  EXPECT_FALSE(fs::exists(dir / "out.svg"));
}

TEST(TradeoffCli, HelpDescribesTheOptions) {
  auto r = runEarshot("tradeoff --help");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("--reference"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--repeats"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--presets"), std::string::npos) << r.output;
}

}  // namespace

namespace {

// Issue 15: --ambisonic-orders writes the floor row (binaural reflections of
// another seed) and one row per order; the late IACC of every order is
// within 0.1 of the exact binaural rendering (the criterion).
TEST(TradeoffCli, AmbisonicOrdersAgainstExactBinaural) {
  TempDir dir("tradeoff_ambisonic");
  auto r = runEarshot("tradeoff " + kScene + " --forward 0,1,0 --up 0,0,1 " +
                      "--quality draft --ambisonic-orders 1,3 -o '" + dir / "amb.csv'");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  std::string header;
  const auto rows = readCsv(dir / "amb.csv", header);
  ASSERT_EQ(rows.size(), 3u) << header;
  EXPECT_EQ(header.rfind("order,channels,ild_err_250_db", 0), 0u) << header;
  EXPECT_EQ(rows[0][0], "binaural_other_seed");
  EXPECT_EQ(rows[1][0], "1");
  EXPECT_EQ(rows[1][1], "4");
  EXPECT_EQ(rows[2][1], "16");
  for (size_t i = 1; i < rows.size(); ++i)
    for (size_t c = 7; c <= 9; ++c) EXPECT_LT(std::fabs(std::stod(rows[i][c])), 0.1) << header << " row " << i;
  auto bad = runEarshot("tradeoff " + kScene + " --ambisonic-orders 4 -o '" +
                        dir / "bad.csv'");
  EXPECT_EQ(bad.exitCode, 2);
  EXPECT_FALSE(fs::exists(dir / "bad.csv"));
}

}  // namespace
