#pragma once
/** @file earshot's C++ API: a thin, header-only RAII layer over the C API
 *  (earshot.h), which stays the one source of truth: every method calls
 *  exactly the C function of the same name, with the same units, ranges and
 *  threading rules (read them there).
 *
 *  Handles. Context, Scene, Mesh and Source each own one reference to their
 *  C object: copying retains (both copies name the same object), moving
 *  transfers, destruction releases. A default-constructed handle is empty
 *  (operator bool is false) and every method on it throws. get() gives the
 *  C handle (not owned) for mixing both APIs.
 *
 *  Errors. Methods throw earshot::Error (status() and what(): the C layer's
 *  message) when the C call fails. The exception is C++-side only: nothing
 *  throws inside the library. The one exception to throwing is
 *  Context::process(), for the audio thread: it is noexcept and returns the
 *  status.
 *
 *  Views. Span<T> is a pointer and a size (C++17 stand-in for std::span),
 *  made implicitly from std::vector, std::array, C arrays or a pointer and a
 *  count; it never owns. */
#include <array>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "earshot/earshot.h"

namespace earshot {

/** What a failed call throws: the C status and the message explaining it. */
class Error : public std::runtime_error {
 public:
  Error(earshot_status status, const std::string& message)
      : std::runtime_error(message.empty() ? std::string(earshot_status_string(status)) : message),
        mStatus(status) {}
  earshot_status status() const noexcept { return mStatus; }

 private:
  earshot_status mStatus;
};

/** Throws Error unless `status` is EARSHOT_OK. */
inline void check(earshot_status status) {
  if (status != EARSHOT_OK) throw Error(status, earshot_last_error_message());
}

/** A non-owning view of `size()` contiguous T. */
template <class T>
class Span {
 public:
  constexpr Span() noexcept = default;
  constexpr Span(T* data, size_t size) noexcept : mData(data), mSize(size) {}
  template <class U, size_t N, class = std::enable_if_t<std::is_convertible_v<U (*)[], T (*)[]>>>
  constexpr Span(U (&array)[N]) noexcept : mData(array), mSize(N) {}  // NOLINT: implicit on purpose
  template <class U, size_t N, class = std::enable_if_t<std::is_convertible_v<U (*)[], T (*)[]>>>
  constexpr Span(std::array<U, N>& a) noexcept : mData(a.data()), mSize(N) {}  // NOLINT
  template <class U, size_t N, class = std::enable_if_t<std::is_convertible_v<const U (*)[], T (*)[]>>>
  constexpr Span(const std::array<U, N>& a) noexcept : mData(a.data()), mSize(N) {}  // NOLINT
  template <class U, class A, class = std::enable_if_t<std::is_convertible_v<U (*)[], T (*)[]>>>
  Span(std::vector<U, A>& v) noexcept : mData(v.data()), mSize(v.size()) {}  // NOLINT
  template <class U, class A, class = std::enable_if_t<std::is_convertible_v<const U (*)[], T (*)[]>>>
  Span(const std::vector<U, A>& v) noexcept : mData(v.data()), mSize(v.size()) {}  // NOLINT
  constexpr Span(std::initializer_list<std::remove_const_t<T>> list) noexcept  // for const T only
      : mData(list.begin()), mSize(list.size()) {}

  constexpr T* data() const noexcept { return mData; }
  constexpr size_t size() const noexcept { return mSize; }
  constexpr bool empty() const noexcept { return mSize == 0; }
  constexpr T& operator[](size_t i) const noexcept { return mData[i]; }
  constexpr T* begin() const noexcept { return mData; }
  constexpr T* end() const noexcept { return mData + mSize; }

 private:
  T* mData = nullptr;
  size_t mSize = 0;
};

inline earshot_vec3 vec3(float x, float y, float z) { return earshot_vec3{x, y, z}; }

namespace detail {

/** One reference to a C object; Retain/Release are its C functions. */
template <class H, earshot_status (*Retain)(H*), earshot_status (*Release)(H*)>
class Handle {
 public:
  Handle() noexcept = default;
  /** Takes over one reference the caller holds. */
  explicit Handle(H* adopted) noexcept : mHandle(adopted) {}
  Handle(const Handle& o) noexcept : mHandle(o.mHandle) {
    if (mHandle) (void)Retain(mHandle);
  }
  Handle(Handle&& o) noexcept : mHandle(std::exchange(o.mHandle, nullptr)) {}
  Handle& operator=(Handle o) noexcept {
    std::swap(mHandle, o.mHandle);
    return *this;
  }
  ~Handle() {
    if (mHandle) (void)Release(mHandle);
  }
  /** The C handle (not owned; valid while this holds it). */
  H* get() const noexcept { return mHandle; }
  explicit operator bool() const noexcept { return mHandle != nullptr; }
  /** Drops the reference now; the handle becomes empty. */
  void reset() noexcept { Handle().swap(*this); }
  void swap(Handle& o) noexcept { std::swap(mHandle, o.mHandle); }

