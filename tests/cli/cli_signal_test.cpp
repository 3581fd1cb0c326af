// A command ended by a signal (Ctrl-C, kill) leaves no temporary file behind
// (temp_files.h), and its parent sees it ended by that signal.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "cli_test_util.h"

extern char** environ;

namespace earshot {
namespace fs = std::filesystem;
using testing::TempDir;

namespace {

std::vector<std::string> filesIn(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  return names;
}

/** Starts `earshot args...` with the termination signals at their default
 *  (a shell's background job would have SIGINT ignored). */
pid_t spawnEarshot(const std::vector<std::string>& args) {
  std::vector<std::string> all{EARSHOT_CLI};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t defaults;
  sigemptyset(&defaults);
  for (int s : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&defaults, s);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK);
  pid_t pid = -1;
  if (posix_spawn(&pid, all[0].c_str(), nullptr, &attr, argv.data(), environ) != 0) pid = -1;
  posix_spawnattr_destroy(&attr);
  return pid;
}

}  // namespace

class CliSignal : public ::testing::TestWithParam<int> {};

TEST_P(CliSignal, AnInterruptedRenderLeavesNoTemporaryFile) {
  const int sig = GetParam();
  for (bool normalize : {false, true}) {
    TempDir dir("cli_signal_" + std::to_string(sig) + (normalize ? "_n" : ""));
    const fs::path out = fs::path(dir.path) / "out.wav";
    std::vector<std::string> args{"render", std::string(EARSHOT_SOURCE_DIR) + "/samples/hall/circling.json", "-o",
                                  out.string(), "--quiet"};
    if (normalize) args.insert(args.end(), {"--normalize", "-1"});
    const pid_t pid = spawnEarshot(args);
    ASSERT_GT(pid, 0);
    // The render streams into a temporary file beside the output from its
    // start (a render of the sample takes seconds): end it once it is there.
    bool seen = false;
    for (int i = 0; i < 6000 && !seen; ++i) {
      for (const auto& name : filesIn(dir.path)) seen = seen || name.find(".tmp-") != std::string::npos;
      if (!seen) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ASSERT_EQ(::kill(pid, sig), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(seen) << "no temporary file appeared";
    ASSERT_TRUE(WIFSIGNALED(status)) << "exit status " << (WIFEXITED(status) ? WEXITSTATUS(status) : -1);
    EXPECT_EQ(WTERMSIG(status), sig);
    EXPECT_EQ(filesIn(dir.path), std::vector<std::string>{}) << "normalize " << normalize;
  }
}

// A file-size limit (ulimit -f) reached mid-render is a write error naming
// the output (SIGXFSZ ignored), and the temporary file goes.
TEST(CliFileSizeLimit, IsAWriteErrorAndLeavesNothing) {
  TempDir dir("cli_fsize");
  const std::string out = dir / "out.wav";
  const std::string scene = std::string(EARSHOT_SOURCE_DIR) + "/samples/hall/circling.json";
  const std::string cli = EARSHOT_CLI;
  int pipeFds[2];
  ASSERT_EQ(::pipe(pipeFds), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    struct rlimit limit {1 << 20, 1 << 20};  // 1 MiB: the render's WAV is larger
    ::setrlimit(RLIMIT_FSIZE, &limit);
    ::signal(SIGXFSZ, SIG_DFL);  // as a shell leaves it
    ::dup2(pipeFds[1], 2);
    ::close(pipeFds[0]);
    ::execl(cli.c_str(), cli.c_str(), "render", scene.c_str(), "-o", out.c_str(), "--quiet", nullptr);
    ::_exit(127);
  }
  ::close(pipeFds[1]);
  std::string err;
  char buf[4096];
  ssize_t n;
  while ((n = ::read(pipeFds[0], buf, sizeof buf)) > 0) err.append(buf, size_t(n));
  ::close(pipeFds[0]);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "ended by signal " << (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  EXPECT_EQ(WEXITSTATUS(status), 2) << err;
  EXPECT_NE(err.find("out.wav: write failed"), std::string::npos) << err;
  EXPECT_EQ(filesIn(dir.path), std::vector<std::string>{});
}

// -o a hard link to a source's audio is refused before the render starts
// (it was refused only at commit, after rendering all of it: the progress
// lines came first).
TEST(CliRenderOutput, AHardLinkToAnInputIsRefusedBeforeRendering) {
  TempDir dir("cli_render_link");
  const fs::path src = fs::path(EARSHOT_SOURCE_DIR) / "samples" / "hall";
  for (const char* f : {"circling.json", "hall.glb", "materials_map.json", "guitar.wav"})
    fs::copy_file(src / f, fs::path(dir.path) / f);
  fs::create_hard_link(fs::path(dir.path) / "guitar.wav", fs::path(dir.path) / "out.wav");
  const std::string before = testing::readFile(dir / "guitar.wav");
  auto r = testing::runEarshot("render " + dir / "circling.json" + " -o " + dir / "out.wav");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("input"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("earshot: render "), std::string::npos) << r.output;  // no progress: nothing rendered
  EXPECT_EQ(testing::readFile(dir / "guitar.wav"), before);
}

INSTANTIATE_TEST_SUITE_P(Signals, CliSignal, ::testing::Values(SIGINT, SIGTERM, SIGHUP),
                         [](const ::testing::TestParamInfo<int>& i) {
                           return std::string(i.param == SIGINT ? "Int" : i.param == SIGTERM ? "Term" : "Hup");
                         });

}  // namespace earshot
