// Cost of the ISO 3382-1 analysis: a 2 s noise-decay IR at 48 kHz (T = 1 s),
// all 7 octave bands + broadband, and one pre-filtered band.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "earshot/analysis/room_acoustics.h"

namespace {

std::vector<float> decayIr(double seconds, double rateHz) {
  std::mt19937 rng(1);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<float> x(size_t(seconds * rateHz));
  for (size_t i = 480; i < x.size(); ++i) x[i] = float(g(rng) * std::exp(-6.9 * double(i - 480) / rateHz));
  return x;
}

void BM_AnalyzeIr2s48k(benchmark::State& state) {
  const auto ir = decayIr(2.0, 48000.0);
  for (auto _ : state) {
    auto r = earshot::analysis::analyzeIr(ir, 48000.0);
    benchmark::DoNotOptimize(r);
  }
  state.SetItemsProcessed(state.iterations() * int64_t(ir.size()));
}
BENCHMARK(BM_AnalyzeIr2s48k)->Unit(benchmark::kMillisecond);

void BM_AnalyzeBandSignal2s48k(benchmark::State& state) {
  const auto ir = decayIr(2.0, 48000.0);
  for (auto _ : state) {
    auto m = earshot::analysis::analyzeBandSignal(ir, 48000.0);
    benchmark::DoNotOptimize(m);
  }
}
BENCHMARK(BM_AnalyzeBandSignal2s48k)->Unit(benchmark::kMillisecond);

}  // namespace