 protected:
  H* checked() const {
    if (!mHandle) throw Error(EARSHOT_ERROR_INVALID_ARGUMENT, "earshot: use of an empty handle");
    return mHandle;
  }

 private:
  H* mHandle = nullptr;
};

}  // namespace detail

class Scene;

/** Settings with the C defaults filled in; edit fields, then pass them on. */
struct ContextSettings : earshot_context_settings {
  ContextSettings() noexcept : earshot_context_settings() { earshot_context_settings_init(this); }
};
struct SceneSettings : earshot_scene_settings {
  SceneSettings() noexcept : earshot_scene_settings() { earshot_scene_settings_init(this); }
};
struct SourceSettings : earshot_source_settings {
  SourceSettings() noexcept : earshot_source_settings() { earshot_source_settings_init(this); }
};

struct IrRequest : earshot_ir_request {
  IrRequest() noexcept : earshot_ir_request() { earshot_ir_request_init(this); }
};

/** An immutable impulse response (earshot_ir_*): channels() planar float
 *  channels of frames() samples at sampleRateHz(). Any thread. */
class Ir : public detail::Handle<earshot_ir, earshot_ir_retain, earshot_ir_release> {
 public:
  Ir() noexcept = default;
  static Ir adopt(earshot_ir* adopted) noexcept { return Ir(adopted); }
  earshot_ir_info info() const {
    earshot_ir_info i{};
    i.struct_size = sizeof(i);
    check(earshot_ir_get_info(checked(), &i));
    return i;
  }
  uint32_t channels() const { return info().channels; }
  uint64_t frames() const { return info().frames; }
  double sampleRateHz() const { return info().sample_rate_hz; }
  /** A copy of one channel. */
  std::vector<float> channel(uint32_t index) const {
    std::vector<float> out(static_cast<size_t>(frames()));
    check(earshot_ir_copy_channel(checked(), index, out.data(), out.size()));
    return out;
  }

 private:
  explicit Ir(earshot_ir* adopted) noexcept : Handle(adopted) {}
};

/** The engine (earshot_context_*). */
class Context : public detail::Handle<earshot_context, earshot_context_retain, earshot_context_release> {
 public:
  Context() noexcept = default;
  /** earshot_context_create. */
  explicit Context(const earshot_context_settings& settings) : Handle(make(settings)) {}
  /** Takes over one reference to `adopted`. */
  static Context adopt(earshot_context* adopted) noexcept { return Context(adopted); }

  earshot_context_info info() const {
    earshot_context_info i{};
    i.struct_size = sizeof(i);
    check(earshot_context_get_info(checked(), &i));
    return i;
  }
  void setListener(earshot_vec3 position, earshot_vec3 forward, earshot_vec3 up) {
    check(earshot_context_set_listener(checked(), position, forward, up));
  }
  /** earshot_context_set_scene; an empty Scene means free field. */
  inline void setScene(const Scene& scene);
  void simulate(uint32_t sourceCount = 0) { check(earshot_simulate(checked(), sourceCount)); }
  void startSimulation(double rateHz, uint32_t sourcesPerStep = 0) {
    check(earshot_context_start_simulation(checked(), rateHz, sourcesPerStep));
  }
  void stopSimulation() { check(earshot_context_stop_simulation(checked())); }
  /** earshot_context_compute_ir: the complete IR of one pair, as `earshot ir`. */
  Ir computeIr(const earshot_ir_request& request) const {
    earshot_ir* ir = nullptr;
    check(earshot_context_compute_ir(checked(), &request, &ir));
    return Ir::adopt(ir);
  }
  /** Audio thread: earshot_process; never throws, returns the status.
   *  inputs[i] is the source with index i (Source::index()). */
  earshot_status process(Span<const float* const> inputs, float* left, float* right, size_t frames) noexcept {
    return earshot_process(get(), inputs.data(), inputs.size(), left, right, frames);
  }
  /** Audio thread: earshot_process_channels (binaural or ambisonic output);
   *  outputs.size() must be Info::output_channels. */
  earshot_status process(Span<const float* const> inputs, Span<float* const> outputs, size_t frames) noexcept {
    return earshot_process_channels(get(), inputs.data(), inputs.size(), outputs.data(), outputs.size(), frames);
  }

