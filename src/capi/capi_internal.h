#pragma once
// The C API's objects and the helpers every entry point uses: handle checks,
// the user's allocator, error reporting (last error, log callback) and the
// exception barrier. Private to src/capi.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/earshot.h"
#include "earshot/materials/material.h"
#include "earshot/runtime/engine.h"
#include "earshot/scene/dynamic_scene.h"

namespace earshot::capi {

/** Tags in the first word of every handle: catch a handle of the wrong type
 *  (or a pointer that is no handle at all, most of the time). */
enum class Kind : uint32_t {
  kContext = 0x43545845,  // "EXTC"
  kScene = 0x4e435345,    // "ESCN"
  kMesh = 0x48534d45,     // "EMSH"
  kSource = 0x43525345,   // "ESRC"
  kIr = 0x52494945,       // "EIIR"
  kDead = 0xdeaddead,
};

/** What every object inherits from its context: the log, the allocator and
 *  the validation flag. Plain data, copied into each handle. */
struct Env {
  earshot_log_callback log = nullptr;
  void* logUser = nullptr;
  earshot_log_level level = EARSHOT_LOG_WARNING;
  earshot_allocate_callback allocate = nullptr;
  earshot_free_callback free = nullptr;
  void* allocUser = nullptr;
  bool validation = false;

  void* allocateBytes(size_t size, size_t alignment) const;
  void freeBytes(void* p) const;
  /** Calls the log callback if set and `level` is enabled; never throws. */
  void logMessage(earshot_log_level level, const std::string& message) const noexcept;
};

struct Object {
  explicit Object(Kind k, const Env& e) : kind(k), env(e) {}
  Kind kind;
  std::atomic<uint32_t> refs{1};
  Env env;
};

/** Constructs a T in memory from env's allocator. Throws std::bad_alloc. */
template <class T, class... Args>
T* create(const Env& env, Args&&... args) {
  void* p = env.allocateBytes(sizeof(T), alignof(T));
  if (!p) throw std::bad_alloc();
  try {
    return new (p) T(env, std::forward<Args>(args)...);
  } catch (...) {
    env.freeBytes(p);
    throw;
  }
}

/** Destroys and frees an object made by create(). */
template <class T>
void destroy(T* object) {
  const Env env = object->env;
  object->~T();
  // The tag lives in memory being freed; the store only helps the common
  // case of a stale handle whose memory is not reused yet.
  reinterpret_cast<Object*>(object)->kind = Kind::kDead;
  env.freeBytes(object);
}

/** The handle's tag matches T (false for NULL). */
template <class T>
bool alive(const T* object) {
  return object != nullptr && object->kind == T::kKind;
}

// ---- errors ----

/** Records `message` as the thread's last error ("fn: message") and returns `code`. */
earshot_status fail(const Env* env, const char* fn, earshot_status code, const std::string& message) noexcept;
/** An invalid argument: recorded, and logged only when validation is on. */
earshot_status argError(const Env* env, const char* fn, const std::string& message) noexcept;
/** The same for a literal: callable outside guard() (nothing allocated before the call). */
earshot_status argError(const Env* env, const char* fn, const char* message) noexcept;
/** Maps a library Status to the C status (recording and logging failures). */
earshot_status fromStatus(const Env* env, const char* fn, const Status& status) noexcept;
earshot_status toCode(StatusCode code);

/** Runs `body` and turns any exception into a status: the barrier at every
 *  entry point. */
template <class F>
earshot_status guard(const Env* env, const char* fn, F&& body) noexcept {
  try {
    return body();
  } catch (const std::bad_alloc&) {
    return fail(env, fn, EARSHOT_ERROR_OUT_OF_MEMORY, "out of memory");
  } catch (const std::exception& e) {
    return fail(env, fn, EARSHOT_ERROR_INTERNAL, std::string("unexpected exception: ") + e.what());
  } catch (...) {
    return fail(env, fn, EARSHOT_ERROR_INTERNAL, "unexpected exception");
  }
}

/** The struct_size check of every settings struct: "" when `got` is
 *  `expected`, else "name->struct_size got is not expected". */
std::string checkStructSize(uint32_t got, size_t expected, const char* name);

/** The integer a C caller stored in an enum field or argument. C allows any
 *  int there; reading it as the C++ enum type would be undefined for values
 *  outside the enumerators, so read its bytes. */
template <class E>
int64_t rawEnum(const E& value) {
  std::underlying_type_t<E> raw;
  static_assert(sizeof(raw) == sizeof(E));
  std::memcpy(&raw, &value, sizeof(raw));
  return int64_t(raw);
}

/** "name is NaN" style checks: the problem, or "" when the value is fine. */
std::string checkFinite(double v, const char* name);
std::string checkVec3(const earshot_vec3& v, const char* name);
/** A number as text for messages (%g). */
std::string describe(double v);

}  // namespace earshot::capi

