// earshot_process through the C API is real-time safe: no heap allocation, no
// lock and (after the first second) no page fault on the audio thread while
// the game thread moves the source, the listener and a door (with commits)
// and the built-in simulation thread updates the IRs. Links the allocation
// hook (a binary of its own).
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <thread>
#include <vector>

#include "../support/alloc_hook.h"
#include "capi_fixture.h"

namespace earshot::capi::test {

TEST(CApiRealtime, ProcessNeverAllocatesOrLocksWhileTheGameEditsAndTheThreadSimulates) {
  earshot_context_settings s = fastSettings();
  s.rays = 500;
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&s, &c), EARSHOT_OK);
  earshot_scene* scene = nullptr;
  ASSERT_EQ(earshot_scene_create(c, nullptr, &scene), EARSHOT_OK);
  earshot_mesh* walls = makeMesh(c, box(0, 0, 0, 6, 5, 3), "plaster", EARSHOT_MESH_STATIC, "walls");
  earshot_mesh* door = makeMesh(c, box(0, 0, 0, 0.05f, 1, 2), "door_wood", EARSHOT_MESH_MOVABLE, "door");
  ASSERT_EQ(earshot_scene_add_mesh(scene, walls), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_add_mesh(scene, door), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
  ASSERT_EQ(earshot_context_set_scene(c, scene), EARSHOT_OK);
  earshot_source *a = nullptr, *b = nullptr;
  ASSERT_EQ(earshot_source_create(c, nullptr, &a), EARSHOT_OK);
  ASSERT_EQ(earshot_source_create(c, nullptr, &b), EARSHOT_OK);
  ASSERT_EQ(earshot_source_set_position(a, {1, 1, 1.5f}), EARSHOT_OK);
  ASSERT_EQ(earshot_source_set_position(b, {5, 4, 1.5f}), EARSHOT_OK);
  ASSERT_EQ(earshot_context_set_listener(c, {3, 2.5f, 1.5f}, {1, 0, 0}, {0, 0, 1}), EARSHOT_OK);
  // Both sources simulated before the audio starts, so they are heard
  // however slowly the simulation thread runs on a loaded machine.
  ASSERT_EQ(earshot_simulate(c, 0), EARSHOT_OK);
  ASSERT_EQ(earshot_context_start_simulation(c, 10.0, 1), EARSHOT_OK);

  std::atomic<bool> done{false};
  std::atomic<int> gameErrors{0};
  std::thread game([&] {
    for (int frame = 0; !done.load(); ++frame) {
      const float t = float(frame) / 90.0f;
      const float angle = 0.5f * std::sin(t);
      if (earshot_source_set_position(a, {3 + 2 * std::cos(t), 2.5f + 2 * std::sin(t), 1.5f}) != EARSHOT_OK ||
          earshot_context_set_listener(c, {3, 2.5f, 1.5f}, {std::cos(angle), std::sin(angle), 0}, {0, 0, 1}) !=
              EARSHOT_OK)
        gameErrors++;
      const float m[12] = {std::cos(angle), -std::sin(angle), 0, 2, std::sin(angle), std::cos(angle), 0, 2, 0, 0, 1, 0};
      if (earshot_mesh_set_transform(door, m) != EARSHOT_OK || earshot_scene_commit(scene) != EARSHOT_OK) gameErrors++;
      std::this_thread::sleep_for(std::chrono::milliseconds(11));
    }
  });

  // 2 s of audio in blocks of 256 and of odd sizes, from this (the audio) thread.
  std::vector<float> dryA(1024, 0.0f), dryB(1024, 0.0f), left(1024), right(1024);
  for (size_t i = 0; i < dryA.size(); i += 32) dryA[i] = 1.0f, dryB[(i + 16) % dryB.size()] = 0.5f;
  const float* inputs[4] = {nullptr, nullptr, nullptr, nullptr};
  uint32_t ia = 0, ib = 0;
  ASSERT_EQ(earshot_source_get_index(a, &ia), EARSHOT_OK);
  ASSERT_EQ(earshot_source_get_index(b, &ib), EARSHOT_OK);
  inputs[ia] = dryA.data();
  inputs[ib] = dryB.data();
  const size_t sizes[] = {256, 256, 100, 1024, 17};
  long allocations = 0, locks = 0, firstSecondFaults = 0, steadyFaults = 0;
  double outEnergy = 0;
  int failures = 0;
  {
    earshot::test::AllocationCounter counter;
    size_t frames = 0;
    for (int k = 0; frames < 96000; ++k) {
      const size_t n = sizes[k % 5];
      const long f0 = earshot::test::threadPageFaults();
      if (earshot_process(c, inputs, 4, left.data(), right.data(), n) != EARSHOT_OK) ++failures;
      (frames < 48000 ? firstSecondFaults : steadyFaults) += earshot::test::threadPageFaults() - f0;
      for (size_t i = 0; i < n; ++i) outEnergy += double(left[i]) * left[i] + double(right[i]) * right[i];
      frames += n;
      // Pace roughly like a device (about 4x real time) so that the other threads interleave.
      counter.pause();
      std::this_thread::sleep_for(std::chrono::microseconds(1300 * n / 256));
      counter.resume();
    }
    allocations = counter.allocations();
    locks = counter.locks();
  }
  done.store(true);
  game.join();
  ASSERT_EQ(earshot_context_stop_simulation(c), EARSHOT_OK);

  EXPECT_EQ(failures, 0);
  EXPECT_EQ(gameErrors.load(), 0);
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(locks, 0);
  if (earshot::test::mallocIsHooked()) {  // as in runtime_realtime_test.cpp
    EXPECT_EQ(steadyFaults, 0) << "page faults on the audio thread after the first second (" << firstSecondFaults
                               << " in it)";
  }
  EXPECT_TRUE(std::isfinite(outEnergy));
  EXPECT_GT(outEnergy, 0.0);

  earshot_source_release(a);
  earshot_source_release(b);
  earshot_mesh_release(door);
  earshot_mesh_release(walls);
  earshot_scene_release(scene);
  earshot_context_release(c);
}

}  // namespace earshot::capi::test
