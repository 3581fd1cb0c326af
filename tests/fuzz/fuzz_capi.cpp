// libFuzzer target: the C API as a game calls it, in any order and with any
// arguments. The input is a program: each step picks one entry point and
// its arguments (handles of any type, NULL, released-by-us never: a freed
// handle is the caller's bug, not hostile input), and runs it. After every
// call the documented contract is checked: a known status, never INTERNAL,
// a one-line message after each error, NULL out-handles on failure, finite audio and
// IR samples, and a context's active_sources equal to the sources the
// program holds on it.
//
// Two contexts (binaural reflections with a trace per source; an ambisonic
// bus written as AmbiX with a shared trace) live for the whole process, so
// that one input costs milliseconds, not an HRTF load; each input starts
// them without a scene or sources and ends by releasing everything it made.
// Their HRTF is tests/data/hrtf/Pulse.sofa at 16 kHz, prepared once into
// <build>/tests/fuzz/capi-cache (the first run of a build takes its
// preparation, ~15 s under coverage and ASan, in LLVMFuzzerInitialize).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "earshot/earshot.h"

#ifndef EARSHOT_FUZZ_SOURCE_DIR
#error "EARSHOT_FUZZ_SOURCE_DIR must name the source tree"
#endif
#ifndef EARSHOT_FUZZ_CACHE_DIR
#error "EARSHOT_FUZZ_CACHE_DIR must name a cache folder in the build tree"
#endif

