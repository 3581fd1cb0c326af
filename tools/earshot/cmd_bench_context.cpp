// `earshot bench context`: what creating a C API context costs a game (time,
// heap memory) for a number of source slots, and what its sources cost: the
// first waits for the HRTF load, each one allocates its slot's state
// (issue 19's "context creation" figure, reproducible).
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
  // Per repetition: create (the HRTF loads in the background), then the
  // first source (waits for the load), then every other slot's source.
  std::vector<double> createMs, createMb, firstMs, firstMb, restMs, allMb;
  for (unsigned k = 0; k < o.repeats; ++k) {
    earshot_context_settings s;
    earshot_context_settings_init(&s);
    s.max_sources = o.sources;
    const double before = heapMb();
    auto t0 = std::chrono::steady_clock::now();
    earshot_context* c = nullptr;
    if (earshot_context_create(&s, &c) != EARSHOT_OK) {
      printError(std::string("context: ") + earshot_last_error_message());
      return 2;
    }
    createMs.push_back(msSince(t0));
    createMb.push_back(heapMb() - before);
    earshot_source_settings ss;
    earshot_source_settings_init(&ss);
    std::vector<earshot_source*> sources(o.sources, nullptr);
    for (uint32_t i = 0; i < o.sources; ++i) {
      t0 = std::chrono::steady_clock::now();
      if (earshot_source_create(c, &ss, &sources[i]) != EARSHOT_OK) {
        printError(std::string("source: ") + earshot_last_error_message());
        for (earshot_source* src : sources)
          if (src) earshot_source_release(src);
        earshot_context_release(c);
        return 2;
      }
      const double ms = msSince(t0);
      if (i == 0) {
        firstMs.push_back(ms);
        firstMb.push_back(heapMb() - before);
      } else {
        restMs.push_back(ms);
      }
    }
    allMb.push_back(heapMb() - before);
    for (earshot_source* src : sources) earshot_source_release(src);
    earshot_context_release(c);
  }
  std::printf("context with %u source slots (default settings: 48 kHz, IRs up to 3 s), medians of %u:\n", o.sources,
              o.repeats);
  std::printf("  create:                     %8.1f ms  %+8.1f MB of heap (the HRTF loads in the background)\n",
              median(createMs), median(createMb));
  std::printf("  first source:               %8.1f ms  %+8.1f MB in all (waits for the HRTF load)\n", median(firstMs),
              median(firstMb));
  if (o.sources > 1)
    std::printf("  each further source:        %8.2f ms  %+8.2f MB each; all %u sources: %+.1f MB\n", median(restMs),
                (median(allMb) - median(firstMb)) / double(o.sources - 1), o.sources, median(allMb));
  return 0;
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<ContextBenchOptions>();
  CLI::App& bench = subcommandGroup(root, "bench", "Benchmarks (tracing, synthesis, convolution speed)");
  CLI::App* cmd = bench.add_subcommand(
      "context",
      "Creating a C API context of N source slots, then its first source and the others: time and heap memory");
  cmd->add_option("--sources", o->sources, "Source slots")->check(CLI::Range(1u, 4096u))->capture_default_str();
  cmd->add_option("--repeats", o->repeats, "Repetitions (medians are reported)")
      ->check(CLI::Range(1u, 100u))
      ->capture_default_str();
  cmd->callback([o] { setExitCode(run(*o)); });
});

}  // namespace
}  // namespace earshot::cli
