// The C API's scenes (a DynamicScene and its materials) and meshes.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <string>

#include "capi_internal.h"
#include "earshot/scene/gltf_loader.h"

namespace earshot::capi {

namespace {

// Limits of what a mesh may hold (DynamicScene refuses more than 2^32 in
// total; these catch garbage sizes before any allocation).
constexpr size_t kMaxMeshElements = size_t(1) << 31;
constexpr size_t kMaxMaterialNames = 65536;
constexpr size_t kMaxMovableNodes = 65536;

std::string checkMatrix(const float* m, size_t n, const char* name) {
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(m[i]))
      return std::string(name) + "[" + std::to_string(i) + "] is " + describe(m[i]) + " (must be finite)";
  return "";
}

AffineTransform fromRowMajor3x4(const float* m) {
  AffineTransform t;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) t.m[r][c] = m[r * 4 + c];
  return t;
}

/** Material id of `name` in the scene's table, or NOT_FOUND naming it. */
Result<uint32_t> materialId(const earshot_scene* s, const std::string& name) {
  auto id = s->materials->find(name);
  if (!id) return notFound("material " + quotedName(name) + " is not one of the scene's materials");
  return *id;
}

/** Adds a mesh handle that holds data to the scene's DynamicScene. */
Status addToScene(earshot_scene* s, earshot_mesh* m) {
  TriangleMesh world = m->data;  // the handle keeps its copy for a later re-add
  if (!m->overrideMaterial.empty()) {
    auto id = materialId(s, m->overrideMaterial);
    if (!id.isOk()) return Status(id.status().code(), "mesh " + quotedName(m->name) + ": " + id.status().message());
    std::fill(world.materialIds.begin(), world.materialIds.end(), *id);
  } else {
    std::vector<uint32_t> ids;
    for (const std::string& name : m->materialNames) {
      auto id = materialId(s, name);
      if (!id.isOk()) return Status(id.status().code(), "mesh " + quotedName(m->name) + ": " + id.status().message());
      ids.push_back(*id);
    }
    for (uint32_t& id : world.materialIds) id = ids[id];
  }
  auto id = s->dynamic->addMesh(std::move(world), m->motion, m->transform, m->name);
  if (!id.isOk()) return id.status();
  m->id = *id;
  return Status::ok();
}

/** Takes `m` out of the scene's bookkeeping and drops the scene's reference. */
void detach(earshot_scene* s, earshot_mesh* m) {
  auto it = std::find(s->meshes.begin(), s->meshes.end(), m);
  if (it != s->meshes.end()) s->meshes.erase(it);
  m->scene = nullptr;
  m->id = 0;
  releaseMesh(m);
}

}  // namespace

void releaseScene(earshot_scene* s) {
  if (s->refs.fetch_sub(1, std::memory_order_acq_rel) == 1) destroy(s);
}

void releaseMesh(earshot_mesh* m) {
  if (m->refs.fetch_sub(1, std::memory_order_acq_rel) == 1) destroy(m);
}

}  // namespace earshot::capi

using namespace earshot;
using namespace earshot::capi;

earshot_scene::~earshot_scene() {
  // The meshes survive if referenced elsewhere, in no scene.
  std::vector<earshot_mesh*> held;
  held.swap(meshes);
  for (earshot_mesh* m : held) {
    m->scene = nullptr;
    m->id = 0;
    releaseMesh(m);
  }
}

namespace {

earshot_status setTransform(earshot_mesh* m, const AffineTransform& t, const char* fn) {
  if (!(std::fabs(t.determinant()) > 0.0)) return argError(&m->env, fn, "the matrix is not invertible");
  if (m->scene) {
    const Status s = m->scene->dynamic->setTransform(m->id, t);
    if (!s.isOk()) return fromStatus(&m->env, fn, s);
  }
  m->transform = t;
  return EARSHOT_OK;
}

}  // namespace

