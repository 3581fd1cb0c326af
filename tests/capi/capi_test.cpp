// The C API (issue 6): invalid arguments never crash and change nothing,
// validation logging, reference counting and the allocator, scene editing,
// glTF loading, audio in any block size, the built-in simulation thread.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "capi_fixture.h"
#include "earshot/core/random.h"
#include "earshot/earshot.h"

namespace earshot::capi::test {
namespace {

const std::string kSource = EARSHOT_SOURCE_DIR;
const std::string kTwoRooms = kSource + "/samples/two_rooms/two_rooms.gltf";
const std::string kTwoRoomsMap = kSource + "/samples/two_rooms/materials_map.json";

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

earshot_context_info infoOf(earshot_context* c) {
  earshot_context_info i{};
  i.struct_size = sizeof(i);
  EXPECT_EQ(earshot_context_get_info(c, &i), EARSHOT_OK);
  return i;
}

earshot_scene_stats statsOf(earshot_scene* s) {
  earshot_scene_stats st{};
  st.struct_size = sizeof(st);
  EXPECT_EQ(earshot_scene_get_stats(s, &st), EARSHOT_OK);
  return st;
}

// An impulse every 100 ms (4800 frames at 48 kHz): each period holds the IR's first 100 ms.
constexpr size_t kPeriod = 4800;
std::vector<float> impulses(size_t frames) {
  std::vector<float> dry(frames, 0.0f);
  for (size_t i = 0; i < frames; i += kPeriod) dry[i] = 1.0f;
  return dry;
}

// Renders `frames` of impulses() for source index 0, in blocks of `block`.
void render(earshot_context* c, size_t frames, size_t block, std::vector<float>& left, std::vector<float>& right) {
  const std::vector<float> dry = impulses(frames);
  left.assign(frames, 0.0f);
  right.assign(frames, 0.0f);
  for (size_t off = 0; off < frames; off += block) {
    const size_t n = std::min(block, frames - off);
    const float* inputs[1] = {dry.data() + off};
    ASSERT_EQ(earshot_process(c, inputs, 1, left.data() + off, right.data() + off, n), EARSHOT_OK);
  }
}

/** A context in a 6 x 5 x 3 m box with a source 2 m to the listener's left, simulated once. */
struct Room {
  earshot_context* context = nullptr;
  earshot_scene* scene = nullptr;
  earshot_source* source = nullptr;
  explicit Room(uint64_t seed = 1) {
    earshot_context_settings s = fastSettings();
    s.seed = seed;
    EXPECT_EQ(earshot_context_create(&s, &context), EARSHOT_OK) << earshot_last_error_message();
    EXPECT_EQ(earshot_scene_create(context, nullptr, &scene), EARSHOT_OK);
    earshot_mesh* walls = makeMesh(context, box(0, 0, 0, 6, 5, 3), "plaster", EARSHOT_MESH_STATIC, "walls");
    EXPECT_EQ(earshot_scene_add_mesh(scene, walls), EARSHOT_OK);
    EXPECT_EQ(earshot_mesh_release(walls), EARSHOT_OK);  // the scene holds it
    EXPECT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
    EXPECT_EQ(earshot_context_set_scene(context, scene), EARSHOT_OK);
    EXPECT_EQ(earshot_context_set_listener(context, {3, 2.5f, 1.5f}, {1, 0, 0}, {0, 0, 1}), EARSHOT_OK);
    EXPECT_EQ(earshot_source_create(context, nullptr, &source), EARSHOT_OK);
    EXPECT_EQ(earshot_source_set_position(source, {3, 4.5f, 1.5f}), EARSHOT_OK);
    EXPECT_EQ(earshot_simulate(context, 0), EARSHOT_OK) << earshot_last_error_message();
  }
  ~Room() {
    if (source) earshot_source_release(source);
    if (scene) earshot_scene_release(scene);
    if (context) earshot_context_release(context);
  }
};

}  // namespace

// ---------------------------------------------------------------------------
// 1000 calls with invalid arguments: each returns EARSHOT_ERROR_INVALID_ARGUMENT
// with a message naming the function, none crashes, and afterwards the objects
// are as they were and still work.
TEST(CApiFuzz, ThousandInvalidCallsReturnErrorsAndChangeNothing) {
  earshot_context_settings good = fastSettings();
  earshot_context* ctx = nullptr;
  ASSERT_EQ(earshot_context_create(&good, &ctx), EARSHOT_OK) << earshot_last_error_message();
  earshot_scene* scene = nullptr;
  ASSERT_EQ(earshot_scene_create(ctx, nullptr, &scene), EARSHOT_OK);
  earshot_mesh* walls = makeMesh(ctx, box(0, 0, 0, 6, 5, 3), "plaster", EARSHOT_MESH_STATIC, "walls");
  earshot_mesh* door = makeMesh(ctx, box(2, 2, 0, 2.1f, 3, 2), "door_wood", EARSHOT_MESH_MOVABLE, "door");
  earshot_mesh* loose = makeMesh(ctx, box(0, 0, 0, 1, 1, 1), "concrete", EARSHOT_MESH_STATIC, "loose");
  ASSERT_EQ(earshot_scene_add_mesh(scene, walls), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_add_mesh(scene, door), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
  ASSERT_EQ(earshot_context_set_scene(ctx, scene), EARSHOT_OK);
  earshot_source* src = nullptr;
  ASSERT_EQ(earshot_source_create(ctx, nullptr, &src), EARSHOT_OK);
  ASSERT_EQ(earshot_source_set_position(src, {1, 1, 1}), EARSHOT_OK);
  ASSERT_EQ(earshot_context_set_listener(ctx, {3, 2.5f, 1.5f}, {1, 0, 0}, {0, 0, 1}), EARSHOT_OK);

  const earshot_context_info infoBefore = infoOf(ctx);
  const earshot_scene_stats statsBefore = statsOf(scene);
  float doorBefore[12];
  ASSERT_EQ(earshot_mesh_get_transform(door, doorBefore), EARSHOT_OK);

  // Handles of the wrong type (live objects, so reading their tag is safe).
  auto* ctxAsScene = reinterpret_cast<earshot_scene*>(ctx);
  auto* sceneAsCtx = reinterpret_cast<earshot_context*>(scene);
  auto* srcAsMesh = reinterpret_cast<earshot_mesh*>(src);
  auto* meshAsSource = reinterpret_cast<earshot_source*>(loose);

  Pcg32 rng(2024, 6);
  auto pick = [&](uint32_t n) { return rng.next() % n; };
  const float badFloats[] = {kNaN, kInf, -kInf};
  auto badFloat = [&] { return badFloats[pick(3)]; };
  auto badVec = [&] {
    earshot_vec3 v{1, 2, 3};
    (&v.x)[pick(3)] = badFloat();
    return v;
  };
  const size_t hugeSizes[] = {std::numeric_limits<size_t>::max(), size_t(1) << 40, (size_t(1) << 31) + 1};
  auto huge = [&] { return hugeSizes[pick(3)]; };
  auto wrongSize = [&](uint32_t right) {
    const uint32_t options[] = {0u, right - 1, right + 1, right * 2, 0xffffffffu};
    return options[pick(5)];
  };
  std::vector<float> left(512), right(512), dry(512, 0.1f);
  const float* inputs[4] = {dry.data(), nullptr, nullptr, nullptr};
  const float box12[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
  BoxData cube = box(0, 0, 0, 1, 1, 1);

  // Each generator makes one invalid call and returns its status.
  std::vector<std::function<earshot_status()>> calls = {
      // context_create: one bad setting at a time.
      [&] {
        earshot_context_settings s = good;
        earshot_context* out = reinterpret_cast<earshot_context*>(&s);  // must be reset to NULL
        switch (pick(16)) {
          case 0: s.struct_size = wrongSize(sizeof(s)); break;
          case 1: s.sample_rate_hz = pick(2) ? double(badFloat()) : 1e9; break;
          case 2: s.block_frames = pick(2) ? 0u : 1u << 20; break;
          case 3: s.max_sources = pick(2) ? 0u : 5000u; break;
          case 4: s.max_ir_seconds = pick(2) ? double(badFloat()) : 61.0; break;
          case 5: s.rays = 0; break;
          case 6: s.bounces = 200000; break;
          case 7: s.image_source_order = 5 + pick(100); break;
          case 8: s.threads = 257 + pick(1000); break;
          case 9: s.max_distance_meters = pick(2) ? double(badFloat()) : 0.0; break;
          case 10: storeRaw(s.log_level, 4 + pick(10)); break;
          case 11: s.allocate = [](void*, size_t, size_t) -> void* { return nullptr; }; break;
          case 12: s.flags = 1u << (1 + pick(31)); break;
          case 13: return earshot_context_create(nullptr, &out);
          case 14: return earshot_context_create(&s, nullptr);
          default: s.sample_rate_hz = -48000.0; break;
        }
        const earshot_status st = earshot_context_create(&s, &out);
        EXPECT_EQ(out, nullptr);
        return st;
      },
      [&] {
        switch (pick(6)) {
          case 0: return earshot_context_set_listener(nullptr, {0, 0, 0}, {1, 0, 0}, {0, 0, 1});
          case 1: return earshot_context_set_listener(sceneAsCtx, {0, 0, 0}, {1, 0, 0}, {0, 0, 1});
          case 2: return earshot_context_set_listener(ctx, badVec(), {1, 0, 0}, {0, 0, 1});
          case 3: return earshot_context_set_listener(ctx, {0, 0, 0}, {0, 0, 0}, {0, 0, 1});
          case 4: return earshot_context_set_listener(ctx, {0, 0, 0}, {0, 0, 2}, {0, 0, 1});  // parallel
          default: return earshot_context_set_listener(ctx, {0, 0, 0}, {1, 0, 0}, badVec());
        }
      },
      [&] { return pick(2) ? earshot_context_set_scene(nullptr, scene) : earshot_context_set_scene(ctx, ctxAsScene); },
      [&] { return pick(2) ? earshot_simulate(nullptr, 0) : earshot_simulate(sceneAsCtx, 1); },
      [&] {
        // 1e-40 Hz: a period past the clock's range (found by fuzz_capi).
        const double rates[] = {double(kNaN), 0.0, -10.0, 1e6, double(kInf), 1e-40, 0.000999};
        return pick(4) ? earshot_context_start_simulation(ctx, rates[pick(7)], 0)
                       : earshot_context_start_simulation(nullptr, 10.0, 0);
      },
      [&] { return earshot_context_stop_simulation(pick(2) ? nullptr : sceneAsCtx); },
      [&] {
        switch (pick(8)) {
          case 0: return earshot_process(nullptr, inputs, 1, left.data(), right.data(), 256);
          case 1: return earshot_process(ctx, inputs, 5 + pick(1000), left.data(), right.data(), 256);
          case 2: return earshot_process(ctx, nullptr, 1, left.data(), right.data(), 256);
          case 3: return earshot_process(ctx, inputs, 1, left.data(), right.data(), huge());
          case 4: return earshot_process(ctx, inputs, 1, nullptr, right.data(), 256);
          case 5: return earshot_process(ctx, inputs, 1, left.data(), nullptr, 256);
          case 6: return earshot_process(ctx, inputs, 1, left.data(), left.data(), 256);
          default: return earshot_process(ctx, inputs, 1, left.data(), left.data() + 100, 256);  // overlap
        }
      },
      [&] {
        earshot_context_info i{};
        i.struct_size = wrongSize(sizeof(i));
        switch (pick(3)) {
          case 0: return earshot_context_get_info(ctx, nullptr);
          case 1: return earshot_context_get_info(sceneAsCtx, &i);
          default: return earshot_context_get_info(ctx, &i);
        }
      },
      [&] {
        earshot_scene_settings s;
        earshot_scene_settings_init(&s);
        s.struct_size = wrongSize(sizeof(s));
        earshot_scene* out = nullptr;
        switch (pick(3)) {
          case 0: return earshot_scene_create(nullptr, nullptr, &out);
          case 1: return earshot_scene_create(ctx, nullptr, nullptr);
          default: return earshot_scene_create(ctx, &s, &out);
        }
      },
      [&] {
        earshot_material m{};
        m.struct_size = sizeof(m);
        m.name = "fuzz";
        for (int b = 0; b < EARSHOT_BAND_COUNT; ++b) m.absorption[b] = 0.5f, m.scattering[b] = 0.5f;
        const int band = int(pick(EARSHOT_BAND_COUNT));
        switch (pick(8)) {
          case 0: return earshot_scene_add_material(scene, nullptr);
          case 1: m.struct_size = wrongSize(sizeof(m)); break;
          case 2: m.name = pick(2) ? nullptr : ""; break;
          case 3: m.absorption[band] = pick(2) ? badFloat() : 1.5f; break;
          case 4: m.scattering[band] = pick(2) ? badFloat() : -0.1f; break;
          case 5: m.transmission[band] = 0.6f; break;  // above absorption
          case 6: return earshot_scene_add_material(nullptr, &m);
          default: m.transmission[band] = badFloat(); break;
        }
        return earshot_scene_add_material(scene, &m);
      },
      [&] {
        switch (pick(4)) {
          case 0: return earshot_scene_add_mesh(nullptr, loose);
          case 1: return earshot_scene_add_mesh(scene, nullptr);
          case 2: return earshot_scene_add_mesh(scene, srcAsMesh);
          default: return earshot_scene_add_mesh(ctxAsScene, loose);
        }
      },
      [&] {
        return pick(2) ? earshot_scene_remove_mesh(nullptr, door) : earshot_scene_remove_mesh(scene, srcAsMesh);
      },
      [&] { return earshot_scene_commit(pick(2) ? nullptr : ctxAsScene); },
      [&] {
        earshot_gltf_settings g;
        earshot_gltf_settings_init(&g);
        g.path = kTwoRooms.c_str();
        const char* names[] = {"door", nullptr};
        switch (pick(6)) {
          case 0: return earshot_scene_load_gltf(scene, nullptr);
          case 1: g.struct_size = wrongSize(sizeof(g)); break;
          case 2: g.path = pick(2) ? nullptr : ""; break;
          case 3: g.movable_node_count = huge(); g.movable_node_names = names; break;
          case 4: g.movable_node_count = 1; g.movable_node_names = nullptr; break;
          default: g.movable_node_count = 2; g.movable_node_names = names; break;  // names[1] NULL
        }
        return earshot_scene_load_gltf(scene, &g);
      },
      [&] {
        earshot_mesh* out = nullptr;
        switch (pick(3)) {
          case 0: return earshot_scene_find_mesh(scene, nullptr, &out);
          case 1: return earshot_scene_find_mesh(scene, "door", nullptr);
          default: return earshot_scene_find_mesh(ctxAsScene, "door", &out);
        }
      },
      [&] {
        earshot_scene_stats st{};
        st.struct_size = wrongSize(sizeof(st));
        return pick(2) ? earshot_scene_get_stats(scene, &st) : earshot_scene_get_stats(scene, nullptr);
      },
      [&] {
        const char* names[] = {"concrete", nullptr};
        std::vector<uint32_t> indices = cube.indices;
        std::vector<float> vertices = cube.vertices;
        std::vector<uint32_t> triMaterials(indices.size() / 3, 0);
        float transform[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
        earshot_mesh_settings s;
        earshot_mesh_settings_init(&s);
        s.vertices = vertices.data();
        s.vertex_count = vertices.size() / 3;
        s.indices = indices.data();
        s.triangle_count = indices.size() / 3;
        s.material_names = names;
        s.material_count = 1;
        earshot_mesh* out = nullptr;
        switch (pick(17)) {
          case 0: return earshot_mesh_create(nullptr, &s, &out);
          case 1: return earshot_mesh_create(ctx, nullptr, &out);
          case 2: return earshot_mesh_create(ctx, &s, nullptr);
          case 3: s.struct_size = wrongSize(sizeof(s)); break;
          case 4: s.vertex_count = pick(2) ? 0 : huge(); break;
          case 5: s.triangle_count = pick(2) ? 0 : huge(); break;
          case 6: s.material_count = pick(2) ? 0 : huge(); break;
          case 7: s.vertices = nullptr; break;
          case 8: s.indices = nullptr; break;
          case 9: s.material_names = nullptr; break;
          case 10: s.material_count = 2; break;  // names[1] is NULL
          case 11: indices[pick(uint32_t(indices.size()))] = uint32_t(8 + pick(1000)); break;
          case 12:
            triMaterials[pick(uint32_t(triMaterials.size()))] = 1 + pick(100);
            s.triangle_materials = triMaterials.data();
            break;
          case 13: vertices[pick(uint32_t(vertices.size()))] = badFloat(); break;
          case 14:
            transform[pick(12)] = badFloat();
            s.transform = transform;
            break;
          case 15:
            std::fill(transform, transform + 12, 0.0f);  // singular
            s.transform = transform;
            break;
          default: storeRaw(s.motion, 2 + pick(100)); break;
        }
        const earshot_status st = earshot_mesh_create(ctx, &s, &out);
        EXPECT_EQ(out, nullptr);
        return st;
      },
      [&] {
        float m12[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
        float m16[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
        switch (pick(8)) {
          case 0: return earshot_mesh_set_transform(nullptr, box12);
          case 1: return earshot_mesh_set_transform(door, nullptr);
          case 2: m12[pick(12)] = badFloat(); return earshot_mesh_set_transform(door, m12);
          case 3: std::fill(m12, m12 + 12, 0.0f); return earshot_mesh_set_transform(door, m12);
          case 4: return earshot_mesh_set_transform(srcAsMesh, box12);
          case 5: m16[pick(16)] = badFloat(); return earshot_mesh_set_transform_4x4(door, m16);
          case 6: m16[0] = m16[5] = m16[10] = 0.0f; return earshot_mesh_set_transform_4x4(door, m16);
          default: return earshot_mesh_set_transform_4x4(door, nullptr);
        }
      },
      [&] {
        return pick(2) ? earshot_mesh_get_transform(door, nullptr) : earshot_mesh_get_transform(srcAsMesh, nullptr);
      },
      [&] {
        switch (pick(3)) {
          case 0: return earshot_mesh_set_material(door, nullptr);
          case 1: return earshot_mesh_set_material(door, "");
          default: return earshot_mesh_set_material(nullptr, "concrete");
        }
      },
      [&] {
        earshot_source_settings s;
        earshot_source_settings_init(&s);
        earshot_source* out = nullptr;
        switch (pick(6)) {
          case 0: return earshot_source_create(nullptr, &s, &out);
          case 1: return earshot_source_create(ctx, &s, nullptr);
          case 2: s.struct_size = wrongSize(sizeof(s)); break;
          case 3: s.gain_db = pick(2) ? badFloat() : 41.0f; break;
          case 4: s.gain_db = -121.0f; break;
          default: storeRaw(s.direct, 2 + pick(100)); break;
        }
        const earshot_status st = earshot_source_create(ctx, &s, &out);
        EXPECT_EQ(out, nullptr);
        return st;
      },
      [&] {
        switch (pick(3)) {
          case 0: return earshot_source_set_position(nullptr, {0, 0, 0});
          case 1: return earshot_source_set_position(meshAsSource, {0, 0, 0});
          default: return earshot_source_set_position(src, badVec());
        }
      },
      [&] {
        const float gains[] = {kNaN, kInf, -kInf, -121.0f, 40.5f, 1e30f};
        return pick(5) ? earshot_source_set_gain_db(src, gains[pick(6)]) : earshot_source_set_gain_db(nullptr, 0.0f);
      },
      [&] {
        uint32_t index = 0;
        return pick(2) ? earshot_source_get_index(src, nullptr) : earshot_source_get_index(meshAsSource, &index);
      },
      // Retain/release of NULL or a handle of another type must not touch any count.
      [&] {
        switch (pick(8)) {
          case 0: return earshot_context_retain(sceneAsCtx);
          case 1: return earshot_context_release(sceneAsCtx);
          case 2: return earshot_scene_retain(ctxAsScene);
          case 3: return earshot_scene_release(ctxAsScene);
          case 4: return earshot_mesh_retain(srcAsMesh);
          case 5: return earshot_mesh_release(srcAsMesh);
          case 6: return earshot_source_retain(meshAsSource);
          default: return earshot_source_release(pick(2) ? nullptr : meshAsSource);
        }
      },
      [&] {
        switch (pick(6)) {
          case 0: return earshot_context_settings_init(nullptr);
          case 1: return earshot_scene_settings_init(nullptr);
          case 2: return earshot_mesh_settings_init(nullptr);
          case 3: return earshot_source_settings_init(nullptr);
          case 4: return earshot_gltf_settings_init(nullptr);
          default: return earshot_hrtf_default_path(nullptr, 1 + pick(100), nullptr);
        }
      },
  };

  std::vector<int> perKind(calls.size(), 0);
  for (int i = 0; i < 1000; ++i) {
    const uint32_t kind = pick(uint32_t(calls.size()));
    ++perKind[kind];
    const earshot_status st = calls[kind]();
    ASSERT_EQ(st, EARSHOT_ERROR_INVALID_ARGUMENT) << "call " << i << " (kind " << kind << "): "
                                                  << earshot_status_string(st) << " " << earshot_last_error_message();
    // Every failure but earshot_process's names the function.
    if (kind != 6) {
      EXPECT_EQ(std::strncmp(earshot_last_error_message(), "earshot_", 8), 0) << "kind " << kind;
    }
  }
  for (size_t k = 0; k < perKind.size(); ++k) EXPECT_GT(perKind[k], 10) << "kind " << k << " hardly exercised";

  // Nothing changed...
  const earshot_context_info infoAfter = infoOf(ctx);
  EXPECT_EQ(infoAfter.active_sources, infoBefore.active_sources);
  EXPECT_EQ(infoAfter.simulation_thread_running, 0u);
  const earshot_scene_stats statsAfter = statsOf(scene);
  EXPECT_EQ(statsAfter.mesh_count, statsBefore.mesh_count);
  EXPECT_EQ(statsAfter.commits, statsBefore.commits);
  float doorAfter[12];
  ASSERT_EQ(earshot_mesh_get_transform(door, doorAfter), EARSHOT_OK);
  EXPECT_EQ(std::memcmp(doorBefore, doorAfter, sizeof(doorBefore)), 0);
  earshot_mesh* found = nullptr;
  EXPECT_EQ(earshot_scene_find_mesh(scene, "loose", &found), EARSHOT_ERROR_NOT_FOUND);

  // ...and everything still works.
  ASSERT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
  ASSERT_EQ(earshot_simulate(ctx, 0), EARSHOT_OK) << earshot_last_error_message();
  std::vector<float> l, r;
  render(ctx, 4096, 256, l, r);
  EXPECT_TRUE(allFinite(l) && allFinite(r));
  EXPECT_GT(energy(l) + energy(r), 0.0);

  EXPECT_EQ(earshot_source_release(src), EARSHOT_OK);
  EXPECT_EQ(earshot_mesh_release(loose), EARSHOT_OK);
  EXPECT_EQ(earshot_mesh_release(door), EARSHOT_OK);
  EXPECT_EQ(earshot_mesh_release(walls), EARSHOT_OK);
  EXPECT_EQ(earshot_scene_release(scene), EARSHOT_OK);
  EXPECT_EQ(earshot_context_release(ctx), EARSHOT_OK);
}

// ---------------------------------------------------------------------------
namespace {
struct LogCapture {
  std::vector<std::string> messages;
  static void callback(void* user, earshot_log_level level, const char* message) {
    auto* self = static_cast<LogCapture*>(user);
    self->messages.push_back(std::to_string(int(level)) + " " + message);
  }
  bool contains(const std::string& needle) const {
    for (const std::string& m : messages)
      if (m.find(needle) != std::string::npos) return true;
    return false;
  }
};
}  // namespace

// With the validation flag, an invalid argument is logged naming the function
// and the argument; without it, only the last-error message says so.
TEST(CApiValidation, LogsTheInvalidArgumentOnlyWhenAsked) {
  for (bool validation : {true, false}) {
    LogCapture log;
    earshot_context_settings s = fastSettings();
    s.log = &LogCapture::callback;
    s.log_user_data = &log;
    s.flags = validation ? EARSHOT_CONTEXT_VALIDATION : 0;
    earshot_context* c = nullptr;
    ASSERT_EQ(earshot_context_create(&s, &c), EARSHOT_OK);
    earshot_source* src = nullptr;
    ASSERT_EQ(earshot_source_create(c, nullptr, &src), EARSHOT_OK);
    EXPECT_EQ(earshot_source_set_position(src, {0, kNaN, 0}), EARSHOT_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(earshot_last_error_message()).find("earshot_source_set_position: position.y is nan"),
              std::string::npos)
        << earshot_last_error_message();
    EXPECT_EQ(log.contains("earshot_source_set_position: position.y"), validation);
    EXPECT_EQ(earshot_source_set_gain_db(src, 99.0f), EARSHOT_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(log.contains("gain_db 99 is outside [-120, 40]"), validation);

    // Other errors are logged either way (a missing materials file).
    earshot_scene_settings ss;
    earshot_scene_settings_init(&ss);
    ss.materials_path = "/nonexistent/materials.json";
    earshot_scene* scene = nullptr;
    EXPECT_EQ(earshot_scene_create(c, &ss, &scene), EARSHOT_ERROR_NOT_FOUND);
    EXPECT_EQ(scene, nullptr);
    EXPECT_TRUE(log.contains("/nonexistent/materials.json"));

    // Settings errors before a context exists use the settings' own log.
    earshot_context_settings bad = s;
    bad.rays = 0;
    earshot_context* none = nullptr;
    EXPECT_EQ(earshot_context_create(&bad, &none), EARSHOT_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(log.contains("settings->rays 0"), validation);

    earshot_source_release(src);
    earshot_context_release(c);
  }
}

// ---------------------------------------------------------------------------
namespace {
struct CountingAllocator {
  std::atomic<long> allocations{0}, frees{0};
  static void* allocate(void* user, size_t size, size_t alignment) {
    static_cast<CountingAllocator*>(user)->allocations++;
    return std::aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
  }
  static void release(void* user, void* p) {
    static_cast<CountingAllocator*>(user)->frees++;
    std::free(p);
  }
};
}  // namespace

// Sources hold their context, the slots are reused after release, every
// handle goes through the allocator callbacks, and all are freed at the end.
TEST(CApiLifecycle, SourcesKeepTheContextAliveAndEveryHandleIsFreed) {
  CountingAllocator alloc;
  earshot_context_settings s = fastSettings();
  s.max_sources = 2;
  s.allocate = &CountingAllocator::allocate;
  s.free = &CountingAllocator::release;
  s.allocator_user_data = &alloc;
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&s, &c), EARSHOT_OK);
  earshot_source *a = nullptr, *b = nullptr, *extra = nullptr;
  ASSERT_EQ(earshot_source_create(c, nullptr, &a), EARSHOT_OK);
  ASSERT_EQ(earshot_source_create(c, nullptr, &b), EARSHOT_OK);
  EXPECT_EQ(earshot_source_create(c, nullptr, &extra), EARSHOT_ERROR_OUT_OF_RANGE);
  EXPECT_EQ(extra, nullptr);
  uint32_t ia = 9, ib = 9;
  ASSERT_EQ(earshot_source_get_index(a, &ia), EARSHOT_OK);
  ASSERT_EQ(earshot_source_get_index(b, &ib), EARSHOT_OK);
  EXPECT_LT(ia, 2u);
  EXPECT_LT(ib, 2u);
  EXPECT_NE(ia, ib);
  EXPECT_EQ(infoOf(c).active_sources, 2u);

  // A retained source survives one release; the last frees its slot.
  ASSERT_EQ(earshot_source_retain(a), EARSHOT_OK);
  ASSERT_EQ(earshot_source_release(a), EARSHOT_OK);
  EXPECT_EQ(infoOf(c).active_sources, 2u);
  ASSERT_EQ(earshot_source_release(a), EARSHOT_OK);
  EXPECT_EQ(infoOf(c).active_sources, 1u);
  ASSERT_EQ(earshot_source_create(c, nullptr, &extra), EARSHOT_OK);
  uint32_t ie = 9;
  ASSERT_EQ(earshot_source_get_index(extra, &ie), EARSHOT_OK);
  EXPECT_EQ(ie, ia);

  // Scenes and meshes use the allocator too; the scene keeps its meshes.
  earshot_scene* scene = nullptr;
  ASSERT_EQ(earshot_scene_create(c, nullptr, &scene), EARSHOT_OK);
  earshot_mesh* m = makeMesh(c, box(0, 0, 0, 4, 4, 3), "brick", EARSHOT_MESH_STATIC, "room");
  ASSERT_EQ(earshot_scene_add_mesh(scene, m), EARSHOT_OK);
  ASSERT_EQ(earshot_mesh_release(m), EARSHOT_OK);
  earshot_mesh* again = nullptr;
  ASSERT_EQ(earshot_scene_find_mesh(scene, "room", &again), EARSHOT_OK);
  EXPECT_EQ(again, m);
  ASSERT_EQ(earshot_context_set_scene(c, scene), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_release(scene), EARSHOT_OK);  // the context holds it
  EXPECT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
  EXPECT_EQ(alloc.allocations.load(), 6);  // context, 3 sources, scene, mesh
  EXPECT_EQ(alloc.frees.load(), 1);        // source a

  // Releasing the context first: the sources keep it (and its scene) alive.
  ASSERT_EQ(earshot_context_release(c), EARSHOT_OK);
  EXPECT_EQ(alloc.frees.load(), 1);
  ASSERT_EQ(earshot_source_set_position(b, {1, 1, 1}), EARSHOT_OK);
  ASSERT_EQ(earshot_simulate(c, 0), EARSHOT_OK);
  ASSERT_EQ(earshot_source_release(b), EARSHOT_OK);
  ASSERT_EQ(earshot_mesh_release(again), EARSHOT_OK);  // still held by the scene
  EXPECT_EQ(alloc.frees.load(), 2);
  ASSERT_EQ(earshot_source_release(extra), EARSHOT_OK);  // last: context, scene, mesh go
  EXPECT_EQ(alloc.frees.load(), alloc.allocations.load());
}

// A context whose rate its HRTF cannot take is refused when made, not at
// its first source (the header said 384 kHz; the HRTF takes 192 kHz).
TEST(CApiLifecycle, RatesTheHrtfCannotServeAreRefusedAtCreation) {
  earshot_context_settings s = fastSettings();
  s.sample_rate_hz = 250000;
  earshot_context* c = nullptr;
  EXPECT_EQ(earshot_context_create(&s, &c), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(c, nullptr);
  EXPECT_NE(std::string(earshot_last_error_message()).find("sample_rate_hz 250000 is outside [8000, 192000]"),
            std::string::npos)
      << earshot_last_error_message();
  s.sample_rate_hz = 192000;
  s.max_ir_seconds = 0.2;
  ASSERT_EQ(earshot_context_create(&s, &c), EARSHOT_OK) << earshot_last_error_message();
  earshot_source* src = nullptr;
  EXPECT_EQ(earshot_source_create(c, nullptr, &src), EARSHOT_OK) << earshot_last_error_message();
  earshot_source_release(src);
  earshot_context_release(c);
}

// max_ir_seconds is (0, 60] in every reflection mode. At 0.15 s or less
// (where the ambisonic bus's shared late tail would start) a context could
// not be made: "engine: sharedTailSeconds 0.15 is outside [0, 0.1)".
TEST(CApiLifecycle, ShortIrsMakeAContextInEveryReflectionMode) {
  for (const uint32_t order : {0u, 1u}) {
    for (const double seconds : {0.01, 0.1, 0.15, 0.16}) {
      SCOPED_TRACE("ambisonic_order " + std::to_string(order) + ", max_ir_seconds " + std::to_string(seconds));
      earshot_context_settings s = fastSettings();
      s.max_ir_seconds = seconds;
      s.ambisonic_order = order;
      earshot_context* c = nullptr;
      ASSERT_EQ(earshot_context_create(&s, &c), EARSHOT_OK) << earshot_last_error_message();
      earshot_scene* scene = nullptr;
      ASSERT_EQ(earshot_scene_create(c, nullptr, &scene), EARSHOT_OK);
      earshot_mesh* m = makeMesh(c, box(0, 0, 0, 4, 4, 3), "brick", EARSHOT_MESH_STATIC, "room");
      ASSERT_EQ(earshot_scene_add_mesh(scene, m), EARSHOT_OK);
      ASSERT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
      ASSERT_EQ(earshot_context_set_scene(c, scene), EARSHOT_OK);
      ASSERT_EQ(earshot_context_set_listener(c, {2, 2, 1.5f}, {0, 0, -1}, {0, 1, 0}), EARSHOT_OK);
      earshot_source* src = nullptr;
      ASSERT_EQ(earshot_source_create(c, nullptr, &src), EARSHOT_OK);
      ASSERT_EQ(earshot_source_set_position(src, {1, 1, 1}), EARSHOT_OK);
      ASSERT_EQ(earshot_simulate(c, 0), EARSHOT_OK) << earshot_last_error_message();
      earshot_ir* ir = nullptr;
      ASSERT_EQ(earshot_source_get_ir(src, &ir), EARSHOT_OK);
      earshot_ir_info info{};
      info.struct_size = sizeof(info);
      ASSERT_EQ(earshot_ir_get_info(ir, &info), EARSHOT_OK);
      EXPECT_EQ(info.channels, order == 0 ? 2u : 4u);
      EXPECT_GE(info.frames, 1u);
      EXPECT_LE(double(info.frames), seconds * s.sample_rate_hz + 1);
      std::vector<float> left(size_t(info.frames));
      ASSERT_EQ(earshot_ir_copy_channel(ir, 0, left.data(), info.frames), EARSHOT_OK);
      EXPECT_GT(energy(left), 0.0);  // the floor's reflection (2.9 m) arrives within 10 ms
      std::vector<float> out(512), outR(512);
      const std::vector<float> in(512, 0.5f);
      const float* inputs[] = {in.data()};
      ASSERT_EQ(earshot_process(c, inputs, 1, out.data(), outR.data(), 512), EARSHOT_OK);
      EXPECT_TRUE(allFinite(out) && allFinite(outR));
      earshot_ir_release(ir);
      earshot_source_release(src);
      earshot_mesh_release(m);
      earshot_scene_release(scene);
      earshot_context_release(c);
    }
  }
}

// ---------------------------------------------------------------------------
// Scene editing: a movable mesh moves without a rebuild of the static BVH;
// materials resolve by name; meshes live in one scene at a time.
TEST(CApiScene, MovingAMovableMeshRebuildsOnlyTheTopLevel) {
  earshot_context_settings s = fastSettings();
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&s, &c), EARSHOT_OK);
  earshot_scene *scene = nullptr, *other = nullptr;
  ASSERT_EQ(earshot_scene_create(c, nullptr, &scene), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_create(c, nullptr, &other), EARSHOT_OK);
  earshot_mesh* walls = makeMesh(c, box(0, 0, 0, 6, 5, 3), "plaster", EARSHOT_MESH_STATIC, "walls");
  earshot_mesh* door = makeMesh(c, box(0, 0, 0, 0.05f, 1, 2), "door_wood", EARSHOT_MESH_MOVABLE, "door");
  ASSERT_EQ(earshot_scene_add_mesh(scene, walls), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_add_mesh(scene, door), EARSHOT_OK);
  EXPECT_EQ(earshot_scene_add_mesh(scene, door), EARSHOT_ERROR_INVALID_STATE);
  EXPECT_EQ(earshot_scene_add_mesh(other, door), EARSHOT_ERROR_INVALID_STATE);
  ASSERT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
  const earshot_scene_stats first = statsOf(scene);
  EXPECT_EQ(first.mesh_count, 2u);
  EXPECT_EQ(first.static_bvh_builds, 1u);

  for (int step = 1; step <= 5; ++step) {
    const float m[12] = {1, 0, 0, 3.0f + 0.1f * float(step), 0, 1, 0, 2, 0, 0, 1, 0};
    ASSERT_EQ(earshot_mesh_set_transform(door, m), EARSHOT_OK);
    ASSERT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
    float back[12];
    ASSERT_EQ(earshot_mesh_get_transform(door, back), EARSHOT_OK);
    EXPECT_EQ(std::memcmp(back, m, sizeof(m)), 0);
  }
  const earshot_scene_stats moved = statsOf(scene);
  EXPECT_EQ(moved.static_bvh_builds, first.static_bvh_builds);
  EXPECT_EQ(moved.top_level_builds, first.top_level_builds + 5);
  EXPECT_EQ(moved.commits, first.commits + 5);

  // A column-major 4x4 is the transpose of the row-major 3x4 plus a last row.
  const float m16[16] = {0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1, 0, 4, 2, 0, 1};  // 90 degrees about z, then (4, 2, 0)
  ASSERT_EQ(earshot_mesh_set_transform_4x4(door, m16), EARSHOT_OK);
  float back[12];
  ASSERT_EQ(earshot_mesh_get_transform(door, back), EARSHOT_OK);
  const float expected[12] = {0, -1, 0, 4, 1, 0, 0, 2, 0, 0, 1, 0};
  for (int i = 0; i < 12; ++i) EXPECT_FLOAT_EQ(back[i], expected[i]) << i;

  // Materials: known names re-material without a BVH build; unknown ones fail.
  ASSERT_EQ(earshot_mesh_set_material(door, "metal"), EARSHOT_OK);
  EXPECT_EQ(earshot_mesh_set_material(door, "unobtainium"), EARSHOT_ERROR_NOT_FOUND);
  earshot_material custom{};
  custom.struct_size = sizeof(custom);
  custom.name = "unobtainium";
  for (int b = 0; b < EARSHOT_BAND_COUNT; ++b) custom.absorption[b] = 0.9f, custom.scattering[b] = 0.2f;
  ASSERT_EQ(earshot_scene_add_material(scene, &custom), EARSHOT_OK);
  ASSERT_EQ(earshot_mesh_set_material(door, "unobtainium"), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
  EXPECT_EQ(statsOf(scene).static_bvh_builds, first.static_bvh_builds);

  // Removed, the mesh can join another scene; its material name must exist there.
  ASSERT_EQ(earshot_scene_remove_mesh(scene, door), EARSHOT_OK);
  EXPECT_EQ(earshot_scene_remove_mesh(scene, door), EARSHOT_ERROR_INVALID_STATE);
  EXPECT_EQ(earshot_scene_add_mesh(other, door), EARSHOT_ERROR_NOT_FOUND);  // "unobtainium" is not in `other`
  ASSERT_EQ(earshot_mesh_set_material(door, "metal"), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_add_mesh(other, door), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
  EXPECT_EQ(statsOf(scene).mesh_count, 1u);
  EXPECT_EQ(statsOf(other).mesh_count, 1u);

  // A static mesh that moves does rebuild the static BVH.
  const float shifted[12] = {1, 0, 0, 0.5f, 0, 1, 0, 0, 0, 0, 1, 0};
  ASSERT_EQ(earshot_mesh_set_transform(walls, shifted), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
  EXPECT_EQ(statsOf(scene).static_bvh_builds, first.static_bvh_builds + 1);

  earshot_mesh_release(door);
  earshot_mesh_release(walls);
  earshot_scene_release(other);
  earshot_scene_release(scene);
  earshot_context_release(c);
}

// glTF: the sample's two rooms with the door movable, all or nothing.
TEST(CApiGltf, LoadsTwoRoomsWithTheDoorMovableAndFailsCleanly) {
  earshot_context_settings s = fastSettings();
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&s, &c), EARSHOT_OK);
  earshot_scene* scene = nullptr;
  ASSERT_EQ(earshot_scene_create(c, nullptr, &scene), EARSHOT_OK);

  earshot_gltf_settings g;
  earshot_gltf_settings_init(&g);
  g.path = kTwoRooms.c_str();
  g.material_map_path = kTwoRoomsMap.c_str();
  const char* wrong[] = {"door", "window"};
  g.movable_node_names = wrong;
  g.movable_node_count = 2;
  EXPECT_EQ(earshot_scene_load_gltf(scene, &g), EARSHOT_ERROR_NOT_FOUND);
  EXPECT_NE(std::string(earshot_last_error_message()).find("window"), std::string::npos);
  EXPECT_EQ(statsOf(scene).mesh_count, 0u);

  const char* movable[] = {"door"};
  g.movable_node_names = movable;
  g.movable_node_count = 1;
  ASSERT_EQ(earshot_scene_load_gltf(scene, &g), EARSHOT_OK) << earshot_last_error_message();
  EXPECT_EQ(statsOf(scene).mesh_count, 2u);
  earshot_mesh *door = nullptr, *rooms = nullptr;
  ASSERT_EQ(earshot_scene_find_mesh(scene, "door", &door), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_find_mesh(scene, kTwoRooms.c_str(), &rooms), EARSHOT_OK);
  float m[12];
  ASSERT_EQ(earshot_mesh_get_transform(door, m), EARSHOT_OK);
  // The node's translation in the file: the hinge at (6.1, 2, 0).
  EXPECT_FLOAT_EQ(m[3], 6.1f);
  EXPECT_FLOAT_EQ(m[7], 2.0f);
  EXPECT_FLOAT_EQ(m[11], 0.0f);
  ASSERT_EQ(earshot_scene_commit(scene), EARSHOT_OK);

  // A glTF mesh removed cannot come back (its triangles live only in the scene).
  ASSERT_EQ(earshot_scene_remove_mesh(scene, door), EARSHOT_OK);
  EXPECT_EQ(earshot_scene_add_mesh(scene, door), EARSHOT_ERROR_INVALID_STATE);

  g.path = "/nonexistent.gltf";
  EXPECT_EQ(earshot_scene_load_gltf(scene, &g), EARSHOT_ERROR_NOT_FOUND);
  earshot_mesh_release(door);
  earshot_mesh_release(rooms);
  earshot_scene_release(scene);
  earshot_context_release(c);
}

// ---------------------------------------------------------------------------
// Any host block size gives the same output as blocks of the convolver's size.
TEST(CApiAudio, AnyBlockSizeGivesTheSameOutput) {
  Room a, b;
  ASSERT_TRUE(a.source && b.source);
  std::vector<float> la, ra;
  render(a.context, 24000, 256, la, ra);
  EXPECT_TRUE(allFinite(la) && allFinite(ra));
  EXPECT_GT(energy(la), 0.0);
  // The source is 2 m to the listener's left (forward +x, up +z): the direct
  // sound (at the latency + 280 frames, before the first reflection at ~420
  // frames after it) is louder in the left ear.
  earshot_context_info info;
  info.struct_size = sizeof(info);
  ASSERT_EQ(earshot_context_get_info(a.context, &info), EARSHOT_OK);
  const size_t latency = info.latency_frames;
  double directL = 0, directR = 0;
  for (size_t p = 0; p + latency + 400 <= la.size(); p += kPeriod)
    for (size_t i = p + latency; i < p + latency + 400; ++i)
      directL += double(la[i]) * la[i], directR += double(ra[i]) * ra[i];
  EXPECT_GT(directL, 2.0 * directR);

  // Odd sizes: 1, 7, 333, 1024, 3001 in turn, on an identical context.
  const std::vector<float> dry = impulses(24000);
  std::vector<float> lb(24000), rb(24000);
  const size_t sizes[] = {1, 7, 333, 1024, 3001};
  size_t off = 0;
  for (int k = 0; off < dry.size(); ++k) {
    const size_t n = std::min(sizes[k % 5], dry.size() - off);
    const float* inputs[1] = {dry.data() + off};
    ASSERT_EQ(earshot_process(b.context, inputs, 1, lb.data() + off, rb.data() + off, n), EARSHOT_OK);
    off += n;
  }
  double maxDiff = 0, peak = 0;
  for (size_t i = 0; i < la.size(); ++i) {
    maxDiff = std::max({maxDiff, double(std::fabs(la[i] - lb[i])), double(std::fabs(ra[i] - rb[i]))});
    peak = std::max(peak, double(std::fabs(la[i])));
  }
  // Bit-identical: the engine works in its own partitions whatever the host
  // block, so the split of the calls changes nothing.
  EXPECT_GT(peak, 0.0);
  EXPECT_EQ(maxDiff, 0.0) << "peak " << peak;

  // Frames 0 and input_count 0 are fine; silence in gives silence out.
  EXPECT_EQ(earshot_process(b.context, nullptr, 0, lb.data(), rb.data(), 0), EARSHOT_OK);
}

// A host that processes in place passes an output buffer, already holding
// the source's samples, as its input (one scratch buffer per source): the
// output is the one from separate buffers, bit for bit, in blocks that span
// several of the engine's chunks.
// An input that overlaps an output any other way is refused, outputs
// untouched. (The direct sound read its input after the reflections had
// been mixed into the outputs: in place, it spatialised the mix.)
TEST(CApiAudio, AnInputMayBeAnOutputBufferProcessedInPlace) {
  Room a, b, c;
  ASSERT_TRUE(a.source && b.source && c.source);
  uint32_t index = 99;
  ASSERT_EQ(earshot_source_get_index(b.source, &index), EARSHOT_OK);
  ASSERT_EQ(index, 0u);
  const size_t frames = 24000, block = 2500;  // blocks span several of the engine's chunks (1,024)
  std::vector<float> la, ra;
  render(a.context, frames, block, la, ra);
  const std::vector<float> dry = impulses(frames);
  std::vector<float> lb(frames), rb(frames), lc(frames), rc(frames);
  for (size_t off = 0; off < frames; off += block) {
    const size_t n = std::min(block, frames - off);
    std::copy(dry.begin() + std::ptrdiff_t(off), dry.begin() + std::ptrdiff_t(off + n), lb.begin() + std::ptrdiff_t(off));
    const float* inLeft[1] = {lb.data() + off};
    ASSERT_EQ(earshot_process(b.context, inLeft, 1, lb.data() + off, rb.data() + off, n), EARSHOT_OK);
    std::copy(dry.begin() + std::ptrdiff_t(off), dry.begin() + std::ptrdiff_t(off + n), rc.begin() + std::ptrdiff_t(off));
    const float* inRight[1] = {rc.data() + off};
    ASSERT_EQ(earshot_process(c.context, inRight, 1, lc.data() + off, rc.data() + off, n), EARSHOT_OK);
  }
  double maxDiff = 0, peak = 0;
  for (size_t i = 0; i < frames; ++i) {
    maxDiff = std::max({maxDiff, double(std::fabs(la[i] - lb[i])), double(std::fabs(ra[i] - rb[i])),
                        double(std::fabs(la[i] - lc[i])), double(std::fabs(ra[i] - rc[i]))});
    peak = std::max(peak, double(std::fabs(la[i])));
  }
  EXPECT_GT(peak, 0.0);
  EXPECT_EQ(maxDiff, 0.0) << "peak " << peak;

  // Overlaps other than the same start: refused, nothing written.
  std::vector<float> wide(3 * block, 0.25f), right(block, 0.25f);
  for (const float* in : {wide.data() + block - 1, wide.data() + block + 1, wide.data() + 2 * block - 1}) {
    const float* inputs[1] = {in};
    EXPECT_EQ(earshot_process(b.context, inputs, 1, wide.data() + block, right.data(), block),
              EARSHOT_ERROR_INVALID_ARGUMENT)
        << (in - wide.data());
  }
  EXPECT_TRUE(std::all_of(wide.begin(), wide.end(), [](float v) { return v == 0.25f; }));
  EXPECT_TRUE(std::all_of(right.begin(), right.end(), [](float v) { return v == 0.25f; }));
  // Beside an output: fine.
  const float* beside[1] = {wide.data() + 2 * block};
  EXPECT_EQ(earshot_process(b.context, beside, 1, wide.data() + block, right.data(), block), EARSHOT_OK);
}

// The built-in simulation thread makes a new source audible, runs at its
// rate, and excludes earshot_simulate while it runs.
TEST(CApiThreads, BuiltInSimulationThreadUpdatesSources) {
  earshot_context_settings s = fastSettings();
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&s, &c), EARSHOT_OK);
  earshot_source* src = nullptr;
  ASSERT_EQ(earshot_source_create(c, nullptr, &src), EARSHOT_OK);
  ASSERT_EQ(earshot_source_set_position(src, {0, 0, -2}), EARSHOT_OK);

  // Not simulated yet: the direct sound plays from the first block (issue
  // 19), the reflections do not (free field here: there are none anyway).
  std::vector<float> l, r;
  render(c, 2048, 256, l, r);
  EXPECT_GT(energy(l) + energy(r), 0.0);

  ASSERT_EQ(earshot_context_start_simulation(c, 50.0, 0), EARSHOT_OK);
  EXPECT_EQ(earshot_context_start_simulation(c, 50.0, 0), EARSHOT_ERROR_INVALID_STATE);
  EXPECT_EQ(earshot_simulate(c, 0), EARSHOT_ERROR_INVALID_STATE);
  EXPECT_EQ(infoOf(c).simulation_thread_running, 1u);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (infoOf(c).last_simulation_sources == 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_EQ(infoOf(c).last_simulation_sources, 1u);
  ASSERT_EQ(earshot_context_stop_simulation(c), EARSHOT_OK);
  ASSERT_EQ(earshot_context_stop_simulation(c), EARSHOT_OK);
  EXPECT_EQ(infoOf(c).simulation_thread_running, 0u);
  EXPECT_EQ(earshot_simulate(c, 0), EARSHOT_OK);
  // The slowest rate: a step, then a wait of 1000 s that stop ends.
  ASSERT_EQ(earshot_context_start_simulation(c, 0.001, 0), EARSHOT_OK);
  ASSERT_EQ(earshot_context_stop_simulation(c), EARSHOT_OK);
  EXPECT_EQ(infoOf(c).simulation_thread_running, 0u);

  render(c, 4096, 256, l, r);
  EXPECT_GT(energy(l) + energy(r), 0.0);
  // Releasing the context with the thread running stops it.
  ASSERT_EQ(earshot_context_start_simulation(c, 100.0, 1), EARSHOT_OK);
  earshot_source_release(src);
  earshot_context_release(c);
}

// The default HRTF is found (in the source tree, for this build) and reported.
TEST(CApiHrtf, DefaultPathIsReportedAndTooSmallBuffersAreRefused) {
  size_t length = 0;
  char small[4];
  EXPECT_EQ(earshot_hrtf_default_path(small, sizeof(small), &length), EARSHOT_ERROR_OUT_OF_RANGE);
  ASSERT_GT(length, 4u);
  std::vector<char> buffer(length + 1);
  ASSERT_EQ(earshot_hrtf_default_path(buffer.data(), buffer.size(), &length), EARSHOT_OK);
  EXPECT_EQ(std::strlen(buffer.data()), length);
  EXPECT_NE(std::string(buffer.data()).find("FHK_HRIR_L2354.sofa"), std::string::npos);
}

}  // namespace earshot::capi::test
