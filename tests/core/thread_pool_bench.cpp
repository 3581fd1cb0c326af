// The worker pool against TBB (issue 19: "TBB or the C++ standard library
// for the worker pool"): the same parallelFor shapes the engine uses, on
// earshot's ThreadPool (std::thread, one mutex and two condition variables)
// and on a tbb::task_arena running tbb::parallel_for with grain 1.
//
//   build/tests/core/thread_pool_bench --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one line)
//
// Shapes: many tiny tasks (the dispatch overhead alone) and a few dozen
// tasks of ~50 us (a tracer's ray batches, a batch of IRs).
#include <benchmark/benchmark.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <cmath>
#include <vector>

#include "earshot/core/thread_pool.h"

namespace {

// ~`iterations` dependent floating-point steps: work that cannot be elided.
double spin(size_t seed, int iterations) {
  double x = 1.0 + double(seed % 7) * 1e-3;
  for (int i = 0; i < iterations; ++i) x = x * 1.0000001 + 1e-9;
  return x;
}

void poolFor(benchmark::State& state) {
  const size_t tasks = size_t(state.range(0));
  const int work = int(state.range(1));
  earshot::ThreadPool pool(2);
  std::vector<double> out(tasks);
  for (auto _ : state) {
    pool.parallelFor(tasks, [&](size_t i, unsigned) { out[i] = spin(i, work); });
    benchmark::DoNotOptimize(out.data());
  }
}

void tbbFor(benchmark::State& state) {
  const size_t tasks = size_t(state.range(0));
  const int work = int(state.range(1));
  tbb::task_arena arena(2);
  std::vector<double> out(tasks);
  for (auto _ : state) {
    arena.execute([&] {
      tbb::parallel_for(
          tbb::blocked_range<size_t>(0, tasks, 1),
          [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i != r.end(); ++i) out[i] = spin(i, work);
          },
          tbb::simple_partitioner());
    });
    benchmark::DoNotOptimize(out.data());
  }
}

// {tasks, spin iterations}: 1000 tasks of ~0; 64 tasks of ~50 us.
BENCHMARK(poolFor)->Args({1000, 0})->Args({64, 50000})->Unit(benchmark::kMicrosecond)->UseRealTime();
BENCHMARK(tbbFor)->Args({1000, 0})->Args({64, 50000})->Unit(benchmark::kMicrosecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
