// earshot bench convolve: speed of the streaming convolver (real-time factor
// and per-block cost) for a synthetic decaying-noise IR.
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "command.h"
#include "earshot/core/random.h"
#include "earshot/dsp/convolver.h"

namespace earshot::cli {
namespace {

struct BenchOptions {
  double irSeconds = 2.0;
  size_t block = 256;
  size_t channels = 2;
  double seconds = 20.0;
  size_t sources = 1;
  double rate = 48000.0;
  size_t maxPartition = 0;
  bool silenceCheck = false;
  bool compact = false;
  size_t swapEvery = 0;
};

double threadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

std::vector<float> decayingNoise(size_t frames, uint64_t seed, double rate) {
  Pcg32 rng(seed, 3);
  std::vector<float> v(frames);
  const double t60 = std::max(0.05, static_cast<double>(frames) / rate);  // -60 dB at the end
  for (size_t i = 0; i < frames; ++i)
    v[i] = static_cast<float>((2.0 * rng.uniformDouble() - 1.0) * std::pow(10.0, -3.0 * i / (t60 * rate)) * 0.1);
  return v;
}

int run(const BenchOptions& o) {
  ConvolverSettings s;
  s.latencyFrames = o.block;
  s.maxIrFrames = std::max<size_t>(1, static_cast<size_t>(std::llround(o.irSeconds * o.rate)));
  s.channels = o.channels;
  s.maxPartitionFrames = o.maxPartition;
  s.phase = 0;
  s.compactSpectra = o.compact;
  auto mixer = ConvolutionMixer::create(s, o.sources);
  if (!check(mixer.status())) return 2;
  ConvolutionMixer& m = **mixer;
  // Two IRs per source (the second only with --swap-every): A, then B
  // and A in turn.
  std::vector<std::shared_ptr<const PreparedIr>> irs[2];
  for (int v = 0; v < (o.swapEvery > 0 ? 2 : 1); ++v)
    for (size_t src = 0; src < o.sources; ++src) {
      std::vector<std::vector<float>> ir;
      for (size_t c = 0; c < o.channels; ++c)
        ir.push_back(decayingNoise(s.maxIrFrames, 100 * src + c + 1000000 * uint64_t(v), o.rate));
      auto p = PreparedIr::create(ir, m.layout());
      if (!check(p.status())) return 2;
      irs[v].push_back(std::move(*p));
    }
  for (size_t src = 0; src < o.sources; ++src)
    if (!check(m.setIr(src, irs[0][src]))) return 2;
  std::vector<std::vector<float>> in(o.sources);
  for (size_t src = 0; src < o.sources; ++src) in[src] = decayingNoise(o.block * 64, 7 + src, 1e12);
  std::vector<const float*> ins(o.sources);
  std::vector<std::vector<float>> out(o.channels, std::vector<float>(o.block));
  std::vector<float*> outs(o.channels);
  for (size_t c = 0; c < o.channels; ++c) outs[c] = out[c].data();

  const size_t warmBlocks = static_cast<size_t>(0.5 * o.rate / o.block) + 1;
  const size_t blocks = std::max<size_t>(1, static_cast<size_t>(o.seconds * o.rate / o.block));
  size_t b = 0;
  auto feed = [&] {
    for (size_t src = 0; src < o.sources; ++src) ins[src] = in[src].data() + (b % 64) * o.block;
    ++b;
  };
  for (size_t i = 0; i < warmBlocks; ++i) {
    feed();
    m.process(ins.data(), outs.data(), o.block);
  }
  // Pass 1: throughput, no per-block timers.
  const double cpu0 = threadCpuSeconds();
  for (size_t i = 0; i < blocks; ++i) {
    feed();
    m.process(ins.data(), outs.data(), o.block);
  }
  const double cpu = threadCpuSeconds() - cpu0;
  // Pass 2: per-block cost as this thread's CPU time (two clock reads per
  // block), so that preemption on a shared machine does not count.
  std::vector<double> blockSeconds;
  blockSeconds.reserve(blocks);
  for (size_t i = 0; i < blocks; ++i) {
    feed();
    const double t0 = threadCpuSeconds();
    m.process(ins.data(), outs.data(), o.block);
    blockSeconds.push_back(threadCpuSeconds() - t0);
  }
  const double audio = static_cast<double>(blocks * o.block) / o.rate;
  const double period = static_cast<double>(o.block) / o.rate;
  std::sort(blockSeconds.begin(), blockSeconds.end());
  const double p99 = blockSeconds[std::min(blockSeconds.size() - 1, blockSeconds.size() * 99 / 100)];
  const double worst = blockSeconds.back();
  std::printf("convolve L=%g B=%zu sources=%zu rt_factor=%.1f p99_block_pct=%.3f max_block_pct=%.3f spectra=%s\n",
              o.irSeconds, o.block, o.sources, audio / std::max(cpu, 1e-9), 100.0 * p99 / period,
              100.0 * worst / period, o.compact ? "half" : "float");
  if (o.swapEvery > 0) {
    // Every source's IR changed every swapEvery blocks (all at once, as
    // when a simulation posts every source): the blocks that crossfade
    // against the others. The IRs are posted between the timed calls.
    std::vector<double> all;
    size_t v = 0;
    for (size_t i = 0; i < blocks; ++i) {
      if (i % o.swapEvery == 0) {
        v ^= 1;
        for (size_t src = 0; src < o.sources; ++src)
          if (!check(m.setIr(src, irs[v][src]))) return 2;
      }
      feed();
      const double t0 = threadCpuSeconds();
      m.process(ins.data(), outs.data(), o.block);
      all.push_back(threadCpuSeconds() - t0);
    }
    std::vector<double> sorted = all;
    std::sort(sorted.begin(), sorted.end());
    const double median = sorted[sorted.size() / 2];
    std::printf("convolve-swap L=%g B=%zu sources=%zu every=%zu max_block_pct=%.3f p99_block_pct=%.3f "
                "median_block_pct=%.3f (no swaps: max %.3f p99 %.3f)\n",
                o.irSeconds, o.block, o.sources, o.swapEvery, 100.0 * sorted.back() / period,
                100.0 * sorted[std::min(sorted.size() - 1, sorted.size() * 99 / 100)] / period, 100.0 * median / period,
                100.0 * worst / period, 100.0 * p99 / period);
  }
  if (o.silenceCheck) {
    // Full-scale noise, then as long again of silence: with denormals
    // flushed the silent blocks must not cost more than the noisy ones.
    Pcg32 rng(99, 5);
    std::vector<std::vector<float>> loud(o.sources, std::vector<float>(o.block));
    std::vector<float> zeros(o.block, 0.0f);
    double noiseCpu = 0, silenceCpu = 0;
    for (int pass = 0; pass < 2; ++pass) {
      for (size_t i = 0; i < blocks; ++i) {
        for (size_t src = 0; src < o.sources; ++src) {
          if (pass == 0) {
            for (float& v : loud[src]) v = 2.0f * rng.uniform() - 1.0f;
            ins[src] = loud[src].data();
          } else {
            ins[src] = zeros.data();
          }
        }
        const double t0 = threadCpuSeconds();
        m.process(ins.data(), outs.data(), o.block);
        (pass == 0 ? noiseCpu : silenceCpu) += threadCpuSeconds() - t0;
      }
    }
    std::printf("convolve-silence L=%g B=%zu noise_us_per_block=%.2f silence_us_per_block=%.2f ratio=%.3f\n",
                o.irSeconds, o.block, 1e6 * noiseCpu / blocks, 1e6 * silenceCpu / blocks, silenceCpu / noiseCpu);
  }
  return 0;
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<BenchOptions>();
  CLI::App& bench = subcommandGroup(root, "bench", "Benchmarks (tracing, synthesis, convolution speed)");
  CLI::App* cmd = bench.add_subcommand(
      "convolve",
      "Streaming convolution speed on one thread: rt_factor = audio seconds per CPU second, "
      "p99/max = per-block time as % of the block period");
  cmd->add_option("--ir-seconds", o->irSeconds, "IR length in seconds")
      ->check(CLI::Range(0.0001, 60.0))
      ->capture_default_str();
  cmd->add_option("--block", o->block, "Host block = latency in frames (even, prime factors 2, 3, 5)")
      ->check(CLI::Range(8u, 65536u))
      ->capture_default_str();
  cmd->add_option("--channels", o->channels, "IR/output channels (2 = binaural)")
      ->check(CLI::Range(1u, 64u))
      ->capture_default_str();
  cmd->add_option("--seconds", o->seconds, "Audio seconds to process (after 0.5 s warm-up)")
      ->check(CLI::Range(0.01, 3600.0))
      ->capture_default_str();
  cmd->add_option("--sources", o->sources, "Sources mixed into one output, each with its own IR")
      ->check(CLI::Range(1u, 4096u))
      ->capture_default_str();
  cmd->add_option("--max-partition", o->maxPartition, "Largest partition in frames (0 = automatic)")
      ->capture_default_str();
  cmd->add_flag("--compact", o->compact,
                "IR spectra as 16-bit floats (what the runtime's ambisonic bus uses): half the memory traffic");
  cmd->add_flag("--silence-check", o->silenceCheck,
                "Also time --seconds of full-scale noise then as much silence (denormal check)");
  cmd->add_option("--swap-every", o->swapEvery,
                  "Also time --seconds in which every source's IR changes every this many blocks, all at once "
                  "(the crossfades' cost; 0: not)")
      ->check(CLI::Range(size_t{0}, size_t{1} << 30));
  cmd->add_option("--rate", o->rate, "Sample rate in Hz")->check(CLI::Range(8000.0, 384000.0))->capture_default_str();
  cmd->callback([o] { setExitCode(run(*o)); });
});

}  // namespace
}  // namespace earshot::cli