#define CAPI_CHECK(cond)                                                              \
  do {                                                                                \
    if (!(cond)) {                                                                    \
      std::fprintf(stderr, "fuzz_capi: %s:%d: %s\n", __FILE__, __LINE__, #cond);     \
      std::abort();                                                                   \
    }                                                                                 \
  } while (0)

namespace {

constexpr double kRate = 16000.0;
constexpr uint32_t kMaxSources = 4;
constexpr size_t kMaxFrames = 700;  // a block longer than the context's (64) and than 256
constexpr size_t kMaxSteps = 64;

/** Reads the program; past its end every read is 0. */
class Bytes {
 public:
  Bytes(const uint8_t* data, size_t size) : mData(data), mSize(size) {}
  bool done() const { return mPos >= mSize; }
  uint8_t u8() { return mPos < mSize ? mData[mPos++] : 0; }
  uint32_t u32() {
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t(u8()) << (8 * i);
    return v;
  }
  uint32_t below(uint32_t n) { return n == 0 ? 0 : u8() % n; }
  /** A value a game or an attacker might pass: ordinary, boundary or not finite. */
  float f() {
    static const float kTable[] = {0.0f, 1.0f, -1.0f, 0.5f, 2.0f, 3.0f, 1.5f, 0.25f, 10.0f, -0.0f, 100.0f,
                                   1e6f, 1.1e6f, -1e6f, 1e30f, -1e30f, 3.4e38f, 1e-40f, 0.1f, 40.0f,
                                   -120.0f, 41.0f, 16.0f, 0.999f, NAN, INFINITY, -INFINITY};
    constexpr uint8_t kCount = sizeof(kTable) / sizeof(kTable[0]);
    const uint8_t sel = u8();
    if (sel < kCount) return kTable[sel];
    if (sel < 128) return float(sel - kCount) * 0.125f - 6.0f;  // a room's coordinates
    uint32_t bits = u32();
    float v;
    std::memcpy(&v, &bits, sizeof(v));
    return v;
  }
  double d() { return double(f()); }
  earshot_vec3 vec() { return earshot_vec3{f(), f(), f()}; }
  /** Any 32-bit value, mostly small: enums, counts, orders. */
  uint32_t count() {
    const uint8_t sel = u8();
    if (sel < 200) return sel % 8;
    if (sel < 250) return u32();
    return 0xffffffffu - (sel - 250);
  }

 private:
  const uint8_t* mData;
  size_t mSize;
  size_t mPos = 0;
};

template <class E>
void storeRaw(E& field, uint32_t value) {
  static_assert(sizeof(E) == sizeof(uint32_t), "C enums are 32-bit here");
  std::memcpy(&field, &value, sizeof(field));
}

/** EARSHOT_FUZZ_CAPI_TRACE=1 prints each step and each call's status (for
 *  writing seeds: make_capi_seeds.py). */
bool tracing() {
  static const bool on = [] {
    const char* v = std::getenv("EARSHOT_FUZZ_CAPI_TRACE");
    return v != nullptr && v[0] == '1';
  }();
  return on;
}

bool known(earshot_status s) { return int(s) >= 0 && int(s) <= int(EARSHOT_ERROR_INVALID_STATE); }

/** Every call but earshot_process*: a known status, never INTERNAL, and a
 *  message for every error. */
earshot_status checked(earshot_status s) {
  if (!known(s)) {
    std::fprintf(stderr, "fuzz_capi: status %d (%s): %s\n", int(s), earshot_status_string(s),
                 earshot_last_error_message());
    std::abort();
  }
  if (s != EARSHOT_OK) {
    const char* message = earshot_last_error_message();
    CAPI_CHECK(message[0] != '\0' && !std::strchr(message, '\n') && !std::strchr(message, '\r'));
  }
  if (tracing()) std::fprintf(stderr, "  -> %s%s%s\n", earshot_status_string(s), s ? ": " : "",
                              s ? earshot_last_error_message() : "");
  return s;
}

/** The context settings' allocator, failing after `allowed` allocations;
 *  counts what it holds, so that a leaked or twice-freed handle shows. */
struct FailingAllocator {
  int allowed = 0;
  int live = 0;
  static void* allocate(void* user, size_t size, size_t alignment) {
    auto* a = static_cast<FailingAllocator*>(user);
    CAPI_CHECK(alignment != 0 && (alignment & (alignment - 1)) == 0 && alignment <= 64);
    if (a->allowed <= 0) return nullptr;
    --a->allowed;
    void* p = nullptr;
    if (posix_memalign(&p, alignment < sizeof(void*) ? sizeof(void*) : alignment, size ? size : 1) != 0) return nullptr;
    ++a->live;
    return p;
  }
  static void release(void* user, void* pointer) {
    auto* a = static_cast<FailingAllocator*>(user);
    CAPI_CHECK(pointer != nullptr && a->live > 0);
    --a->live;
    std::free(pointer);
  }
};

struct Contexts {
  earshot_context* c[2] = {nullptr, nullptr};
};

Contexts& contexts() {
  static Contexts all = [] {
    setenv("EARSHOT_CACHE_DIR", EARSHOT_FUZZ_CACHE_DIR, 1);
    Contexts made;
    for (int i = 0; i < 2; ++i) {
      earshot_context_settings s;
      earshot_context_settings_init(&s);
      s.sample_rate_hz = kRate;
      s.block_frames = 64;
      s.max_sources = kMaxSources;
      s.max_ir_seconds = 0.25;
      s.rays = 64;
      s.bounces = 4;
      s.image_source_order = 2;
      s.threads = 1;
      s.max_distance_meters = 50;
      s.hrtf_path = EARSHOT_FUZZ_SOURCE_DIR "/tests/data/hrtf/Pulse.sofa";
      s.ambisonic_order = i == 0 ? 0 : 1;
      s.output_format = i == 0 ? EARSHOT_OUTPUT_BINAURAL : EARSHOT_OUTPUT_AMBISONIC;
      s.trace_mode = i == 0 ? EARSHOT_TRACE_PER_SOURCE : EARSHOT_TRACE_SHARED;
      if (earshot_context_create(&s, &made.c[i]) != EARSHOT_OK) {
        std::fprintf(stderr, "fuzz_capi: context %d: %s\n", i, earshot_last_error_message());
        std::abort();
      }
    }
    return made;
  }();
  return all;
}

/** What one input holds. Everything is released at its end. */
struct Program {
  explicit Program(Bytes& b) : in(b) {}
  Bytes& in;
  std::vector<earshot_scene*> scenes;
  std::vector<earshot_mesh*> meshes;
  struct Source {
    earshot_source* handle;
    int context;
    bool directInIr;  // EARSHOT_DIRECT_IN_IMPULSE_RESPONSE
  };
  std::vector<Source> sources;
  std::vector<earshot_ir*> irs;
  std::vector<float> scratch;

  earshot_context* context() { return contexts().c[in.below(2)]; }

  /** A handle for an argument of type T: usually one of T's, sometimes
   *  NULL or a live handle of another type (the API names both). */
  template <class T>
  T* pick(const std::vector<T*>& own) {
    const uint8_t sel = in.u8();
    if (sel < 200 && !own.empty()) return own[sel % own.size()];
    if (sel < 215) return nullptr;
    void* other = nullptr;
    switch (sel % 4) {
      case 0: other = scenes.empty() ? nullptr : scenes[0]; break;
      case 1: other = meshes.empty() ? nullptr : meshes[0]; break;
      case 2: other = sources.empty() ? nullptr : sources[0].handle; break;
      default: other = contexts().c[0]; break;
    }
    return static_cast<T*>(other);
  }
  size_t pickSource() { return sources.empty() ? 0 : in.below(uint32_t(sources.size())); }

  const char* materialName() {
    static const char* kNames[] = {"concrete", "carpet", "glass", "wood", "", "no such material",
                                   "fuzz_a", "two\nlines"};
    const uint8_t sel = in.u8();
    if (sel == 255) return nullptr;
    return kNames[sel % 8];
  }

  void addMaterial() {
    earshot_material m{};
    m.struct_size = in.u8() < 250 ? sizeof(m) : in.u32();
    m.name = materialName();
    for (int b = 0; b < EARSHOT_BAND_COUNT; ++b) {
      m.absorption[b] = in.f();
      m.scattering[b] = in.f();
      m.transmission[b] = in.f();
    }
    earshot_scene* scene = pick(scenes);
    const bool withMaterial = in.u8() < 250;
    checked(earshot_scene_add_material(scene, withMaterial ? &m : nullptr));
  }

  void createMesh() {
    const uint32_t vertexCount = in.below(10);
    const uint32_t triangleCount = in.below(13);
    std::vector<float> vertices(vertexCount * 3);
    // Mostly a box's corners, sometimes any value.
    for (uint32_t v = 0; v < vertexCount; ++v) {
      const bool any = in.u8() > 220;
      for (int a = 0; a < 3; ++a) vertices[v * 3 + a] = any ? in.f() : ((v >> a) & 1 ? 3.0f : -2.0f);
    }
    std::vector<uint32_t> indices(triangleCount * 3);
    for (auto& i : indices) i = in.u8() < 240 ? in.below(vertexCount ? vertexCount : 1) : in.count();
    const uint32_t materialCount = in.below(3);
    const char* names[3];
    for (uint32_t m = 0; m < materialCount; ++m) names[m] = materialName();
    std::vector<uint32_t> perTriangle(triangleCount);
    for (auto& t : perTriangle) t = in.u8() < 240 ? in.below(materialCount ? materialCount : 1) : in.count();
    float transform[12];
    const bool withTransform = in.u8() > 200;
    if (withTransform)
      for (float& t : transform) t = in.f();

    earshot_mesh_settings s;
    earshot_mesh_settings_init(&s);
    if (in.u8() > 250) s.struct_size = in.u32();
    s.name = in.u8() < 128 ? "fuzz_mesh" : (in.u8() < 128 ? nullptr : "door\r\n\x1b[2J");
    s.vertices = (vertexCount || in.u8() < 128) ? vertices.data() : nullptr;
    // Counts may understate the arrays (the API cannot tell), never overstate
    // them: reading past an array the caller sized is the caller's bug.
    s.vertex_count = in.u8() < 240 ? vertexCount : in.below(vertexCount + 1);
    s.indices = indices.data();
    s.triangle_count = in.u8() < 240 ? triangleCount : in.below(triangleCount + 1);
    s.material_names = materialCount ? names : nullptr;
    s.material_count = in.u8() < 240 ? materialCount : in.below(materialCount + 1);
    s.triangle_materials = in.u8() < 128 ? perTriangle.data() : nullptr;
    storeRaw(s.motion, in.u8() < 240 ? in.below(2) : in.count());
    s.transform = withTransform ? transform : nullptr;
    earshot_mesh* mesh = reinterpret_cast<earshot_mesh*>(uintptr_t(1));
    const earshot_status st = checked(earshot_mesh_create(context(), &s, &mesh));
    if (st == EARSHOT_OK) {
      CAPI_CHECK(mesh != nullptr);
      meshes.push_back(mesh);
    } else {
      CAPI_CHECK(mesh == nullptr);
    }
  }

  void fillSourceSettings(earshot_source_settings& s) {
    earshot_source_settings_init(&s);
    const uint8_t which = in.u8();
    if (which & 1) s.gain_db = in.f();
    if (which & 2) storeRaw(s.direct, in.count());
    if (which & 4) {
      s.direct_gain_db = in.f();
      s.reflections_gain_db = in.f();
    }
    if (which & 8) {
      storeRaw(s.distance_model, in.count());
      s.min_distance = in.f();
      s.max_distance = in.f();
      s.rolloff = in.f();
      s.distance_table_count = in.count();
      for (int i = 0; i < EARSHOT_DISTANCE_TABLE_POINTS; ++i) {
        s.distance_table_distance[i] = in.u8() < 200 ? float(i) : in.f();
        s.distance_table_gain[i] = in.f();
      }
    }
    if (which & 16) {
      storeRaw(s.occlusion, in.count());
      s.radius = in.f();
      s.transmission = int32_t(in.count());
      s.priority = int32_t(in.u32());
    }
    if (which & 32) {
      s.directivity_alpha = in.f();
      s.directivity_sharpness = in.f();
      s.directivity_per_band = int32_t(in.count());
      for (float& a : s.directivity_band_alpha) a = in.f();
    }
    if (which & 64) s.struct_size = in.count();
  }

  void createSource() {
    const int ci = int(in.below(2));
    earshot_source_settings s;
    fillSourceSettings(s);
    earshot_source* source = reinterpret_cast<earshot_source*>(uintptr_t(1));
    const bool withSettings = in.u8() < 240;
    // Created, or created where it is (earshot_source_create_at: any
    // position and forward, the default ones half the time).
    earshot_status st;
    if (in.u8() < 128) {
      st = checked(earshot_source_create(contexts().c[ci], withSettings ? &s : nullptr, &source));
    } else {
      const earshot_vec3 p = in.vec();
      const earshot_vec3 f = in.u8() < 128 ? earshot_vec3{0, 0, -1} : in.vec();
      st = checked(earshot_source_create_at(contexts().c[ci], withSettings ? &s : nullptr, p, f, &source));
    }
    if (st == EARSHOT_OK) {
      CAPI_CHECK(source != nullptr);
      uint32_t index = kMaxSources;
      CAPI_CHECK(earshot_source_get_index(source, &index) == EARSHOT_OK && index < kMaxSources);
      sources.push_back({source, ci, withSettings && s.direct == EARSHOT_DIRECT_IN_IMPULSE_RESPONSE});
    } else {
      CAPI_CHECK(source == nullptr);
    }
  }

  void process() {
    const int ci = int(in.below(2));
    size_t frames = in.u32() % (kMaxFrames + 1);
    if (frames % 4 != 3) frames = (frames % 3) * 64 + (frames / 3) % 3;  // mostly 0-2 blocks, give or take
    const size_t inputCount = in.u8() < 240 ? in.below(kMaxSources + 1) : in.count();
    const size_t realInputs = inputCount < kMaxSources ? inputCount : kMaxSources;
    // Each input: noise-like values, or silence with one sample of any value
    // (NaN, 3.4e38, ...), or NULL.
    std::vector<std::vector<float>> signals(realInputs, std::vector<float>(frames, 0.0f));
    std::vector<const float*> inputs(kMaxSources + 8, nullptr);
    for (size_t i = 0; i < realInputs; ++i) {
      const uint8_t kind = in.u8();
      for (size_t n = 0; n < frames; ++n) signals[i][n] = kind < 128 ? float((n * 2654435761u) % 1000) / 500.0f - 1.0f : 0.0f;
      if (frames && kind >= 128) {
        const uint32_t at = in.u32() % frames;
        signals[i][at] = in.f();
      }
      inputs[i] = kind == 255 ? nullptr : signals[i].data();
    }
    earshot_context_info info{};
    info.struct_size = sizeof(info);
    CAPI_CHECK(earshot_context_get_info(contexts().c[ci], &info) == EARSHOT_OK);
    const uint32_t channels = in.u8() < 240 ? info.output_channels : in.below(20);
    std::vector<std::vector<float>> out(channels < 16 ? channels : 16, std::vector<float>(frames + 1, 7.0f));
    std::vector<float*> outputs;
    for (auto& o : out) outputs.push_back(o.data());
    earshot_status st;
    // Only counts the program can back are passed: the API cannot know an
    // array's length, and reading past it is the caller's bug.
    const size_t passedInputs = inputCount <= inputs.size() ? inputCount : realInputs;
    if (ci == 0 && in.u8() < 128 && out.size() >= 2) {
      st = earshot_process(contexts().c[ci], passedInputs ? inputs.data() : nullptr, passedInputs, outputs[0],
                           outputs[1], frames);
    } else {
      st = earshot_process_channels(contexts().c[ci], passedInputs ? inputs.data() : nullptr, passedInputs,
                                    outputs.empty() ? nullptr : outputs.data(), outputs.size(), frames);
    }
    CAPI_CHECK(known(st) && st != EARSHOT_ERROR_INTERNAL);
    if (tracing()) std::fprintf(stderr, "  process %zu frames, %zu inputs, %zu outputs -> %s\n", frames, passedInputs,
                                outputs.size(), earshot_status_string(st));
    if (st == EARSHOT_OK) {
      for (auto& o : out) {
        for (size_t n = 0; n < frames; ++n) CAPI_CHECK(std::isfinite(o[n]));
        CAPI_CHECK(o[frames] == 7.0f);  // nothing written past `frames`
      }
    }
  }

  /** Reads an IR's layout and one channel. A source's IR (`fromSource`)
   *  has the context's channels (2 binaural; 4, AmbiX order 1, for the
   *  ambisonic context), a simulation number and an age; a computed one
   *  the request's channels, the direct sound and neither. */
  void readIr(earshot_ir* ir, uint32_t channels, bool fromSource, bool includesDirect) {
    earshot_ir_info info{};
    info.struct_size = sizeof(info);
    CAPI_CHECK(checked(earshot_ir_get_info(ir, &info)) == EARSHOT_OK);
    CAPI_CHECK(info.channels == channels);
    CAPI_CHECK(info.sample_rate_hz == kRate);
    CAPI_CHECK(info.frames >= 1 && info.frames <= uint64_t(kRate * 60));
    CAPI_CHECK(info.includes_direct == (includesDirect ? 1u : 0u));
    if (fromSource) {
      CAPI_CHECK(info.simulation >= 1 && std::isfinite(info.age_seconds) && info.age_seconds >= 0);
      CAPI_CHECK(info.frames <= uint64_t(kRate * 0.25) + 1);  // cut at max_ir_seconds
    } else {
      CAPI_CHECK(info.simulation == 0 && info.age_seconds == 0);
    }
    scratch.assign(size_t(info.frames) + 1, 7.0f);
    const uint32_t channel = in.u8() < 240 ? in.below(info.channels) : in.count();
    const uint64_t capacity = in.u8() < 240 ? info.frames : in.below(uint32_t(info.frames) + 1);
    if (checked(earshot_ir_copy_channel(ir, channel, scratch.data(), capacity)) == EARSHOT_OK) {
      for (size_t n = 0; n < info.frames; ++n) CAPI_CHECK(std::isfinite(scratch[n]));
      CAPI_CHECK(scratch[info.frames] == 7.0f);
    }
  }

  /** A scene, a box mesh in it and a source, each made with `c`'s allocator
   *  (which may refuse: OUT_OF_MEMORY and a NULL handle), then all dropped. */
  void madeWithAllocator(earshot_context* c) {
    earshot_scene* scene = reinterpret_cast<earshot_scene*>(uintptr_t(1));
    const earshot_status sceneStatus = checked(earshot_scene_create(c, nullptr, &scene));
    CAPI_CHECK(sceneStatus == EARSHOT_OK ? scene != nullptr : scene == nullptr);
    static const float kCorners[] = {0, 0, 0, 4, 0, 0, 0, 4, 0, 0, 0, 3};
    static const uint32_t kFaces[] = {0, 1, 2, 0, 1, 3, 0, 2, 3, 1, 2, 3};
    const char* names[] = {"concrete"};
    earshot_mesh_settings ms;
    earshot_mesh_settings_init(&ms);
    ms.vertices = kCorners;
    ms.vertex_count = 4;
    ms.indices = kFaces;
    ms.triangle_count = 4;
    ms.material_names = names;
    ms.material_count = 1;
    earshot_mesh* mesh = reinterpret_cast<earshot_mesh*>(uintptr_t(1));
    const earshot_status meshStatus = checked(earshot_mesh_create(c, &ms, &mesh));
    CAPI_CHECK(meshStatus == EARSHOT_OK ? mesh != nullptr : mesh == nullptr);
    if (scene && mesh) {
      checked(earshot_scene_add_mesh(scene, mesh));
      checked(earshot_scene_commit(scene));
      checked(earshot_context_set_scene(c, scene));
    }
    earshot_source* source = reinterpret_cast<earshot_source*>(uintptr_t(1));
    const earshot_status sourceStatus = checked(earshot_source_create(c, nullptr, &source));
    CAPI_CHECK(sourceStatus == EARSHOT_OK ? source != nullptr : source == nullptr);
    if (source) {
      checked(earshot_simulate(c, 0));
      CAPI_CHECK(earshot_source_release(source) == EARSHOT_OK);
    }
    if (mesh) CAPI_CHECK(earshot_mesh_release(mesh) == EARSHOT_OK);
    if (scene) CAPI_CHECK(earshot_scene_release(scene) == EARSHOT_OK);
  }

  void step() {
    const uint32_t op = in.below(27);
    if (tracing()) std::fprintf(stderr, "step %u\n", op);
    switch (op) {
      case 0: {
        earshot_scene_settings s;
        earshot_scene_settings_init(&s);
        const uint8_t sel = in.u8();
        if (sel > 240) s.materials_path = "/dev/zero";
        else if (sel > 230) s.materials_path = EARSHOT_FUZZ_SOURCE_DIR "/materials/no_such.json";
        else if (sel > 220) s.materials_path = EARSHOT_FUZZ_SOURCE_DIR "/tests/data/hrtf/Pulse.sofa";
        earshot_scene* scene = reinterpret_cast<earshot_scene*>(uintptr_t(1));
        earshot_context* c = context();
        const bool withSettings = in.u8() < 250;
        if (checked(earshot_scene_create(c, withSettings ? &s : nullptr, &scene)) == EARSHOT_OK) {
          CAPI_CHECK(scene != nullptr);
          scenes.push_back(scene);
        } else {
          CAPI_CHECK(scene == nullptr);
        }
        break;
      }
      case 1:
        if (!scenes.empty()) {
          const size_t i = in.below(uint32_t(scenes.size()));
          CAPI_CHECK(checked(earshot_scene_release(scenes[i])) == EARSHOT_OK);
          scenes.erase(scenes.begin() + long(i));
        }
        break;
      case 2: addMaterial(); break;
      case 3: createMesh(); break;
      case 4:
        if (!meshes.empty()) {
          const size_t i = in.below(uint32_t(meshes.size()));
          CAPI_CHECK(checked(earshot_mesh_release(meshes[i])) == EARSHOT_OK);
          meshes.erase(meshes.begin() + long(i));
        }
        break;
      case 5:
      case 6: {
        // Arguments are read one statement at a time: C++ leaves the order
        // of a call's arguments to the compiler, and replay runs gcc builds.
        const bool add = in.u8() < 160;
        earshot_scene* scene = pick(scenes);
        earshot_mesh* mesh = pick(meshes);
        checked(add ? earshot_scene_add_mesh(scene, mesh) : earshot_scene_remove_mesh(scene, mesh));
        break;
      }
      case 7: checked(earshot_scene_commit(pick(scenes))); break;
      case 8: {
        earshot_context* c = context();
        checked(earshot_context_set_scene(c, pick(scenes)));
        break;
      }
      case 9: {
        float m[16];
        for (float& v : m) v = in.u8() < 200 ? 0.0f : in.f();
        m[0] = m[5] = m[10] = in.u8() < 200 ? 1.0f : in.f();
        m[3] = in.f();
        const bool rowMajor = in.u8() < 128;
        earshot_mesh* mesh = pick(meshes);
        const bool withMatrix = in.u8() < 250;
        if (rowMajor)
          checked(earshot_mesh_set_transform(mesh, withMatrix ? m : nullptr));
        else
          checked(earshot_mesh_set_transform_4x4(mesh, m));
        float back[13];
        back[12] = 7.0f;
        if (checked(earshot_mesh_get_transform(pick(meshes), back)) == EARSHOT_OK) CAPI_CHECK(back[12] == 7.0f);
        break;
      }
      case 10: {
        earshot_mesh* mesh = pick(meshes);
        checked(earshot_mesh_set_material(mesh, materialName()));
        break;
      }
      case 11: createSource(); break;
      case 12:
        if (!sources.empty()) {
          const size_t i = pickSource();
          CAPI_CHECK(checked(earshot_source_release(sources[i].handle)) == EARSHOT_OK);
          sources.erase(sources.begin() + long(i));
        }
        break;
      case 13: {
        earshot_source* s = sources.empty() ? nullptr : sources[pickSource()].handle;
        switch (in.below(3)) {
          case 0: checked(earshot_source_set_position(s, in.vec())); break;
          case 1: checked(earshot_source_set_gain_db(s, in.f())); break;
          default: checked(earshot_source_set_orientation(s, in.vec())); break;
        }
        break;
      }
      case 14: {
        earshot_source* s = sources.empty() ? nullptr : sources[pickSource()].handle;
        earshot_source_settings settings;
        fillSourceSettings(settings);
        if (checked(earshot_source_set_settings(s, &settings)) == EARSHOT_OK) {
          earshot_source_settings back;
          earshot_source_settings_init(&back);
          CAPI_CHECK(earshot_source_get_settings(s, &back) == EARSHOT_OK);
          CAPI_CHECK(std::memcmp(&back.gain_db, &settings.gain_db, sizeof(float)) == 0);
        }
        break;
      }
      case 15: {
        const earshot_vec3 p = in.vec();
        const earshot_vec3 f = in.u8() < 128 ? earshot_vec3{0, 0, -1} : in.vec();
        const earshot_vec3 u = in.u8() < 128 ? earshot_vec3{0, 1, 0} : in.vec();
        checked(earshot_context_set_listener(context(), p, f, u));
        break;
      }
      case 16: {
        earshot_context* c = context();
        checked(earshot_simulate(c, in.count()));
        // Every source's occlusion: whole and in range, simulated or not.
        for (const Source& held : sources) {
          earshot_source_occlusion o;
          o.struct_size = sizeof(o);
          CAPI_CHECK(checked(earshot_source_get_occlusion(held.handle, &o)) == EARSHOT_OK);
          bool any = false;
          for (float t : o.transmission) {
            CAPI_CHECK(t >= 0.0f && t <= 1.0f);  // sqrt of a product of transmissions <= 1, or of a mean of such
            any = any || t > 0.0f;
          }
          // (A band of 1e-50 through many surfaces is 0 as a float.)
          CAPI_CHECK(o.audible <= 1u && (!any || o.audible == 1u));
          CAPI_CHECK(o.simulated <= 1u);
        }
        break;
      }
      case 17:
      case 18: process(); break;
      case 19: {
        const Source* held = sources.empty() ? nullptr : &sources[pickSource()];
        earshot_ir* ir = reinterpret_cast<earshot_ir*>(uintptr_t(1));
        if (checked(earshot_source_get_ir(held ? held->handle : nullptr, &ir)) == EARSHOT_OK) {
          CAPI_CHECK(ir != nullptr && held != nullptr);
          readIr(ir, held->context == 0 ? 2 : 4, true, held->directInIr);
          irs.push_back(ir);
        }
        break;
      }
      case 20: {
        earshot_ir_request r;
        earshot_ir_request_init(&r);
        const uint8_t which = in.u8();
        if (which & 1) r.source = in.vec();
        if (which & 2) r.listener = in.vec();
        if (which & 4) r.forward = in.vec();
        if (which & 8) r.up = in.vec();
        if (which & 16) storeRaw(r.receiver, in.count());
        if (which & 32) r.seed = in.u32();
        if (which & 64) r.ambisonic_order = in.count();
        if (which & 128) r.struct_size = in.count();
        earshot_ir* ir = reinterpret_cast<earshot_ir*>(uintptr_t(1));
        if (checked(earshot_context_compute_ir(context(), &r, &ir)) == EARSHOT_OK) {
          CAPI_CHECK(ir != nullptr);
          const uint32_t channels = r.receiver == EARSHOT_RECEIVER_OMNI       ? 1
                                    : r.receiver == EARSHOT_RECEIVER_BINAURAL ? 2
                                    : (r.ambisonic_order + 1) * (r.ambisonic_order + 1);
          readIr(ir, channels, false, true);
          irs.push_back(ir);
        } else {
          CAPI_CHECK(ir == nullptr);
        }
        break;
      }
      case 21: {
        const char* names[] = {"fuzz_mesh", "door", "", nullptr, "shoebox.gltf"};
        earshot_mesh* found = nullptr;
        earshot_scene* scene = pick(scenes);
        const char* name = names[in.below(5)];
        if (checked(earshot_scene_find_mesh(scene, name, &found)) == EARSHOT_OK) {
          CAPI_CHECK(found != nullptr);
          meshes.push_back(found);  // a new reference, released at the end
        }
        break;
      }
      case 22: {
        earshot_gltf_settings g;
        earshot_gltf_settings_init(&g);
        const char* movable[] = {"room", "no such node", ""};
        g.path = in.u8() < 200 ? EARSHOT_FUZZ_SOURCE_DIR "/samples/shoebox/shoebox.gltf" : "/dev/zero";
        g.material_map_path = in.u8() < 128 ? nullptr : EARSHOT_FUZZ_SOURCE_DIR "/samples/shoebox/materials_map.json";
        g.movable_node_count = in.below(4);
        g.movable_node_names = g.movable_node_count ? movable : nullptr;
        if (g.movable_node_count > 3) g.movable_node_count = 3;
        if (in.u8() > 240) g.max_memory_bytes = in.count();
        checked(earshot_scene_load_gltf(pick(scenes), &g));
        break;
      }
      case 23: {
        earshot_context_info info{};
        info.struct_size = in.u8() < 250 ? sizeof(info) : in.count();
        checked(earshot_context_get_info(context(), &info));
        earshot_scene_stats stats{};
        stats.struct_size = sizeof(stats);
        checked(earshot_scene_get_stats(pick(scenes), &stats));
        break;
      }
      case 24: {
        // A context of any settings, made and dropped (no source: its HRTF
        // is loaded only in the background, from the cache when valid).
        earshot_context_settings s;
        earshot_context_settings_init(&s);
        s.sample_rate_hz = in.u8() < 200 ? kRate : in.d();
        s.block_frames = in.u8() < 200 ? 64 : in.count();
        s.max_sources = in.u8() < 200 ? 2 : in.count();
        s.max_ir_seconds = in.u8() < 200 ? 0.25 : in.d();
        s.rays = in.u8() < 200 ? 64 : in.count();
        s.bounces = in.u8() < 200 ? 4 : in.count();
        s.image_source_order = in.count();
        s.threads = in.u8() < 200 ? 1 : in.count();
        s.max_distance_meters = in.u8() < 200 ? 50 : in.d();
        s.ambisonic_order = in.count();
        storeRaw(s.output_format, in.count());
        storeRaw(s.trace_mode, in.count());
        const uint8_t hrtf = in.u8();
        s.hrtf_path = hrtf < 200   ? EARSHOT_FUZZ_SOURCE_DIR "/tests/data/hrtf/Pulse.sofa"
                      : hrtf < 220 ? "/dev/zero"
                      : hrtf < 240 ? EARSHOT_FUZZ_SOURCE_DIR "/tests/data/hrtf/not_sofa.sofa"
                                   : "no/such/file.sofa";
        if (in.u8() > 250) s.struct_size = in.count();
        // Pulse.sofa at another rate would be prepared afresh (tens of seconds
        // under ASan, and release waits for it): a file that fails fast instead.
        if (s.sample_rate_hz != kRate && hrtf < 200)
          s.hrtf_path = EARSHOT_FUZZ_SOURCE_DIR "/tests/data/hrtf/not_sofa.sofa";
        // Sometimes with an allocator that fails after a few handles: then a
        // scene, a mesh and a source are made with it and all dropped, and
        // the allocator must hold nothing at the end.
        FailingAllocator alloc;
        const bool withAllocator = in.u8() > 160;
        if (withAllocator) {
          alloc.allowed = int(in.below(5));
          s.allocate = &FailingAllocator::allocate;
          s.free = &FailingAllocator::release;
          s.allocator_user_data = &alloc;
        }
        earshot_context* c = reinterpret_cast<earshot_context*>(uintptr_t(1));
        if (checked(earshot_context_create(&s, &c)) == EARSHOT_OK) {
          CAPI_CHECK(c != nullptr);
          if (withAllocator) madeWithAllocator(c);
          CAPI_CHECK(earshot_context_release(c) == EARSHOT_OK);
        } else {
          CAPI_CHECK(c == nullptr);
        }
        CAPI_CHECK(alloc.live == 0);
        break;
      }
      case 26: {
        // The built-in simulation thread at any rate, audio blocks while it
        // runs, then stopped (the step's threads make this op's timing, not
        // its checks, vary between runs).
        earshot_context* c = context();
        const double rate = in.u8() < 200 ? double(1 + in.below(200)) : in.d();
        const uint32_t perStep = in.count();
        if (checked(earshot_context_start_simulation(c, rate, perStep)) == EARSHOT_OK) {
          const uint32_t blocks = in.below(4);
          for (uint32_t b = 0; b < blocks; ++b) process();
          CAPI_CHECK(checked(earshot_simulate(c, 0)) == EARSHOT_ERROR_INVALID_STATE);
          CAPI_CHECK(checked(earshot_context_stop_simulation(c)) == EARSHOT_OK);
        }
        break;
      }
      default: {
        static const uint64_t kLimits[] = {0, 1, 1u << 20, 64u << 20, 256u << 20};
        checked(earshot_set_memory_limit(kLimits[in.below(5)]));
        break;
      }
    }
  }

  void checkSourceCounts() {
    for (int ci = 0; ci < 2; ++ci) {
      uint32_t held = 0;
      for (const auto& s : sources) held += s.context == ci ? 1 : 0;
      earshot_context_info info{};
      info.struct_size = sizeof(info);
      CAPI_CHECK(earshot_context_get_info(contexts().c[ci], &info) == EARSHOT_OK);
      CAPI_CHECK(info.active_sources == held);
    }
  }

  ~Program() {
    for (earshot_ir* ir : irs) CAPI_CHECK(earshot_ir_release(ir) == EARSHOT_OK);
    for (const auto& s : sources) CAPI_CHECK(earshot_source_release(s.handle) == EARSHOT_OK);
    for (earshot_mesh* m : meshes) CAPI_CHECK(earshot_mesh_release(m) == EARSHOT_OK);
    for (int ci = 0; ci < 2; ++ci) CAPI_CHECK(earshot_context_set_scene(contexts().c[ci], nullptr) == EARSHOT_OK);
    for (earshot_scene* s : scenes) CAPI_CHECK(earshot_scene_release(s) == EARSHOT_OK);
  }
};

}  // namespace

// libFuzzer calls this once before any input (the replay driver does not;
// there the first input makes the contexts): the contexts' HRTF is prepared
// here, outside the per-input timeout (a cold cache takes ~15 s under
// coverage and ASan, more on a busy machine).
extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  for (earshot_context* c : contexts().c) {
    earshot_source* s = nullptr;
    CAPI_CHECK(earshot_source_create(c, nullptr, &s) == EARSHOT_OK);  // waits for the HRTF
    CAPI_CHECK(earshot_source_release(s) == EARSHOT_OK);
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Contexts& all = contexts();
  CAPI_CHECK(earshot_set_memory_limit(256u << 20) == EARSHOT_OK);
  const earshot_vec3 origin{0, 0, 0}, forward{0, 0, -1}, up{0, 1, 0};
  for (earshot_context* c : all.c) CAPI_CHECK(earshot_context_set_listener(c, origin, forward, up) == EARSHOT_OK);
  Bytes in(data, size);
  {
    Program program(in);
    for (size_t step = 0; step < kMaxSteps && !in.done(); ++step) {
      program.step();
      program.checkSourceCounts();
    }
  }
  for (earshot_context* c : all.c) {
    earshot_context_info info{};
    info.struct_size = sizeof(info);
    CAPI_CHECK(earshot_context_get_info(c, &info) == EARSHOT_OK && info.active_sources == 0);
  }
  return 0;
}
