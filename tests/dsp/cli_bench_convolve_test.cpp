// `earshot bench convolve` end to end: the one-line report and its errors.

// GCC 12 (the asan preset's -O2 with the sanitizers) warns
// -Wmaybe-uninitialized inside libstdc++'s std::regex (std::function's move
// of an automaton state): a false positive in library code this file only
// uses, so off for the file, before the includes that define it.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <regex>
#include <string>

namespace {

struct Ran {
  std::string out;
  int code = -1;
};

Ran runCli(const std::string& args) {
  std::string cmd = std::string("'") + EARSHOT_CLI + "' " + args + " 2>&1";
  Ran r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[512];
  while (fgets(buf, sizeof buf, p)) r.out += buf;
  int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

TEST(CliBenchConvolve, PrintsOneReportLine) {
  for (const char* spectra : {"float", "half"}) {
    const std::string compact = std::string(spectra) == "half" ? " --compact" : "";
    Ran r = runCli("bench convolve --ir-seconds 0.1 --block 128 --seconds 0.2 --sources 2" + compact);
    ASSERT_EQ(r.code, 0) << r.out;
    std::smatch m;
    std::regex line(R"(convolve L=0\.1 B=128 sources=2 rt_factor=([0-9.]+) p99_block_pct=([0-9.]+) )"
                    R"(max_block_pct=([0-9.]+) spectra=)" +
                    std::string(spectra) + "\n");
    ASSERT_TRUE(std::regex_match(r.out, m, line)) << r.out;
    EXPECT_GT(std::stod(m[1]), 0.0);
    EXPECT_LE(std::stod(m[2]), std::stod(m[3]));  // p99 never above the maximum
  }
}

// --swap-every: a second line, the blocks timed while every source's IR
// changes every N blocks.
TEST(CliBenchConvolve, SwapEveryTimesTheCrossfadesApart) {
  Ran r = runCli("bench convolve --ir-seconds 0.05 --block 128 --seconds 0.2 --sources 3 --channels 4 --compact "
                 "--swap-every 4");
  ASSERT_EQ(r.code, 0) << r.out;
  std::smatch m;
  std::regex lines(R"(convolve L=0\.05 B=128 sources=3 [^\n]*spectra=half\n)"
                   R"(convolve-swap L=0\.05 B=128 sources=3 every=4 max_block_pct=([0-9.]+) p99_block_pct=([0-9.]+) )"
                   R"(median_block_pct=([0-9.]+) \(no swaps: max [0-9.]+ p99 [0-9.]+\)\n)");
  ASSERT_TRUE(std::regex_match(r.out, m, lines)) << r.out;
  EXPECT_LE(std::stod(m[2]), std::stod(m[1]));
  EXPECT_LE(std::stod(m[3]), std::stod(m[2]));
  EXPECT_GT(std::stod(m[3]), 0.0);
  // Without it, one line only.
  Ran plain = runCli("bench convolve --ir-seconds 0.05 --block 128 --seconds 0.1");
  ASSERT_EQ(plain.code, 0) << plain.out;
  EXPECT_EQ(plain.out.find("convolve-swap"), std::string::npos) << plain.out;
}

TEST(CliBenchConvolve, RejectsABlockKissFftWouldAllocateFor) {
  Ran r = runCli("bench convolve --block 14 --seconds 0.1");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("latencyFrames=14"), std::string::npos) << r.out;
}

}  // namespace
