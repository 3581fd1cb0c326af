// Issue 6: no heap allocation, no lock and (after the first second) no page
// fault on the audio path during a 10 s run with IR updates at 10 Hz and
// scene edits, while a game thread moves the sources and the listener and a
// simulation thread traces. Also built as the `tsan` entry (ThreadSanitizer
// sees the same three threads).
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <atomic>
#include <mutex>
#include <cmath>
#include <thread>
#include <vector>

#include "../support/alloc_hook.h"
#include "earshot/core/math.h"
#include "runtime_fixture.h"

namespace earshot::runtime {

using earshot::test::threadPageFaults;

// The hooks see what they must catch (so the test below could fail).
TEST(EngineRealtime, HooksSeeAllocationsAndLocks) {
  {
    // A fresh anonymous mapping's pages fault when first touched (16 pages:
    // under a transparent huge page's 2 MB).
    const size_t page = size_t(sysconf(_SC_PAGESIZE)), bytes = 16 * page;
    void* mem = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    ASSERT_NE(mem, MAP_FAILED);
    const long f0 = threadPageFaults();
    for (size_t i = 0; i < bytes; i += page) static_cast<volatile char*>(mem)[i] = 1;
    const long faults = threadPageFaults() - f0;
    munmap(mem, bytes);
    EXPECT_GE(faults, 1);
  }
  std::mutex m;
  long allocations = 0, locks = 0;
  {
    earshot::test::AllocationCounter counter;
    auto* p = new std::vector<int>(100);
    { std::lock_guard<std::mutex> lock(m); }
    delete p;
    allocations = counter.allocations();
    locks = counter.locks();
  }
  EXPECT_GE(allocations, 1);
  if (earshot::test::mallocIsHooked()) {
    EXPECT_GE(locks, 1);
  }
}

// Ten seconds of audio with reflections of `ambisonicOrder` (0: binaural per
// source; 1-3: the ambisonic bus, rotated and decoded on the audio thread).
void tenSecondsWithUpdatesAndSceneEdits(int ambisonicOrder) {
  auto model = test::ku100();
  ASSERT_TRUE(model);
  test::Room roomA(0.1f), roomB(0.4f);
  EngineSettings es = test::fastSettings();
  es.ambisonicOrder = ambisonicOrder;
  es.simulation.rays = 1000;
  es.simulation.bounces = 6;
  es.maxIrSeconds = 1.0;
  auto created = Engine::create(es, model);
  ASSERT_TRUE(created.isOk()) << created.status().message();
  Engine& engine = **created;
  engine.setScene(roomA.tracer, roomA.materials);
  std::vector<uint32_t> ids;
  for (int i = 0; i < 3; ++i) {
    auto id = engine.addSource({});
    ASSERT_TRUE(id.isOk());
    ids.push_back(*id);
    ASSERT_TRUE(engine.setSourcePosition(*id, {2.0 + 2 * i, 2.0, 1.5}).isOk());
  }
  ASSERT_TRUE(engine.setListener({5, 3.5, 1.6}, {{1, 0, 0}, {0, 0, 1}}).isOk());
  ASSERT_TRUE(engine.simulate().isOk());

  const double fs = test::kFs;
  const size_t block = 256, blocks = size_t(10.0 * fs / block);
  const size_t blocksPerUpdate = size_t(0.1 * fs / block);  // 10 Hz
  std::atomic<size_t> audioBlock{0}, updatesDone{0};
  std::atomic<bool> stop{false}, simFailed{false};

  // Simulation thread: one update per 0.1 s of audio, with a scene edit every fifth.
  std::thread sim([&] {
    size_t done = 0;
    while (!stop.load()) {
      const size_t wanted = audioBlock.load() / blocksPerUpdate;
      if (done >= wanted) {
        std::this_thread::yield();
        continue;
      }
      if (done % 5 == 4) {
        if (done % 10 == 9)
          engine.setScene(roomA.tracer, roomA.materials);
        else
          engine.setScene(roomB.tracer, roomB.materials);
      }
      if (!engine.simulate(2).isOk()) simFailed = true;
      updatesDone.store(++done);
    }
  });
  // Game thread: moves the sources and turns the listener continuously,
  // and plays one-shots of 0.15 s in the fourth slot: each a new source,
  // released once played; the next one 0.4 s later (the slot still rings:
  // its IR fades out, then its convolution starts anew) or 1.3 s later (it
  // has rung out: dropped at once).
  const std::vector<double> shots = {1.0, 1.55, 3.0, 3.55, 5.0, 5.55, 7.0, 7.55};
  std::atomic<int> oneShot{-1};
  std::atomic<size_t> shotsPlayed{0};
  std::thread game([&] {
    size_t next = 0;
    uint32_t shot = 0;
    bool playing = false;
    while (!stop.load()) {
      const double t = double(audioBlock.load()) * block / fs;
      for (size_t i = 0; i < ids.size(); ++i)
        (void)engine.setSourcePosition(ids[i], {5 + 3 * std::cos(t + i), 3.5 + 2 * std::sin(t + i), 1.5});
      (void)engine.setListener({5, 3.5, 1.6}, {{std::cos(0.5 * t), std::sin(0.5 * t), 0}, {0, 0, 1}});
      if (!playing && next < shots.size() && t >= shots[next]) {
        auto id = engine.addSource({});
        if (id.isOk()) {
          shot = *id;
          (void)engine.setSourcePosition(shot, {3.0 + 0.5 * double(next), 5.0, 1.2});
          oneShot.store(int(shot));
          playing = true;
        }
      } else if (playing && t >= shots[next] + 0.15) {
        oneShot.store(-1);
        (void)engine.removeSource(shot);
        playing = false;
        shotsPlayed.store(++next);
      }
      std::this_thread::yield();
    }
  });

  std::vector<std::vector<float>> in(ids.size(), std::vector<float>(block));
  for (size_t s = 0; s < ids.size(); ++s)
    for (size_t k = 0; k < block; ++k) in[s][k] = float(std::sin(0.05 * double(k * (s + 1))));
  std::vector<const float*> inputs(es.maxSources, nullptr);
  for (size_t s = 0; s < ids.size(); ++s) inputs[ids[s]] = in[s].data();
  std::vector<float> left(block), right(block), shotIn(block);
  for (size_t k = 0; k < block; ++k) shotIn[k] = float(0.5 * std::sin(0.3 * double(k)));
  int fedShot = -1;  // the slot given the one-shot's input
  double sumSquares = 0;
  long allocations = 0, releases = 0, locks = 0, steadyFaults = 0, firstSecondFaults = 0;
  const size_t warmBlocks = size_t(fs / block);
  {
    earshot::test::AllocationCounter counter;
    for (size_t b = 0; b < blocks; ++b) {
      const int playing = oneShot.load();
      if (playing != fedShot) {
        if (fedShot >= 0) inputs[size_t(fedShot)] = nullptr;
        if (playing >= 0) inputs[size_t(playing)] = shotIn.data();
        fedShot = playing;
      }
      const long f0 = threadPageFaults();
      engine.process(inputs.data(), left.data(), right.data(), block);
      (b < warmBlocks ? firstSecondFaults : steadyFaults) += threadPageFaults() - f0;
      for (size_t k = 0; k < block; ++k) sumSquares += double(left[k]) * left[k] + double(right[k]) * right[k];
      audioBlock.store(b + 1);
      // Pace the run so that the 10 Hz updates really land during it (the
      // wait is the test's, outside process(); it spins without allocating).
      while (updatesDone.load() + 2 < (b + 1) / blocksPerUpdate) std::this_thread::yield();
    }
    allocations = counter.allocations();
    releases = counter.releases();
    locks = counter.locks();
  }
  stop = true;
  sim.join();
  game.join();
  EXPECT_FALSE(simFailed.load());
  EXPECT_GE(updatesDone.load(), 90u) << "IR updates at 10 Hz over 10 s";
  EXPECT_EQ(shotsPlayed.load(), shots.size()) << "one-shots played";
  EXPECT_GT(sumSquares, 0.0) << "the run produced sound";
  EXPECT_TRUE(std::isfinite(sumSquares));
  EXPECT_EQ(allocations, 0) << "heap allocation on the audio thread";
  EXPECT_EQ(releases, 0) << "heap release on the audio thread";
  if (earshot::test::mallocIsHooked()) {
    EXPECT_EQ(locks, 0) << "lock taken on the audio thread";
    // After the first second (whose first touches of the engine's buffers
    // may fault), no page fault: the IRs, scenes and buffers the audio
    // thread reads were touched by the threads that made them. Not asserted
    // under a sanitizer, whose allocator and shadow memory are its own.
    EXPECT_EQ(steadyFaults, 0) << "page faults on the audio thread after the first second (" << firstSecondFaults
                               << " in it)";
  }
}

TEST(EngineRealtime, TenSecondsWithUpdatesAndSceneEditsNeverAllocateOrLockOnTheAudioThread) {
  tenSecondsWithUpdatesAndSceneEdits(0);
}

// Issue 15: the same with the ambisonic bus (the head turns all the while).
TEST(EngineRealtime, AmbisonicBusNeverAllocatesOrLocksOnTheAudioThread) { tenSecondsWithUpdatesAndSceneEdits(1); }

}  // namespace earshot::runtime