 private:
  explicit Context(earshot_context* adopted) noexcept : Handle(adopted) {}
  static earshot_context* make(const earshot_context_settings& settings) {
    earshot_context* c = nullptr;
    check(earshot_context_create(&settings, &c));
    return c;
  }
};

/** Triangles with materials and a transform (earshot_mesh_*). */
class Mesh : public detail::Handle<earshot_mesh, earshot_mesh_retain, earshot_mesh_release> {
 public:
  using Matrix3x4 = std::array<float, 12>;  ///< row-major, element [r * 4 + c]

  Mesh() noexcept = default;
  /** earshot_mesh_create: `vertices` x, y, z per vertex (metres), `indices`
   *  three per triangle, `materials` names (at least one), `triangleMaterials`
   *  one index into `materials` per triangle (empty: all use materials[0]). */
  Mesh(const Context& context, Span<const float> vertices, Span<const uint32_t> indices,
       const std::vector<std::string>& materials, Span<const uint32_t> triangleMaterials = {},
       earshot_mesh_motion motion = EARSHOT_MESH_STATIC, const std::string& name = "")
      : Handle(make(context, vertices, indices, materials, triangleMaterials, motion, name)) {}
  static Mesh adopt(earshot_mesh* adopted) noexcept { return Mesh(adopted); }

  void setTransform(const Matrix3x4& rowMajor3x4) { check(earshot_mesh_set_transform(checked(), rowMajor3x4.data())); }
  /** Column-major 4x4 (glTF, OpenGL). */
  void setTransform4x4(const std::array<float, 16>& columnMajor) {
    check(earshot_mesh_set_transform_4x4(checked(), columnMajor.data()));
  }
  Matrix3x4 transform() const {
    Matrix3x4 m{};
    check(earshot_mesh_get_transform(checked(), m.data()));
    return m;
  }
  void setMaterial(const std::string& name) { check(earshot_mesh_set_material(checked(), name.c_str())); }

 private:
  explicit Mesh(earshot_mesh* adopted) noexcept : Handle(adopted) {}
  static earshot_mesh* make(const Context& context, Span<const float> vertices, Span<const uint32_t> indices,
                            const std::vector<std::string>& materials, Span<const uint32_t> triangleMaterials,
                            earshot_mesh_motion motion, const std::string& name) {
    if (vertices.size() % 3 != 0 || indices.size() % 3 != 0)
      throw Error(EARSHOT_ERROR_INVALID_ARGUMENT, "earshot::Mesh: vertices and indices must come in threes");
    if (!triangleMaterials.empty() && triangleMaterials.size() != indices.size() / 3)
      throw Error(EARSHOT_ERROR_INVALID_ARGUMENT, "earshot::Mesh: triangleMaterials needs one entry per triangle");
    std::vector<const char*> names;
    for (const std::string& m : materials) names.push_back(m.c_str());
    earshot_mesh_settings s;
    earshot_mesh_settings_init(&s);
    s.name = name.c_str();
    s.vertices = vertices.data();
    s.vertex_count = vertices.size() / 3;
    s.indices = indices.data();
    s.triangle_count = indices.size() / 3;
    s.material_names = names.data();
    s.material_count = names.size();
    s.triangle_materials = triangleMaterials.empty() ? nullptr : triangleMaterials.data();
    s.motion = motion;
    earshot_mesh* m = nullptr;
    check(earshot_mesh_create(context.get(), &s, &m));
    return m;
  }
};

/** Editable geometry and materials (earshot_scene_*). */
class Scene : public detail::Handle<earshot_scene, earshot_scene_retain, earshot_scene_release> {
 public:
  Scene() noexcept = default;
  /** earshot_scene_create with `settings` (default: earshot's materials). */
  explicit Scene(const Context& context, const earshot_scene_settings& settings = SceneSettings())
      : Handle(make(context, settings)) {}
  static Scene adopt(earshot_scene* adopted) noexcept { return Scene(adopted); }

