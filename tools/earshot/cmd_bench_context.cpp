// `earshot bench context`: what creating a C API context costs a game (time,
// heap memory) for a number of source slots, the HRTF load included and
// measured apart (issue 19's "context creation" figure, reproducible).
#include <chrono>
#include <cstdio>
#include <malloc.h>
#include <memory>
#include <string>
#include <vector>

#include "command.h"
#include "earshot/earshot.h"

namespace earshot::cli {
namespace {

struct ContextBenchOptions {
  uint32_t sources = 256;
  unsigned repeats = 3;
};

// Heap bytes in use (glibc): unlike the resident size, it falls again when a
// context is released, so repetitions measure the same thing.
double heapMb() { return double(mallinfo2().uordblks) / (1024.0 * 1024.0); }

int run(const ContextBenchOptions& o) {
  std::vector<double> createMs, oneSlotMs, growthMb;
  for (unsigned k = 0; k < o.repeats; ++k) {
    for (uint32_t slots : {1u, o.sources}) {
      earshot_context_settings s;
      earshot_context_settings_init(&s);
      s.max_sources = slots;
      const double before = heapMb();
      const auto t0 = std::chrono::steady_clock::now();
      earshot_context* c = nullptr;
      if (earshot_context_create(&s, &c) != EARSHOT_OK) {
        printError(std::string("context: ") + earshot_last_error_message());
        return 2;
      }
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      if (slots == 1) {
        oneSlotMs.push_back(ms);
      } else {
        createMs.push_back(ms);
        growthMb.push_back(heapMb() - before);
      }
      earshot_context_release(c);
    }
  }
  std::printf("context with %u source slots: %.1f ms, +%.1f MB of heap; with 1 slot: %.1f ms "
              "(mostly loading the default HRTF); medians of %u\n",
              o.sources, median(createMs), median(growthMb), median(oneSlotMs), o.repeats);
  return 0;
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<ContextBenchOptions>();
  CLI::App& bench = subcommandGroup(root, "bench", "Benchmarks (tracing, synthesis, convolution speed)");
  CLI::App* cmd = bench.add_subcommand(
      "context", "Creating a C API context: time and heap memory for N source slots, and for 1");
  cmd->add_option("--sources", o->sources, "Source slots")->check(CLI::Range(1u, 4096u))->capture_default_str();
  cmd->add_option("--repeats", o->repeats, "Repetitions (medians are reported)")
      ->check(CLI::Range(1u, 100u))
      ->capture_default_str();
  cmd->callback([o] { setExitCode(run(*o)); });
});

}  // namespace
}  // namespace earshot::cli
