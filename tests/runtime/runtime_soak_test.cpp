// Issue 8 soak: one hour of audio through the runtime (a static source's
// exact convolution and a circling source's per-block direct sound with
// reflection updates every 5 s): the level does not drift and memory does
// not grow. Label `soak`; built and registered only with
// -DEARSHOT_SOAK_TESTS=ON (about two minutes on 2 cores).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
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
  const double fs = test::kFs, circle = 20.0;  // seconds per turn of the moving source
  auto circling = [&](double t) {
    return Vec3d(5 + 2.5 * std::cos(2 * kPi * t / circle), 3.5 + 2.5 * std::sin(2 * kPi * t / circle), 1.5);
  };
  ASSERT_TRUE(e.setSourcePosition(*b, circling(0)).isOk());
  ASSERT_TRUE(e.simulate().isOk());

  const size_t block = 256;
  const double hour = 3600.0;
  const size_t blocks = size_t(hour * fs / block), perMinute = size_t(60.0 * fs / block);
  const size_t updateEvery = size_t(5.0 * fs / block);
  std::vector<float> sineA(block), sineB(block), left(block), right(block);
  std::vector<const float*> inputs(es.maxSources, nullptr);
  inputs[*a] = sineA.data();
  inputs[*b] = sineB.data();
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
    if (k % updateEvery == 0) ASSERT_TRUE(e.simulate(std::vector<uint32_t>{*b}).isOk());
    e.process(inputs.data(), left.data(), right.data(), block);
    for (size_t i = 0; i < block; ++i) {
      ASSERT_TRUE(std::isfinite(left[i]) && std::isfinite(right[i])) << "block " << k;
      energy += double(left[i]) * left[i] + double(right[i]) * right[i];
    }
    if ((k + 1) % (3 * perMinute) == 0) {  // 3 minutes = 9 turns of the moving source
      minutes.push_back(energy);
      energy = 0;
    }
    if (k + 1 == 3 * perMinute) rssAfterWarmUp = residentKb();
  }
  ASSERT_GE(minutes.size(), 19u);
  firstMinute = minutes[1];  // the second window: the first holds the onset
  for (size_t m = 2; m < minutes.size(); ++m)
    EXPECT_NEAR(energyToDb(minutes[m] / firstMinute), 0.0, 0.01) << "window " << m << " of 3 minutes";
  const long growth = residentKb() - rssAfterWarmUp;
  std::printf("one hour: level of the last 3 minutes vs the second %+.4f dB, resident memory growth %ld KB\n",
              energyToDb(minutes.back() / firstMinute), growth);
  EXPECT_LT(growth, 4096) << "KB of resident memory gained after the warm-up";
}

}  // namespace earshot::runtime
