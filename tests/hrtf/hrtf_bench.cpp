// HRTF lookup cost (Google Benchmark). Run: build/tests/hrtf/hrtf_bench
// Reports nanoseconds per lookup for the shipped KU100 set (2354 directions)
// and MIT KEMAR (710 directions, elevation hole), barycentric and nearest,
// plus the load time.
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <vector>

#include "earshot/hrtf/hrtf_set.h"

namespace {

using earshot::Vec3f;
using namespace earshot::hrtf;

const std::string kKu100 = std::string(EARSHOT_SOURCE_DIR) + "/hrtf/FHK_HRIR_L2354.sofa";
const std::string kKemar = std::string(EARSHOT_TEST_DATA_DIR) + "/hrtf/MIT_KEMAR_normal_pinna.sofa";

std::vector<Vec3f> directions() {
  std::vector<Vec3f> d;
  for (int i = 0; i < 4096; ++i) {
    double y = 1.0 - 2.0 * (i + 0.5) / 4096.0, r = std::sqrt(1.0 - y * y), a = 2.399963 * i;
    d.emplace_back(float(r * std::cos(a)), float(y), float(r * std::sin(a)));
  }
  return d;
}

void lookupBench(benchmark::State& state, const std::string& path, InterpolationMode mode) {
  auto set = HrtfSet::load(path, 48000.0, mode);
  if (!set.isOk()) {
    state.SkipWithError(set.status().message().c_str());
    return;
  }
  auto dirs = directions();
  auto pair = std::make_unique<HrirPair>();
  std::size_t i = 0;
  for (auto _ : state) {
    set.value()->lookup(dirs[i++ & 4095], *pair);
    benchmark::DoNotOptimize(pair->left[0]);
  }
  state.counters["taps"] = double(set.value()->hrirLength());
}

void weightsBench(benchmark::State& state, const std::string& path) {
  auto set = HrtfSet::load(path, 48000.0);
  if (!set.isOk()) {
    state.SkipWithError(set.status().message().c_str());
    return;
  }
  auto dirs = directions();
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(set.value()->weights(dirs[i++ & 4095]));
}

void loadBench(benchmark::State& state, const std::string& path) {
  for (auto _ : state) {
    auto set = HrtfSet::load(path, 48000.0);
    benchmark::DoNotOptimize(set.isOk());
  }
}

BENCHMARK_CAPTURE(lookupBench, ku100_barycentric, kKu100, InterpolationMode::kBarycentric);
BENCHMARK_CAPTURE(lookupBench, ku100_nearest, kKu100, InterpolationMode::kNearest);
BENCHMARK_CAPTURE(lookupBench, kemar_barycentric, kKemar, InterpolationMode::kBarycentric);
BENCHMARK_CAPTURE(weightsBench, ku100_weights_only, kKu100);
BENCHMARK_CAPTURE(loadBench, ku100_load_48k, kKu100)->Unit(benchmark::kMillisecond)->Iterations(2);

}  // namespace

BENCHMARK_MAIN();
