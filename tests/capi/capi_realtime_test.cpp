// earshot_process through the C API is real-time safe: no heap allocation, no
// lock and (after the first second) no page fault on the audio thread while
// the game thread moves the source, the listener and a door (with commits)
// and the built-in simulation thread updates the IRs. Links the allocation
// hook (a binary of its own).
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdio>
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

// Churn: the game thread creates and releases sources, edits a scene's
// meshes and swaps the context's scene while the built-in simulation thread
// runs, a tool thread computes IRs and the audio thread renders.
TEST(CApiRealtime, ProcessStaysRealTimeWhileTheGameChurnsSourcesMeshesAndScenes) {
  earshot_context_settings s = fastSettings();
  s.rays = 300;
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&s, &c), EARSHOT_OK);
  earshot_scene *roomA = nullptr, *roomB = nullptr;
  ASSERT_EQ(earshot_scene_create(c, nullptr, &roomA), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_create(c, nullptr, &roomB), EARSHOT_OK);
  earshot_mesh* wallsA = makeMesh(c, box(0, 0, 0, 6, 5, 3), "plaster", EARSHOT_MESH_STATIC, "walls");
  earshot_mesh* door = makeMesh(c, box(2, 2, 0, 2.05f, 3, 2), "door_wood", EARSHOT_MESH_MOVABLE, "door");
  earshot_mesh* wallsB = makeMesh(c, box(-2, -2, -1, 10, 8, 4), "concrete", EARSHOT_MESH_STATIC, "hall");
  ASSERT_EQ(earshot_scene_add_mesh(roomA, wallsA), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_add_mesh(roomA, door), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_add_mesh(roomB, wallsB), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_commit(roomA), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_commit(roomB), EARSHOT_OK);
  ASSERT_EQ(earshot_context_set_scene(c, roomA), EARSHOT_OK);
  earshot_source* a = nullptr;
  ASSERT_EQ(earshot_source_create(c, nullptr, &a), EARSHOT_OK);
  ASSERT_EQ(earshot_source_set_position(a, {1, 1, 1.5f}), EARSHOT_OK);
  ASSERT_EQ(earshot_context_set_listener(c, {3, 2.5f, 1.5f}, {1, 0, 0}, {0, 0, 1}), EARSHOT_OK);
  ASSERT_EQ(earshot_simulate(c, 0), EARSHOT_OK);
  ASSERT_EQ(earshot_context_start_simulation(c, 20.0, 0), EARSHOT_OK);

  std::atomic<bool> done{false};
  std::atomic<int> gameErrors{0}, toolErrors{0}, created{0}, swaps{0}, irsRead{0}, irsComputed{0};
  std::thread game([&] {
    earshot_source* churn = nullptr;
    bool doorIn = true;
    int scene = 0;
    auto ok = [&](earshot_status st) {
      if (st != EARSHOT_OK) gameErrors++;
    };
    for (int frame = 0; !done.load(); ++frame) {
      const float t = float(frame) / 90.0f;
      ok(earshot_source_set_position(a, {3 + 2 * std::cos(t), 2.5f + 2 * std::sin(t), 1.5f}));
      ok(earshot_context_set_listener(c, {3, 2.5f, 1.5f}, {std::cos(t), std::sin(t), 0}, {0, 0, 1}));
      if (frame % 5 == 0) {
        if (churn) {
          ok(earshot_source_release(churn));
          churn = nullptr;
        } else {
          earshot_source_settings ss;
          earshot_source_settings_init(&ss);
          ss.directivity_alpha = 0.5f;
          ss.occlusion = (frame % 2) ? EARSHOT_OCCLUSION_VOLUMETRIC : EARSHOT_OCCLUSION_RAY;
          ok(earshot_source_create(c, &ss, &churn));
          if (churn) {
            created++;
            ok(earshot_source_set_position(churn, {4, 1 + float(frame % 3), 1.2f}));
          }
        }
      }
      if (frame % 7 == 0) {
        ok(doorIn ? earshot_scene_remove_mesh(roomA, door) : earshot_scene_add_mesh(roomA, door));
        doorIn = !doorIn;
        ok(earshot_scene_commit(roomA));
      }
      if (frame % 13 == 0) {
        scene = (scene + 1) % 3;
        ok(earshot_context_set_scene(c, scene == 0 ? roomA : scene == 1 ? roomB : nullptr));
        swaps++;
      }
      if (frame % 9 == 0) {
        earshot_source_settings ss;
        ss.struct_size = sizeof(ss);
        ok(earshot_source_get_settings(a, &ss));
        ss.gain_db = -float(frame % 12);
        ss.occlusion = (frame % 2) ? EARSHOT_OCCLUSION_VOLUMETRIC : EARSHOT_OCCLUSION_RAY;
        ok(earshot_source_set_settings(a, &ss));
      }
      if (frame % 11 == 0) {
        earshot_ir* ir = nullptr;
        if (earshot_source_get_ir(a, &ir) == EARSHOT_OK) {
          earshot_ir_info info;
          info.struct_size = sizeof(info);
          ok(earshot_ir_get_info(ir, &info));
          std::vector<float> ch(info.frames);
          ok(earshot_ir_copy_channel(ir, 0, ch.data(), ch.size()));
          if (!allFinite(ch)) gameErrors++;
          ok(earshot_ir_release(ir));
          irsRead++;
        } else {
          gameErrors++;
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(11));
    }
    if (churn) ok(earshot_source_release(churn));
  });
  std::thread tool([&] {
    while (!done.load()) {
      earshot_ir_request r;
      earshot_ir_request_init(&r);
      r.source = {1, 1, 1};
      r.listener = {4, 3, 1.5f};
      r.receiver = EARSHOT_RECEIVER_OMNI;
      earshot_ir* ir = nullptr;
      if (earshot_context_compute_ir(c, &r, &ir) != EARSHOT_OK) {
        toolErrors++;
        continue;
      }
      earshot_ir_info info;
      info.struct_size = sizeof(info);
      if (earshot_ir_get_info(ir, &info) != EARSHOT_OK || info.frames == 0) toolErrors++;
      earshot_ir_release(ir);
      earshot_context_info ci;
      ci.struct_size = sizeof(ci);
      if (earshot_context_get_info(c, &ci) != EARSHOT_OK) toolErrors++;
      irsComputed++;
    }
  });

  std::vector<std::vector<float>> dry(4, std::vector<float>(1024, 0.0f));
  for (size_t k = 0; k < 4; ++k)
    for (size_t i = k * 8; i < 1024; i += 32) dry[k][i] = 0.5f;
  const float* inputs[4] = {dry[0].data(), dry[1].data(), dry[2].data(), dry[3].data()};
  std::vector<float> left(1024), right(1024);
  const size_t sizes[] = {256, 256, 100, 1024, 17};
  long allocations = 0, locks = 0;
  double outEnergy = 0;
  int failures = 0;
  {
    earshot::test::AllocationCounter counter;
    size_t frames = 0;
    for (int k = 0; frames < 3 * 48000; ++k) {
      const size_t n = sizes[k % 5];
      if (earshot_process(c, inputs, 4, left.data(), right.data(), n) != EARSHOT_OK) ++failures;
      for (size_t i = 0; i < n; ++i) outEnergy += double(left[i]) * left[i] + double(right[i]) * right[i];
      frames += n;
      counter.pause();
      std::this_thread::sleep_for(std::chrono::microseconds(2600 * n / 256));
      counter.resume();
    }
    allocations = counter.allocations();
    locks = counter.locks();
  }
  done.store(true);
  game.join();
  tool.join();
  ASSERT_EQ(earshot_context_stop_simulation(c), EARSHOT_OK);

  EXPECT_EQ(failures, 0);
  EXPECT_EQ(gameErrors.load(), 0) << earshot_last_error_message();
  EXPECT_EQ(toolErrors.load(), 0);
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(locks, 0);
  EXPECT_TRUE(std::isfinite(outEnergy));
  EXPECT_GT(outEnergy, 0.0);
  EXPECT_GT(created.load(), 3);
  EXPECT_GT(swaps.load(), 3);
  EXPECT_GT(irsRead.load(), 3);
  EXPECT_GT(irsComputed.load(), 0);
  std::printf("churn: %d sources created, %d scene swaps, %d IRs read, %d computed\n", created.load(), swaps.load(),
              irsRead.load(), irsComputed.load());

  earshot_source_release(a);
  earshot_mesh_release(door);
  earshot_mesh_release(wallsA);
  earshot_mesh_release(wallsB);
  earshot_scene_release(roomA);
  earshot_scene_release(roomB);
  earshot_context_release(c);
}

}  // namespace earshot::capi::test
