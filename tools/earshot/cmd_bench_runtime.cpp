// `earshot bench runtime`: the middleware workload. N moving sources in a
// scene; a simulation thread updates their reflections round robin as fast
// as it can (or at a set rate); the audio thread renders 256-frame blocks in
// real time (paced by the clock). Reports CPU time per thread role and the
// worst audio block as a fraction of its period: its wall time, and the
// audio thread's own CPU time in it (worst_block_cpu_pct; the difference is
// time the thread waited for the CPU) and in the block that took the most
// (max_block_cpu_pct), and the page faults the audio thread took in
// engine.process after the first second. With --one-shots-hz, the game also
// adds sources now and then (each released once simulated), and the time
// each waited for its first reflections is reported.
#include <pthread.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <sched.h>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <cstring>
#include <memory>
#include <thread>
#include <vector>

#include "command.h"
#include "earshot/core/math.h"
#include "earshot/core/thread_pool.h"
#include "earshot/ir/binaural_synthesis.h"
#include "earshot/runtime/engine.h"

namespace earshot::cli {
namespace {

struct BenchRuntimeOptions {
  std::string geometry;
  std::string materialMap;
  std::string quality = "balanced";
  unsigned sources = 32;
  double seconds = 10.0;
  size_t block = 256;
  double updateHz = 10.0;  // per-source target; the thread runs round robin, never faster than this
  unsigned threads = 0;  // the engine's default: the cores less one
  size_t maxPartition = 0;
  int ambisonicOrder = -1;  // -1: the engine's default
  std::string trace = "shared";
  double irSeconds = 0.0;   // 0: the engine's default maxIrSeconds
  double turnDegreesPerSecond = 90.0;
  double sharedTail = -1.0;  // < 0: the engine's default
  size_t groupSources = 0;   // 0: the engine's default
  double oneShotsHz = 0.0;   // sources added by the game per second (0: none)
};

// One-shots live at once at most (the slots kept for them).
constexpr unsigned kMaxOneShots = 16;

double threadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

// Page faults this thread has taken so far (minor and major): a fault costs
// ~12 us in this project's guest (docs/performance.md), so a block that
// faults a few hundred times takes a third of its period more.
uint64_t threadFaults() {
  rusage ru{};
  if (getrusage(RUSAGE_THREAD, &ru) != 0) return 0;
  return uint64_t(ru.ru_minflt) + uint64_t(ru.ru_majflt);
}

// The machine's steal time so far (Linux /proc/stat: time a hypervisor ran
// something else while this guest's CPUs had work), summed over CPUs, in
// seconds; negative where unknown. A guest's thread CPU clock may count
// time stolen while the thread ran as its own (tools/stall_probe.py
// measured it), so a block the hypervisor held up can look slow even in
// CPU time.
double stealSeconds() {
  std::FILE* f = std::fopen("/proc/stat", "r");
  if (!f) return -1.0;
  unsigned long long v[8] = {};
  const int got = std::fscanf(f, "cpu %llu %llu %llu %llu %llu %llu %llu %llu", &v[0], &v[1], &v[2], &v[3], &v[4],
                              &v[5], &v[6], &v[7]);
  std::fclose(f);
  const long hz = sysconf(_SC_CLK_TCK);
  if (got != 8 || hz <= 0) return -1.0;
  return double(v[7]) / double(hz);
}

int run(const BenchRuntimeOptions& o) {
  auto scene = loadSceneInputs(o.geometry, "", o.materialMap);
  if (!check(scene.status())) return 2;
  runtime::EngineSettings es;
  auto preset = qualityPreset(o.quality);
  if (!check(preset.status())) return 2;
  apply(*preset, es.simulation);
  es.blockFrames = o.block;
  es.maxSources = o.sources + (o.oneShotsHz > 0 ? kMaxOneShots : 0);
  if (o.groupSources > 0) es.simulationGroupSources = o.groupSources;
  es.threads = o.threads;
  es.maxPartitionFrames = o.maxPartition;
  if (o.ambisonicOrder >= 0) es.ambisonicOrder = o.ambisonicOrder;
  if (o.irSeconds > 0) es.maxIrSeconds = o.irSeconds;
  if (o.sharedTail >= 0) es.sharedTailSeconds = o.sharedTail;
  es.traceMode = *traceModeFromString(o.trace);
  auto model = loadBinauralModel("", es.sampleRateHz);
  if (!check(model.status())) return 2;
  auto created = runtime::Engine::create(es, *model);
  if (!check(created.status())) return 2;
  runtime::Engine& engine = **created;
  std::shared_ptr<const RayTracer> tracer = std::move(scene->tracer);
  engine.setScene(tracer, std::make_shared<const MaterialTable>(scene->materials));
  const Vec3f lo = tracer->boundsMin(), hi = tracer->boundsMax();
  const Vec3d centre = (Vec3d(lo) + Vec3d(hi)) * 0.5;
  // Sources circle the centre inside the bounds (ringPosition).
  auto sourceAt = [&](unsigned i, double t) { return ringPosition(*tracer, 2 * kPi * (double(i) / o.sources + 0.05 * t)); };
  std::vector<uint32_t> ids;
  for (unsigned i = 0; i < o.sources; ++i) {
    auto id = engine.addSource({}, sourceAt(i, 0));
    if (!check(id.status())) return 2;
    ids.push_back(*id);
  }
  if (!check(engine.setListener(centre, {{1, 0, 0}, {0, 0, 1}}))) return 2;
  if (!check(engine.simulate())) return 2;  // every source once before the clock starts

  std::atomic<bool> stop{false};
  std::atomic<uint64_t> updates{0};
  // The moving sources' IR updates (one-shots apart), from here to the end.
  auto movingSimulations = [&] {
    uint64_t n = 0;
    for (uint32_t id : ids) n += engine.sourceIrInfo(id).simulations;
    return n;
  };
  const uint64_t movingBefore = movingSimulations();
  double simCpu = 0;
  runtime::SimulationStats simTotals;  // summed over the clocked simulations
  std::thread sim([&] {
    lowerThisThreadsPriority(es.workerNice);  // as the engine's workers: below the audio thread
    const double c0 = threadCpuSeconds();
    const auto start = std::chrono::steady_clock::now();
    while (!stop.load()) {
      // Never more than updateHz per source: wait for the slot's turn.
      const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (double(updates.load()) >= elapsed * o.updateHz * o.sources) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        continue;
      }
      // Shared: every source from one trace; per source: one at a time.
      if (!engine.simulate(es.traceMode == TraceMode::kShared ? 0u : 1u).isOk()) break;
      const runtime::SimulationStats st = engine.lastSimulation();
      updates.fetch_add(st.sourcesSimulated);
      simTotals.traceMs += st.traceMs;
      simTotals.synthesisMs += st.synthesisMs;
      simTotals.prepareMs += st.prepareMs;
      simTotals.totalMs += st.totalMs;
    }
    simCpu = threadCpuSeconds() - c0;
  });