  void addMaterial(const earshot_material& material) { check(earshot_scene_add_material(checked(), &material)); }
  void add(const Mesh& mesh) { check(earshot_scene_add_mesh(checked(), mesh.get())); }
  void remove(const Mesh& mesh) { check(earshot_scene_remove_mesh(checked(), mesh.get())); }
  void commit() { check(earshot_scene_commit(checked())); }
  /** earshot_scene_load_gltf; `materialMapPath` "" = none. */
  void loadGltf(const std::string& path, const std::string& materialMapPath = "",
                const std::vector<std::string>& movableNodes = {}) {
    std::vector<const char*> names;
    for (const std::string& n : movableNodes) names.push_back(n.c_str());
    earshot_gltf_settings s;
    earshot_gltf_settings_init(&s);
    s.path = path.c_str();
    s.material_map_path = materialMapPath.empty() ? nullptr : materialMapPath.c_str();
    s.movable_node_names = names.data();
    s.movable_node_count = names.size();
    check(earshot_scene_load_gltf(checked(), &s));
  }
  Mesh findMesh(const std::string& name) const {
    earshot_mesh* m = nullptr;
    check(earshot_scene_find_mesh(checked(), name.c_str(), &m));
    return Mesh::adopt(m);
  }
  earshot_scene_stats stats() const {
    earshot_scene_stats s{};
    s.struct_size = sizeof(s);
    check(earshot_scene_get_stats(checked(), &s));
    return s;
  }

 private:
  explicit Scene(earshot_scene* adopted) noexcept : Handle(adopted) {}
  static earshot_scene* make(const Context& context, const earshot_scene_settings& settings) {
    earshot_scene* s = nullptr;
    check(earshot_scene_create(context.get(), &settings, &s));
    return s;
  }
};

inline void Context::setScene(const Scene& scene) { check(earshot_context_set_scene(checked(), scene.get())); }

/** A sound source (earshot_source_*). */
class Source : public detail::Handle<earshot_source, earshot_source_retain, earshot_source_release> {
 public:
  Source() noexcept = default;
  explicit Source(const Context& context, const earshot_source_settings& settings = SourceSettings())
      : Handle(make(context, settings)) {}
  /** earshot_source_create_at: created where it is (forward: its facing). */
  Source(const Context& context, earshot_vec3 position, earshot_vec3 forward = {0, 0, -1},
         const earshot_source_settings& settings = SourceSettings())
      : Handle(makeAt(context, settings, position, forward)) {}
  static Source adopt(earshot_source* adopted) noexcept { return Source(adopted); }

  /** Slot index: the position of this source's input in Context::process. */
  uint32_t index() const {
    uint32_t i = 0;
    check(earshot_source_get_index(checked(), &i));
    return i;
  }
  void setPosition(earshot_vec3 position) { check(earshot_source_set_position(checked(), position)); }
  void setGainDb(float gainDb) { check(earshot_source_set_gain_db(checked(), gainDb)); }
  void setOrientation(earshot_vec3 forward) { check(earshot_source_set_orientation(checked(), forward)); }
  /** earshot_source_get_settings / _set_settings: the source's controls
   *  (gains, distance curve, occlusion, transmission, priority). */
  SourceSettings settings() const {
    SourceSettings s;
    check(earshot_source_get_settings(checked(), &s));
    return s;
  }
  void setSettings(const earshot_source_settings& settings) {
    check(earshot_source_set_settings(checked(), &settings));
  }
  /** earshot_source_get_occlusion: the direct path's occlusion of the
   *  source's last simulation. */
  earshot_source_occlusion occlusion() const {
    earshot_source_occlusion o{};
    o.struct_size = sizeof(o);
    check(earshot_source_get_occlusion(checked(), &o));
    return o;
  }
  /** earshot_source_get_ir: the IR of the source's last simulation. */
  Ir ir() const {
    earshot_ir* ir = nullptr;
    check(earshot_source_get_ir(checked(), &ir));
    return Ir::adopt(ir);
  }

 private:
  explicit Source(earshot_source* adopted) noexcept : Handle(adopted) {}
  static earshot_source* make(const Context& context, const earshot_source_settings& settings) {
    earshot_source* s = nullptr;
    check(earshot_source_create(context.get(), &settings, &s));
    return s;
  }
  static earshot_source* makeAt(const Context& context, const earshot_source_settings& settings,
                                earshot_vec3 position, earshot_vec3 forward) {
    earshot_source* s = nullptr;
    check(earshot_source_create_at(context.get(), &settings, position, forward, &s));
    return s;
  }
};

}  // namespace earshot
