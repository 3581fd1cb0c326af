// Issue 8 soak: one hour of audio through the runtime (a static source's
// exact convolution and a circling source's per-block direct sound with
// reflection updates every 5 s): the level does not drift and memory does
// not grow. Label `soak`; built and registered only with
// -DEARSHOT_SOAK_TESTS=ON (about two minutes on 2 cores).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <fstream>
#include <vector>

#include "earshot/core/math.h"
#include "runtime_fixture.h"

namespace earshot::runtime {
namespace {

long residentKb() {
  std::ifstream f("/proc/self/statm");
  long pages = 0, resident = 0;
  f >> pages >> resident;
  return resident * 4;  // 4 KB pages
}

}  // namespace

TEST(EngineSoak, OneHourOfAudioKeepsItsLevelAndItsMemory) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room room;
  EngineSettings es = test::fastSettings();
  es.simulation.rays = 500;
  es.simulation.bounces = 6;
  es.maxIrSeconds = 1.0;
  auto created = Engine::create(es, model);
  ASSERT_TRUE(created.isOk());
  Engine& e = **created;
  e.setScene(room.tracer, room.materials);
  SourceSettings still;
  still.direct = DirectMode::kInImpulseResponse;
  auto a = e.addSource(still);
  auto b = e.addSource({});
  ASSERT_TRUE(a.isOk() && b.isOk());
  ASSERT_TRUE(e.setSourcePosition(*a, {2, 2, 1.5}).isOk());
  ASSERT_TRUE(e.setListener({5, 3.5, 1.6}, {{1, 0, 0}, {0, 0, 1}}).isOk());
  // One turn of the moving source takes 3840 blocks (20.48 s); its reflections
  // are updated every 960 blocks, four times a turn at the same four places,
  // so every turn is rendered alike and any change between turns is drift.
  const double fs = test::kFs, circle = 3840.0 * 256.0 / fs;
  auto circling = [&](double t) {
    return Vec3d(5 + 2.5 * std::cos(2 * kPi * t / circle), 3.5 + 2.5 * std::sin(2 * kPi * t / circle), 1.5);
  };
  ASSERT_TRUE(e.setSourcePosition(*b, circling(0)).isOk());
  ASSERT_TRUE(e.simulate().isOk());

  const size_t block = 256;
  // EARSHOT_SOAK_SECONDS shortens the run (diagnosis); EARSHOT_SOAK_ONLY=a|b keeps one source.
  const double hour = std::getenv("EARSHOT_SOAK_SECONDS") ? std::atof(std::getenv("EARSHOT_SOAK_SECONDS")) : 3600.0;
  const std::string only = std::getenv("EARSHOT_SOAK_ONLY") ? std::getenv("EARSHOT_SOAK_ONLY") : "";
  const size_t blocks = size_t(hour * fs / block), window = 9 * 3840;  // nine turns, 184 s
  const size_t updateEvery = 960;
  std::vector<float> sineA(block), sineB(block), left(block), right(block);
  std::vector<const float*> inputs(es.maxSources, nullptr);
  if (only != "b") inputs[*a] = sineA.data();
  if (only != "a") inputs[*b] = sineB.data();
  double energy = 0, firstMinute = 0;
  std::vector<double> minutes;
  long rssAfterWarmUp = 0;
  for (size_t k = 0; k < blocks; ++k) {
    for (size_t i = 0; i < block; ++i) {
      const double n = double(k * block + i);
      sineA[i] = float(0.3 * std::sin(2 * kPi * 440.0 * n / fs));
      sineB[i] = float(0.3 * std::sin(2 * kPi * 220.0 * n / fs));
    }
    const double t = double((k + 1) * block) / fs;
    ASSERT_TRUE(e.setSourcePosition(*b, circling(t)).isOk());
    if (k % updateEvery == 0) {
      ASSERT_TRUE(e.simulate(std::vector<uint32_t>{*b}).isOk());
    }
    e.process(inputs.data(), left.data(), right.data(), block);
    for (size_t i = 0; i < block; ++i) {
      ASSERT_TRUE(std::isfinite(left[i]) && std::isfinite(right[i])) << "block " << k;
      energy += double(left[i]) * left[i] + double(right[i]) * right[i];
    }
    if ((k + 1) % window == 0) {
      minutes.push_back(energy);
      energy = 0;
    }
    if (k + 1 == window) rssAfterWarmUp = residentKb();
  }
  ASSERT_GE(minutes.size(), size_t(hour / 184.32) - 1);
  firstMinute = minutes[1];  // the second window: the first holds the onset
  for (size_t m = 2; m < minutes.size(); ++m) {
    std::printf("window %zu: %+.4f dB\n", m, energyToDb(minutes[m] / firstMinute));
    EXPECT_NEAR(energyToDb(minutes[m] / firstMinute), 0.0, 0.01) << "window " << m << " of nine turns";
  }
  const long growth = residentKb() - rssAfterWarmUp;
  std::printf("one hour: level of the last nine turns vs the second nine %+.4f dB, resident memory growth %ld KB\n",
              energyToDb(minutes.back() / firstMinute), growth);
  EXPECT_LT(growth, 4096) << "KB of resident memory gained after the warm-up";
}

}  // namespace earshot::runtime