  const double fs = es.sampleRateHz, period = double(o.block) / fs;
  const size_t blocks = size_t(o.seconds / period);
  std::vector<std::vector<float>> in(o.sources, std::vector<float>(o.block));
  std::vector<const float*> inputs(es.maxSources, nullptr);
  for (unsigned s = 0; s < o.sources; ++s) {
    for (size_t k = 0; k < o.block; ++k) in[s][k] = float(0.1 * std::sin(0.01 * double(k * (s + 3))));
    inputs[s] = in[s].data();
  }
  std::vector<float> left(o.block), right(o.block);
  std::vector<double> blockMs, blockCpuMs, irAges;
  // The game's calls: their wall time per block (poses, one-shots, IR
  // ages), and each addSource / removeSource of a one-shot (a call that
  // waits for a lock the simulation holds shows here).
  std::vector<double> gameMs, addRemoveMs;
  gameMs.reserve(size_t(o.seconds * es.sampleRateHz / double(o.block)) + 1);
  addRemoveMs.reserve(2 * size_t(o.seconds * o.oneShotsHz + 1));
  std::vector<uint64_t> blockFaults;
  // The audio thread (this one) at real-time priority where the system
  // allows it; said either way.
  std::string audioPriority = "realtime (SCHED_FIFO 80)";
  {
    sched_param sp{};
    sp.sched_priority = 80;
    const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    if (err != 0) audioPriority = std::string("normal (SCHED_FIFO refused: ") + std::strerror(err) + ")";
  }
  const size_t ageEvery = std::max<size_t>(1, size_t(0.1 / (double(o.block) / es.sampleRateHz)));
  double audioCpu = 0, gameCpu = 0;
  std::vector<std::pair<uint32_t, double>> oneShots;  // live: slot, when added (s)
  oneShots.reserve(kMaxOneShots);
  std::vector<double> oneShotWaits;
  double nextOneShot = 1.0;
  size_t oneShotCount = 0, oneShotsMissed = 0;
  const double steal0 = stealSeconds();
  const auto start = std::chrono::steady_clock::now();
  for (size_t b = 0; b < blocks; ++b) {
    // Game thread's part, here at 90 Hz: new poses for every source.
    const double t = double(b) * period;
    const double g0 = threadCpuSeconds();
    const auto gameStart = std::chrono::steady_clock::now();
    if (b % std::max<size_t>(1, size_t((1.0 / 90.0) / period)) == 0) {
      for (unsigned s = 0; s < o.sources; ++s) (void)engine.setSourcePosition(ids[s], sourceAt(s, t));
      // The head turns about the up axis (z) of the samples.
      const double a = o.turnDegreesPerSecond * kPi / 180.0 * t;
      (void)engine.setListener(centre, {{std::cos(a), std::sin(a), 0.0}, {0.0, 0.0, 1.0}});
    }
    // One-shots: added from the first second on, released once their
    // first IR has landed (they play nothing: what is measured is the wait).
    if (o.oneShotsHz > 0 && t >= nextOneShot) {
      nextOneShot += 1.0 / o.oneShotsHz;
      const auto a0 = std::chrono::steady_clock::now();
      auto id = oneShots.size() < kMaxOneShots ? engine.addSource({}, sourceAt(unsigned(oneShotCount * 7 + 3), t))
                                               : Result<uint32_t>(outOfRange("no slot"));
      if (id.isOk()) addRemoveMs.push_back(msSince(a0));
      if (id.isOk()) {
        oneShots.push_back({*id, t});
      } else {
        ++oneShotsMissed;
      }
      ++oneShotCount;
    }
    for (size_t k = 0; k < oneShots.size();) {
      const bool simulated = engine.sourceIrInfo(oneShots[k].first).simulations > 0;
      if (simulated || t - oneShots[k].second > 3.0) {
        if (simulated) oneShotWaits.push_back(t - oneShots[k].second);
        else ++oneShotsMissed;
        const auto r0 = std::chrono::steady_clock::now();
        (void)engine.removeSource(oneShots[k].first);
        addRemoveMs.push_back(msSince(r0));
        oneShots.erase(oneShots.begin() + std::ptrdiff_t(k));
      } else {
        ++k;
      }
    }
    gameCpu += threadCpuSeconds() - g0;
    if (b % ageEvery == 0 && double(b) * period >= 1.0) {
      // Every 100 ms after the first second: how old each source's IR is.
      const auto now = std::chrono::steady_clock::now();
      for (unsigned s = 0; s < o.sources; ++s)
        irAges.push_back(std::chrono::duration<double>(now - engine.sourceIrInfo(ids[s]).posed).count());
    }
    gameMs.push_back(msSince(gameStart));
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = threadCpuSeconds();
    const uint64_t f0 = threadFaults();
    engine.process(inputs.data(), left.data(), right.data(), o.block);
    const double cpu = threadCpuSeconds() - c0;
    const uint64_t faults = threadFaults() - f0;
    audioCpu += cpu;
    blockMs.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    blockCpuMs.push_back(1000.0 * cpu);
    blockFaults.push_back(faults);
    std::this_thread::sleep_until(start + std::chrono::duration<double>(double(b + 1) * period));
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double steal1 = stealSeconds();
  stop = true;
  sim.join();
  // The first second (first touch of every buffer, IR pick-up) is reported apart.
  const size_t warm = std::min(blockMs.size() - 1, size_t(1.0 / period));
  const double worstFirstSecond = *std::max_element(blockMs.begin(), blockMs.begin() + std::ptrdiff_t(warm) + 1);
  // The worst block's wall time, and the audio thread's own CPU time in it:
  // a real-time thread that waited for the CPU (another process, the
  // hypervisor) shows a wall time far over its CPU time. And the most CPU
  // time any block took.
  const auto worstAt = std::max_element(blockMs.begin() + std::ptrdiff_t(warm), blockMs.end());
  const double worstCpu = blockCpuMs[size_t(worstAt - blockMs.begin())];
  const double maxCpu = *std::max_element(blockCpuMs.begin() + std::ptrdiff_t(warm), blockCpuMs.end());
  const uint64_t worstFaults = blockFaults[size_t(worstAt - blockMs.begin())];
  uint64_t steadyFaults = 0, faultingBlocks = 0;
  for (size_t b = warm; b < blockFaults.size(); ++b) {
    steadyFaults += blockFaults[b];
    faultingBlocks += blockFaults[b] > 0 ? 1 : 0;
  }
  std::vector<double> steady(blockMs.begin() + std::ptrdiff_t(warm), blockMs.end());
  std::sort(steady.begin(), steady.end());
  const double worst = steady.back(), p99 = steady[size_t(0.99 * double(steady.size() - 1))];
  const double perSourceHz = double(movingSimulations() - movingBefore) / wall / o.sources;
  std::sort(irAges.begin(), irAges.end());
  // The value at quantile q of sorted values (0 when there are none).
  auto quantile = [](const std::vector<double>& sorted, double q) {
    return sorted.empty() ? 0.0 : sorted[size_t(q * double(sorted.size() - 1))];
  };
  std::printf("runtime reflections=%s ir_seconds=%.1f shared_tail_s=%.2f head_turn_dps=%.0f trace=%s\n",
              es.ambisonicOrder > 0 ? ("ambisonic order " + std::to_string(es.ambisonicOrder)).c_str() : "binaural",
              es.maxIrSeconds, es.ambisonicOrder > 0 ? engine.settings().sharedTailSeconds : 0.0, o.turnDegreesPerSecond,
              toString(es.traceMode));
  std::printf("runtime scene=%s triangles=%zu sources=%u quality=%s block=%zu max_partition=%zu seconds=%.1f sim_threads=%u "
              "audio_cpu_pct_of_one_core=%.1f worst_block_pct_of_period=%.1f p99_block_pct=%.1f "
              "worst_block_first_second_pct=%.1f worst_block_cpu_pct=%.1f max_block_cpu_pct=%.1f "
              "sim_updates_per_s=%.1f per_source_update_hz=%.2f sim_thread_cpu_pct=%.1f game_cpu_pct=%.2f\n",
              o.geometry.c_str(), tracer->mesh().triangleCount(), o.sources, o.quality.c_str(), o.block,
              o.maxPartition, wall,
              engine.settings().threads, 100.0 * audioCpu / wall, 100.0 * worst / (period * 1000.0), 100.0 * p99 / (period * 1000.0),
              100.0 * worstFirstSecond / (period * 1000.0), 100.0 * worstCpu / (period * 1000.0),
              100.0 * maxCpu / (period * 1000.0), double(updates.load()) / wall, perSourceHz, 100.0 * simCpu / wall, 100.0 * gameCpu / wall);
  std::printf("ir_age_s median=%.3f p95=%.3f max=%.3f (per source, sampled every 100 ms after the first second)\n",
              quantile(irAges, 0.5), quantile(irAges, 0.95), quantile(irAges, 1.0));
  const double perUpdate = updates.load() > 0 ? 1.0 / double(updates.load()) : 0.0;
  if (o.oneShotsHz > 0) {
    std::sort(oneShotWaits.begin(), oneShotWaits.end());
    std::printf("one_shot_first_reflections_s median=%.3f p95=%.3f max=%.3f simulated=%zu missed=%zu (a source added "
                "by the game, until its first IR landed; group_sources=%zu)\n",
                quantile(oneShotWaits, 0.5), quantile(oneShotWaits, 0.95), quantile(oneShotWaits, 1.0),
                oneShotWaits.size(), oneShotsMissed,
                engine.settings().simulationGroupSources);
  }
  std::vector<double> steadyGame(gameMs.begin() + std::ptrdiff_t(std::min(warm, gameMs.size())), gameMs.end());
  std::sort(steadyGame.begin(), steadyGame.end());
  std::sort(addRemoveMs.begin(), addRemoveMs.end());
  std::printf("game_calls_ms_per_block median=%.3f p99=%.3f max=%.3f (wall time of the game's calls each block after "
              "the first second)\n",
              quantile(steadyGame, 0.5), quantile(steadyGame, 0.99), quantile(steadyGame, 1.0));
  if (o.oneShotsHz > 0)
    std::printf("one_shot_add_remove_ms median=%.3f p99=%.3f max=%.3f calls=%zu (each addSource and removeSource)\n",
                quantile(addRemoveMs, 0.5), quantile(addRemoveMs, 0.99), quantile(addRemoveMs, 1.0),
                addRemoveMs.size());
  std::printf("sim_ms_per_source_update trace_and_image_sources=%.1f synthesis=%.1f prepare=%.1f wall=%.1f\n",
              simTotals.traceMs * perUpdate, simTotals.synthesisMs * perUpdate, simTotals.prepareMs * perUpdate,
              simTotals.totalMs * perUpdate);
  std::printf("audio_page_faults_after_first_second=%llu audio_blocks_with_faults=%llu of_blocks=%zu "
              "audio_page_faults_in_worst_block=%llu (the audio thread's, in engine.process)\n",
              static_cast<unsigned long long>(steadyFaults), static_cast<unsigned long long>(faultingBlocks),
              blockFaults.size() - warm, static_cast<unsigned long long>(worstFaults));
  std::printf("audio_thread_priority=%s sim_threads=%u at nice +%d\n", audioPriority.c_str(),
              engine.settings().threads, es.workerNice);
  if (steal0 >= 0 && steal1 >= 0)
    std::printf("machine_steal_ms=%.0f (time the hypervisor took from this machine's CPUs during the run, all CPUs; "
                "in a guest, time stolen while a thread runs may count as that thread's CPU time)\n",
                1000.0 * (steal1 - steal0));
  std::printf("note: sim_thread_cpu_pct counts the simulation thread only; its tracing workers (sim_threads) add "
              "to it (the machine's total is in `time`)\n");
  return 0;
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<BenchRuntimeOptions>();
  CLI::App& bench = subcommandGroup(root, "bench", "Measure the speed of earshot's stages");
  CLI::App* cmd = bench.add_subcommand(
      "runtime", "Middleware load: N moving sources, reflection updates (one shared trace for all, or round robin), real-time 256-frame audio blocks");
  cmd->add_option("geometry", o->geometry, "Scene geometry (glTF)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--material-map", o->materialMap, "JSON object mapping glTF material names to acoustic materials");
  cmd->add_option("--quality", o->quality, "Simulation preset")
      ->check(CLI::IsMember({"draft", "balanced", "high", "reference"}))
      ->capture_default_str();
  cmd->add_option("--sources", o->sources, "Moving sources")->check(CLI::Range(1u, 4096u))->capture_default_str();
  cmd->add_option("--seconds", o->seconds, "Audio seconds (real time)")->check(CLI::Range(0.5, 3600.0))->capture_default_str();
  cmd->add_option("--block", o->block, "Audio block, frames")->check(CLI::Range(size_t(16), size_t(8192)))->capture_default_str();
  cmd->add_option("--update-hz", o->updateHz, "Per-source reflection update ceiling")->check(CLI::Range(0.01, 1000.0))
      ->capture_default_str();
  cmd->add_option("--max-partition", o->maxPartition, "Largest convolution partition, frames (0: automatic)")
      ->capture_default_str();
  cmd->add_option("--ambisonic-order", o->ambisonicOrder,
                  "Reflections: 0 binaural per source, 1-3 the ambisonic bus (default: the engine's)")
      ->check(CLI::Range(0, 3));
  cmd->add_option("--ir-seconds", o->irSeconds, "Longest IR convolved (default: the engine's, 3 s)")
      ->check(CLI::Range(0.1, 60.0));
  cmd->add_option("--shared-tail", o->sharedTail,
                  "Ambisonic reflections: each source's own IR up to this time, one shared tail after it "
                  "(seconds; 0: whole IRs per source; default: the engine's, 0.15, or 0 with IRs that short)")
      ->check(CLI::Range(0.0, 60.0));
  cmd->add_option("--trace", o->trace,
                  "shared: each simulation updates every source from one listener-centred trace; per-source: one "
                  "source per simulation, traced from it (the engine's default, auto, is shared for 3 sources or "
                  "more)")
      ->check(CLI::IsMember({"shared", "per-source"}))
      ->capture_default_str();
  cmd->add_option("--turn-dps", o->turnDegreesPerSecond, "Head turn, degrees per second (0: still)")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
  cmd->add_option("--group-sources", o->groupSources,
                  "Sources per group of a simulation step: each group's IRs land when it is done, and a source "
                  "added meanwhile joins the next (0: the engine's default, 8)")
      ->check(CLI::Range(size_t(0), size_t(4096)))
      ->capture_default_str();
  cmd->add_option("--one-shots-hz", o->oneShotsHz,
                  "The game also adds this many sources a second from the first second on (each released once "
                  "its first IR lands; up to 16 at once); reports how long each waited for its first reflections")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  cmd->add_option("--threads", o->threads, "Simulation threads (0: the cores less one, the engine's default)")->check(CLI::Range(0u, 256u))->capture_default_str();
  cmd->callback([o] { setExitCode(run(*o)); });
});

}  // namespace
}  // namespace earshot::cli