// ---- the handles (global names: the C header declares them) ----

struct earshot_scene;

struct earshot_context : earshot::capi::Object {
  static constexpr earshot::capi::Kind kKind = earshot::capi::Kind::kContext;
  explicit earshot_context(const earshot::capi::Env& e) : Object(kKind, e) {}
  ~earshot_context();

  std::unique_ptr<earshot::runtime::Engine> engine;
  double sampleRateHz = 0;
  uint32_t blockFrames = 0;
  uint32_t maxSources = 0;
  std::vector<const float*> inputs;  // audio thread scratch: one pointer per slot

  std::mutex sourcesMutex;  // source create/release (the engine's slot search is not synchronised)
  uint32_t activeSources = 0;

  // The scene followed, and the snapshot the engine has (guarded by sceneMutex).
  std::mutex sceneMutex;
  earshot_scene* scene = nullptr;  // holds a reference
  uint64_t appliedVersion = 0;
  bool appliedAny = false;

  // Simulation steps (earshot_simulate and the built-in thread) one at a time.
  std::mutex stepMutex;
  uint32_t lastStepSources = 0;
  double lastStepMs = 0;

  // The built-in simulation thread.
  std::mutex threadControl;  // start/stop
  std::mutex threadMutex;    // guards stop and the wait
  std::condition_variable threadWake;
  std::thread thread;
  bool threadStop = false;
  std::atomic<bool> threadRunning{false};
};

struct earshot_scene : earshot::capi::Object {
  static constexpr earshot::capi::Kind kKind = earshot::capi::Kind::kScene;
  explicit earshot_scene(const earshot::capi::Env& e) : Object(kKind, e) {}
  ~earshot_scene();

  std::unique_ptr<earshot::DynamicScene> dynamic;
  std::shared_ptr<const earshot::MaterialTable> materials;  // replaced (copied) on add_material
  std::vector<earshot_mesh*> meshes;                        // in the scene, each holding a reference

  // What commit() published, read by the contexts' simulation steps.
  std::mutex publishMutex;
  uint64_t version = 0;  // 0: never committed
  std::shared_ptr<const earshot::RayTracer> snapshot;
  std::shared_ptr<const earshot::MaterialTable> snapshotMaterials;
};

struct earshot_mesh : earshot::capi::Object {
  static constexpr earshot::capi::Kind kKind = earshot::capi::Kind::kMesh;
  explicit earshot_mesh(const earshot::capi::Env& e) : Object(kKind, e) {}

  std::string name;
  bool hasData = false;                  // false: made by a glTF load (the triangles live in the scene only)
  earshot::TriangleMesh data;            // own frame; materialIds index `materialNames`
  std::vector<std::string> materialNames;
  std::string overrideMaterial;          // set_material before the mesh is in a scene ("" none)
  earshot::MeshMotion motion = earshot::MeshMotion::kStatic;
  earshot::AffineTransform transform;
  earshot_scene* scene = nullptr;        // not owned: the scene holding it, if any
  earshot::MeshId id = 0;
};

struct earshot_source : earshot::capi::Object {
  static constexpr earshot::capi::Kind kKind = earshot::capi::Kind::kSource;
  explicit earshot_source(const earshot::capi::Env& e) : Object(kKind, e) {}

  earshot_context* context = nullptr;  // holds a reference
  uint32_t slot = 0;
};

struct earshot_ir : earshot::capi::Object {
  static constexpr earshot::capi::Kind kKind = earshot::capi::Kind::kIr;
  explicit earshot_ir(const earshot::capi::Env& e) : Object(kKind, e) {}

  std::shared_ptr<const earshot::AudioBuffer> ir;  // never modified
  bool includesDirect = false;
  uint64_t simulation = 0;
  std::chrono::steady_clock::time_point posed{};  // a source's IR: when its poses were read
};

namespace earshot::capi {
/** `_retain` of every handle type: one more reference, or an argument error. */
template <class T>
earshot_status retainHandle(T* object, const char* fn, const char* what) {
  return guard(nullptr, fn, [&]() -> earshot_status {
    if (!alive(object)) return argError(nullptr, fn, std::string(what) + " is not a live handle of its type");
    object->refs.fetch_add(1, std::memory_order_relaxed);
    return EARSHOT_OK;
  });
}

/** `_release` of a handle type whose last reference needs nothing but `drop`. */
template <class T>
earshot_status releaseHandle(T* object, const char* fn, const char* what, void (*drop)(T*)) {
  return guard(nullptr, fn, [&]() -> earshot_status {
    if (!alive(object)) return argError(nullptr, fn, std::string(what) + " is not a live handle of its type");
    drop(object);
    return EARSHOT_OK;
  });
}

/** Drops one reference of each kind (destroying at zero). */
void releaseContext(earshot_context* c);
void releaseScene(earshot_scene* s);
void releaseMesh(earshot_mesh* m);
}  // namespace earshot::capi
