// `earshot tradeoff` end to end: a tiny sweep against a reference IR made
// first with `earshot ir`, and the error paths (exit 2, no partial output).
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

TEST(TradeoffCli, TinySweepAgainstAGivenReference) {
  TempDir dir("sweep");
  auto ref = runEarshot("ir " + kScene + " --receiver omni --rays 20000 -o '" + dir / "ref.wav'");
  ASSERT_EQ(ref.exitCode, 0) << ref.output;
  auto r = runEarshot("tradeoff " + kScene + " --rays 500,2000 --bounces 4 --repeats 1 --reference '" +
                      dir / "ref.wav' -o '" + dir / "out.csv'");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  std::string header;
  auto rows = readCsv(dir / "out.csv", header);
  EXPECT_EQ(header, kHeader);
  ASSERT_EQ(rows.size(), 2u);
  double maxJnd[2] = {0, 0};
  for (size_t i = 0; i < rows.size(); ++i) {
    ASSERT_EQ(rows[i].size(), 11u);
    EXPECT_EQ(rows[i][0], i == 0 ? "500" : "2000");
    EXPECT_EQ(rows[i][1], "4");
    EXPECT_GT(std::stod(rows[i][2]), 0.0) << "a run takes some time";
    for (size_t c = 3; c < 11; ++c) {
      const double v = std::stod(rows[i][c]);
      EXPECT_TRUE(std::isfinite(v)) << "row " << i << " column " << c << ": " << rows[i][c];
      EXPECT_GE(v, 0.0) << "row " << i << " column " << c;
    }
    maxJnd[i] = std::stod(rows[i][10]);
    double worst = 0;
    for (size_t c = 3; c < 10; ++c) worst = std::max(worst, std::stod(rows[i][c]));
    EXPECT_DOUBLE_EQ(maxJnd[i], worst) << "max_jnd is the worst of the seven metrics";
  }
  // Monte Carlo noise falls as 1/sqrt(rays): 4x the rays should about halve
  // the random part of the error (the 4-bounce bias is the same in both).
  // 3x leaves room for one unlucky seed without hiding an error that grows
  // with the ray count.
  EXPECT_LE(maxJnd[1], 3.0 * maxJnd[0]) << "2000 rays: " << maxJnd[1] << ", 500 rays: " << maxJnd[0];
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
}

}  // namespace
