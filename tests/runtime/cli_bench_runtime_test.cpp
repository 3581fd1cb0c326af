// `earshot bench runtime` end to end: the report's figures and how they
// relate (a short run: two sources in the shoebox, 1.5 s of audio).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <map>
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
  char buf[1024];
  while (fgets(buf, sizeof buf, p)) r.out += buf;
  int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// Every key=number of the report.
std::map<std::string, double> figures(const std::string& out) {
  std::map<std::string, double> f;
  const std::regex kv(R"(([a-z0-9_]+)=([0-9.]+))");
  for (auto it = std::sregex_iterator(out.begin(), out.end(), kv); it != std::sregex_iterator(); ++it)
    f[(*it)[1]] = std::stod((*it)[2]);
  return f;
}

TEST(CliBenchRuntime, ReportsTheWorstBlocksWallAndCpuTimeAndTheMachinesSteal) {
  const std::string shoebox = std::string(EARSHOT_SOURCE_DIR) + "/samples/shoebox/shoebox.gltf";
  Ran r = runCli("bench runtime '" + shoebox + "' --sources 2 --seconds 1.5 --quality draft --ir-seconds 0.5");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto f = figures(r.out);
  for (const char* key : {"worst_block_pct_of_period", "p99_block_pct", "worst_block_cpu_pct", "max_block_cpu_pct",
                          "per_source_update_hz", "machine_steal_ms"})
    ASSERT_EQ(f.count(key), 1u) << key << " missing in\n" << r.out;
  // A block's CPU time lies within its wall time; the most CPU any block
  // took is at least the worst (wall) block's; p99 is at most the worst.
  EXPECT_LE(f.at("worst_block_cpu_pct"), f.at("worst_block_pct_of_period") + 1e-6);
  EXPECT_LE(f.at("worst_block_cpu_pct"), f.at("max_block_cpu_pct") + 1e-6);
  EXPECT_LE(f.at("p99_block_pct"), f.at("worst_block_pct_of_period") + 1e-6);
  EXPECT_GT(f.at("max_block_cpu_pct"), 0.0);
  EXPECT_GT(f.at("per_source_update_hz"), 0.0);
}

}  // namespace