extern "C" {

earshot_status earshot_scene_settings_init(earshot_scene_settings* s) {
  if (!s) return argError(nullptr, "earshot_scene_settings_init", "settings is NULL");
  *s = earshot_scene_settings{};
  s->struct_size = sizeof(earshot_scene_settings);
  s->materials_path = nullptr;
  return EARSHOT_OK;
}

earshot_status earshot_scene_create(earshot_context* c, const earshot_scene_settings* settings, earshot_scene** out) {
  static const char* kFn = "earshot_scene_create";
  if (out) *out = nullptr;
  if (!alive(c)) return argError(nullptr, kFn, "context is not a live earshot_context");
  if (!out) return argError(&c->env, kFn, "out is NULL");
  return guard(&c->env, kFn, [&]() -> earshot_status {
    const std::string badSize =
        settings ? checkStructSize(settings->struct_size, sizeof(earshot_scene_settings), "settings") : "";
    if (!badSize.empty()) return argError(&c->env, kFn, badSize);
    std::shared_ptr<const MaterialTable> materials;
    if (settings && settings->materials_path) {
      auto loaded = loadMaterials(settings->materials_path);
      if (!loaded.isOk()) return fromStatus(&c->env, kFn, loaded.status());
      materials = std::make_shared<const MaterialTable>(std::move(loaded.value()));
    } else {
      materials = std::make_shared<const MaterialTable>(defaultMaterials());
    }
    auto dynamic = DynamicScene::create();
    if (!dynamic.isOk()) return fromStatus(&c->env, kFn, dynamic.status());
    earshot_scene* s = create<earshot_scene>(c->env);
    s->dynamic = std::move(dynamic.value());
    s->materials = std::move(materials);
    *out = s;
    return EARSHOT_OK;
  });
}

earshot_status earshot_scene_retain(earshot_scene* s) {
  return retainHandle(s, "earshot_scene_retain", "scene");
}

earshot_status earshot_scene_release(earshot_scene* s) {
  return releaseHandle(s, "earshot_scene_release", "scene", releaseScene);
}

earshot_status earshot_scene_add_material(earshot_scene* s, const earshot_material* material) {
  static const char* kFn = "earshot_scene_add_material";
  if (!alive(s)) return argError(nullptr, kFn, "scene is not a live earshot_scene");
  if (!material) return argError(&s->env, kFn, "material is NULL");
  return guard(&s->env, kFn, [&]() -> earshot_status {
    const std::string badSize = checkStructSize(material->struct_size, sizeof(earshot_material), "material");
    if (!badSize.empty()) return argError(&s->env, kFn, badSize);
    if (!material->name || !material->name[0]) return argError(&s->env, kFn, "material->name is NULL or empty");
    Material m;
    m.name = material->name;
    for (int b = 0; b < EARSHOT_BAND_COUNT; ++b) {
      const float a = material->absorption[b], sc = material->scattering[b], t = material->transmission[b];
      const std::string band = "[" + std::to_string(b) + "]";
      if (!(a >= 0.0f && a <= 1.0f))
        return argError(&s->env, kFn, "material " + quotedName(m.name) + ": absorption" + band + " = " + describe(a) +
                                          " is outside [0, 1]");
      if (!(sc >= 0.0f && sc <= 1.0f))
        return argError(&s->env, kFn, "material " + quotedName(m.name) + ": scattering" + band + " = " + describe(sc) +
                                          " is outside [0, 1]");
      if (!(t >= 0.0f && t <= a))
        return argError(&s->env, kFn, "material " + quotedName(m.name) + ": transmission" + band + " = " + describe(t) +
                                          " is outside [0, absorption = " + describe(a) + "]");
      m.absorption[b] = a;
      m.scattering[b] = sc;
      m.transmission[b] = t;
    }
    static_assert(EARSHOT_BAND_COUNT == kNumBands, "the C API's bands are the engine's");
    auto table = std::make_shared<MaterialTable>(*s->materials);
    table->add(std::move(m));
    s->materials = std::move(table);
    return EARSHOT_OK;
  });
}

earshot_status earshot_scene_add_mesh(earshot_scene* s, earshot_mesh* m) {
  static const char* kFn = "earshot_scene_add_mesh";
  if (!alive(s)) return argError(nullptr, kFn, "scene is not a live earshot_scene");
  if (!alive(m)) return argError(&s->env, kFn, "mesh is not a live earshot_mesh");
  return guard(&s->env, kFn, [&]() -> earshot_status {
    if (m->scene)
      return fail(&s->env, kFn, EARSHOT_ERROR_INVALID_STATE,
                  "mesh " + quotedName(m->name) + " is already in " + (m->scene == s ? "this" : "another") + " scene");
    if (!m->hasData)
      return fail(&s->env, kFn, EARSHOT_ERROR_INVALID_STATE,
                  "mesh " + quotedName(m->name) + " came from a glTF file and was removed; its triangles are not kept");
    s->meshes.reserve(s->meshes.size() + 1);
    const Status added = addToScene(s, m);
    if (!added.isOk()) return fromStatus(&s->env, kFn, added);
    m->scene = s;
    m->refs.fetch_add(1, std::memory_order_relaxed);
    s->meshes.push_back(m);
    return EARSHOT_OK;
  });
}

earshot_status earshot_scene_remove_mesh(earshot_scene* s, earshot_mesh* m) {
  static const char* kFn = "earshot_scene_remove_mesh";
  if (!alive(s)) return argError(nullptr, kFn, "scene is not a live earshot_scene");
  if (!alive(m)) return argError(&s->env, kFn, "mesh is not a live earshot_mesh");
  return guard(&s->env, kFn, [&]() -> earshot_status {
    if (m->scene != s)
      return fail(&s->env, kFn, EARSHOT_ERROR_INVALID_STATE, "mesh " + quotedName(m->name) + " is not in this scene");
    const Status removed = s->dynamic->removeMesh(m->id);
    if (!removed.isOk()) return fromStatus(&s->env, kFn, removed);
    detach(s, m);
    return EARSHOT_OK;
  });
}

earshot_status earshot_scene_commit(earshot_scene* s) {
  static const char* kFn = "earshot_scene_commit";
  if (!alive(s)) return argError(nullptr, kFn, "scene is not a live earshot_scene");
  return guard(&s->env, kFn, [&]() -> earshot_status {
    auto snapshot = s->dynamic->commit();
    if (!snapshot.isOk()) return fromStatus(&s->env, kFn, snapshot.status());
    std::lock_guard<std::mutex> lock(s->publishMutex);
    if (snapshot.value() == s->snapshot && s->materials == s->snapshotMaterials) return EARSHOT_OK;
    s->snapshot = std::move(snapshot.value());
    s->snapshotMaterials = s->materials;
    ++s->version;
    return EARSHOT_OK;
  });
}

earshot_status earshot_gltf_settings_init(earshot_gltf_settings* s) {
  if (!s) return argError(nullptr, "earshot_gltf_settings_init", "settings is NULL");
  *s = earshot_gltf_settings{};
  s->struct_size = sizeof(earshot_gltf_settings);
  return EARSHOT_OK;
}

earshot_status earshot_scene_load_gltf(earshot_scene* s, const earshot_gltf_settings* settings) {
  static const char* kFn = "earshot_scene_load_gltf";
  if (!alive(s)) return argError(nullptr, kFn, "scene is not a live earshot_scene");
  if (!settings) return argError(&s->env, kFn, "settings is NULL");
  return guard(&s->env, kFn, [&]() -> earshot_status {
    const std::string badSize = checkStructSize(settings->struct_size, sizeof(earshot_gltf_settings), "settings");
    if (!badSize.empty()) return argError(&s->env, kFn, badSize);
    if (!settings->path || !settings->path[0]) return argError(&s->env, kFn, "settings->path is NULL or empty");
    if (settings->movable_node_count > kMaxMovableNodes)
      return argError(&s->env, kFn, "settings->movable_node_count " + std::to_string(settings->movable_node_count) +
                                        " is outside [0, " + std::to_string(kMaxMovableNodes) + "]");
    if (settings->movable_node_count > 0 && !settings->movable_node_names)
      return argError(&s->env, kFn, "settings->movable_node_names is NULL with a non-zero count");
    std::vector<std::string> movable;
    for (size_t i = 0; i < settings->movable_node_count; ++i) {
      if (!settings->movable_node_names[i])
        return argError(&s->env, kFn, "settings->movable_node_names[" + std::to_string(i) + "] is NULL");
      movable.emplace_back(settings->movable_node_names[i]);
    }
    std::map<std::string, std::string> materialMap;
    if (settings->material_map_path) {
      auto map = loadMaterialMap(settings->material_map_path);
      if (!map.isOk()) return fromStatus(&s->env, kFn, map.status());
      materialMap = std::move(map.value());
    }
    const std::string path = settings->path;
    InputLimits limits;
    limits.allowOutsidePaths = settings->allow_outside_paths != 0;
    if (settings->max_memory_bytes > 0) limits.maxMemoryBytes = settings->max_memory_bytes;
    auto loaded = loadGltfIntoScene(path, *s->materials, materialMap, movable, *s->dynamic, limits);
    if (!loaded.isOk()) return fromStatus(&s->env, kFn, loaded.status());
    for (const std::string& w : loaded->warnings) s->env.logMessage(EARSHOT_LOG_WARNING, path + ": " + w);

    // One handle per mesh the load added (the scene holds each). If making a
    // handle fails, the meshes already added stay in the scene by id only.
    struct Added {
      std::string name;
      MeshId id;
      MeshMotion motion;
      AffineTransform transform;
    };
    std::vector<Added> added;
    if (loaded->staticMesh != 0) added.push_back({path, loaded->staticMesh, MeshMotion::kStatic, {}});
    for (const GltfMovableNode& n : loaded->movable) added.push_back({n.name, n.id, MeshMotion::kMovable, n.transform});
    s->meshes.reserve(s->meshes.size() + added.size());
    for (const Added& a : added) {
      earshot_mesh* m = create<earshot_mesh>(s->env);
      m->name = a.name;
      m->hasData = false;
      m->motion = a.motion;
      m->transform = a.transform;
      m->id = a.id;
      m->scene = s;
      s->meshes.push_back(m);  // the scene holds the creation reference
    }
    s->env.logMessage(EARSHOT_LOG_INFO, std::string(kFn) + ": " + path + ": " + std::to_string(added.size()) +
                                            " meshes (" + std::to_string(loaded->movable.size()) + " movable)");
    return EARSHOT_OK;
  });
}

earshot_status earshot_scene_find_mesh(earshot_scene* s, const char* name, earshot_mesh** out) {
  static const char* kFn = "earshot_scene_find_mesh";
  if (out) *out = nullptr;
  if (!alive(s)) return argError(nullptr, kFn, "scene is not a live earshot_scene");
  if (!name) return argError(&s->env, kFn, "name is NULL");
  if (!out) return argError(&s->env, kFn, "out is NULL");
  return guard(&s->env, kFn, [&]() -> earshot_status {
    for (earshot_mesh* m : s->meshes) {
      if (m->name != name) continue;
      m->refs.fetch_add(1, std::memory_order_relaxed);
      *out = m;
      return EARSHOT_OK;
    }
    return fail(&s->env, kFn, EARSHOT_ERROR_NOT_FOUND, "no mesh named " + quotedName(name) + " in the scene");
  });
}

earshot_status earshot_scene_get_stats(earshot_scene* s, earshot_scene_stats* stats) {
  static const char* kFn = "earshot_scene_get_stats";
  if (!alive(s)) return argError(nullptr, kFn, "scene is not a live earshot_scene");
  if (!stats) return argError(&s->env, kFn, "stats is NULL");
  return guard(&s->env, kFn, [&] {
    const std::string badSize = checkStructSize(stats->struct_size, sizeof(earshot_scene_stats), "stats");
    if (!badSize.empty()) return argError(&s->env, kFn, badSize);
    const DynamicSceneStats d = s->dynamic->stats();
    earshot_scene_stats out{};
    out.struct_size = sizeof(earshot_scene_stats);
    out.mesh_count = uint32_t(s->dynamic->meshCount());
    out.commits = d.commits;
    out.static_bvh_builds = d.staticBvhBuilds;
    out.top_level_builds = d.topLevelBuilds;
    out.last_commit_ms = d.lastCommitMs;
    *stats = out;
    return EARSHOT_OK;
  });
}

// ---- meshes ----

earshot_status earshot_mesh_settings_init(earshot_mesh_settings* s) {
  if (!s) return argError(nullptr, "earshot_mesh_settings_init", "settings is NULL");
  *s = earshot_mesh_settings{};
  s->struct_size = sizeof(earshot_mesh_settings);
  s->motion = EARSHOT_MESH_STATIC;
  return EARSHOT_OK;
}

earshot_status earshot_mesh_create(earshot_context* c, const earshot_mesh_settings* settings, earshot_mesh** out) {
  static const char* kFn = "earshot_mesh_create";
  if (out) *out = nullptr;
  if (!alive(c)) return argError(nullptr, kFn, "context is not a live earshot_context");
  const Env* env = &c->env;
  if (!out) return argError(env, kFn, "out is NULL");
  if (!settings) return argError(env, kFn, "settings is NULL");
  return guard(env, kFn, [&]() -> earshot_status {
    const earshot_mesh_settings& s = *settings;
    const std::string badSize = checkStructSize(s.struct_size, sizeof(earshot_mesh_settings), "settings");
    if (!badSize.empty()) return argError(env, kFn, badSize);
    if (s.vertex_count < 1 || s.vertex_count > kMaxMeshElements)
      return argError(env, kFn,
                      "settings->vertex_count " + std::to_string(s.vertex_count) + " is outside [1, 2^31]");
    if (s.triangle_count < 1 || s.triangle_count > kMaxMeshElements)
      return argError(env, kFn,
                      "settings->triangle_count " + std::to_string(s.triangle_count) + " is outside [1, 2^31]");
    if (s.material_count < 1 || s.material_count > kMaxMaterialNames)
      return argError(env, kFn,
                      "settings->material_count " + std::to_string(s.material_count) + " is outside [1, 65536]");
    if (!s.vertices) return argError(env, kFn, "settings->vertices is NULL");
    if (!s.indices) return argError(env, kFn, "settings->indices is NULL");
    if (!s.material_names) return argError(env, kFn, "settings->material_names is NULL");
    const int64_t motion = rawEnum(s.motion);
    if (motion != EARSHOT_MESH_STATIC && motion != EARSHOT_MESH_MOVABLE)
      return argError(env, kFn, "settings->motion " + std::to_string(motion) + " is not an earshot_mesh_motion");
    const std::string name = s.name ? s.name : "";
    const std::string prefix = "mesh " + quotedName(name) + ": ";
    AffineTransform transform;
    if (s.transform) {
      const std::string bad = checkMatrix(s.transform, 12, "settings->transform");
      if (!bad.empty()) return argError(env, kFn, prefix + bad);
      transform = fromRowMajor3x4(s.transform);
      if (!(std::fabs(transform.determinant()) > 0.0))
        return argError(env, kFn, prefix + "settings->transform is not invertible");
    }
    std::vector<std::string> names;
    for (size_t i = 0; i < s.material_count; ++i) {
      if (!s.material_names[i] || !s.material_names[i][0])
        return argError(env, kFn, prefix + "settings->material_names[" + std::to_string(i) + "] is NULL or empty");
      names.emplace_back(s.material_names[i]);
    }
    TriangleMesh mesh;
    mesh.positions.resize(s.vertex_count);
    for (size_t v = 0; v < s.vertex_count; ++v) {
      const float* p = s.vertices + 3 * v;
      if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
        return argError(env, kFn, prefix + "vertex " + std::to_string(v) + " is not finite");
      mesh.positions[v] = {p[0], p[1], p[2]};
    }
    mesh.triangles.resize(s.triangle_count);
    mesh.materialIds.assign(s.triangle_count, 0);
    for (size_t t = 0; t < s.triangle_count; ++t) {
      for (int k = 0; k < 3; ++k) {
        const uint32_t index = s.indices[3 * t + size_t(k)];
        if (index >= s.vertex_count)
          return argError(env, kFn, prefix + "indices[" + std::to_string(3 * t + size_t(k)) + "] = " +
                                        std::to_string(index) + " is not below vertex_count " +
                                        std::to_string(s.vertex_count));
        mesh.triangles[t][size_t(k)] = index;
      }
      if (s.triangle_materials) {
        const uint32_t mi = s.triangle_materials[t];
        if (mi >= s.material_count)
          return argError(env, kFn, prefix + "triangle_materials[" + std::to_string(t) + "] = " + std::to_string(mi) +
                                        " is not below material_count " + std::to_string(s.material_count));
        mesh.materialIds[t] = mi;
      }
    }
    earshot_mesh* m = create<earshot_mesh>(*env);
    m->name = name;
    m->hasData = true;
    m->data = std::move(mesh);
    m->materialNames = std::move(names);
    m->motion = motion == EARSHOT_MESH_MOVABLE ? MeshMotion::kMovable : MeshMotion::kStatic;
    m->transform = transform;
    *out = m;
    return EARSHOT_OK;
  });
}

earshot_status earshot_mesh_retain(earshot_mesh* m) {
  return retainHandle(m, "earshot_mesh_retain", "mesh");
}

earshot_status earshot_mesh_release(earshot_mesh* m) {
  return releaseHandle(m, "earshot_mesh_release", "mesh", releaseMesh);
}

earshot_status earshot_mesh_set_transform(earshot_mesh* m, const float* matrix) {
  static const char* kFn = "earshot_mesh_set_transform";
  if (!alive(m)) return argError(nullptr, kFn, "mesh is not a live earshot_mesh");
  if (!matrix) return argError(&m->env, kFn, "matrix3x4 is NULL");
  return guard(&m->env, kFn, [&]() -> earshot_status {
    const std::string bad = checkMatrix(matrix, 12, "matrix3x4");
    if (!bad.empty()) return argError(&m->env, kFn, bad);
    return setTransform(m, fromRowMajor3x4(matrix), kFn);
  });
}

earshot_status earshot_mesh_set_transform_4x4(earshot_mesh* m, const float* matrix) {
  static const char* kFn = "earshot_mesh_set_transform_4x4";
  if (!alive(m)) return argError(nullptr, kFn, "mesh is not a live earshot_mesh");
  if (!matrix) return argError(&m->env, kFn, "matrix4x4 is NULL");
  return guard(&m->env, kFn, [&]() -> earshot_status {
    const std::string bad = checkMatrix(matrix, 16, "matrix4x4");
    if (!bad.empty()) return argError(&m->env, kFn, bad);
    std::array<double, 16> c;
    for (size_t i = 0; i < 16; ++i) c[i] = matrix[i];
    return setTransform(m, AffineTransform::fromColumnMajor(c), kFn);
  });
}

earshot_status earshot_mesh_get_transform(earshot_mesh* m, float* matrix) {
  static const char* kFn = "earshot_mesh_get_transform";
  if (!alive(m)) return argError(nullptr, kFn, "mesh is not a live earshot_mesh");
  if (!matrix) return argError(&m->env, kFn, "matrix3x4 is NULL");
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) matrix[r * 4 + c] = float(m->transform.m[r][c]);
  return EARSHOT_OK;
}

earshot_status earshot_mesh_set_material(earshot_mesh* m, const char* name) {
  static const char* kFn = "earshot_mesh_set_material";
  if (!alive(m)) return argError(nullptr, kFn, "mesh is not a live earshot_mesh");
  if (!name || !name[0]) return argError(&m->env, kFn, "name is NULL or empty");
  return guard(&m->env, kFn, [&]() -> earshot_status {
    if (m->scene) {
      auto id = materialId(m->scene, name);
      if (!id.isOk()) return fromStatus(&m->env, kFn, id.status());
      const Status s = m->scene->dynamic->setMaterial(m->id, *id);
      if (!s.isOk()) return fromStatus(&m->env, kFn, s);
    }
    m->overrideMaterial = name;
    return EARSHOT_OK;
  });
}

}  // extern "C"
