// Benchmark (not a test, prints only): what a DynamicScene commit costs when
// one mesh moves, against RayTracer::create of the same geometry, and what
// instancing costs the tracer. Medians of repeated runs.
//   dynamic_scene_bench [runs]
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

#include "earshot/core/math.h"
#include "earshot/core/thread_pool.h"
#include "earshot/materials/material.h"
#include "earshot/propagation/reflection_tracer.h"
#include "earshot/scene/dynamic_scene.h"
#include "earshot/scene/gltf_loader.h"
#include "earshot/scene/planes.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot {
namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : (v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]));
}

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

[[noreturn]] void die(const Status& s) {
  std::fprintf(stderr, "error: %s\n", s.message().c_str());
  std::exit(2);
}

/** One scene: its flat mesh, and the same geometry in a DynamicScene with
 *  one movable mesh that `move(k)` places for run k. */
struct Case {
  std::string name;
  TriangleMesh flat;
  std::unique_ptr<DynamicScene> scene;
  MeshId movable = 0;
  size_t movableTriangles = 0;
  std::function<AffineTransform(int)> move;
  Vec3d source, listener;
};

Case twoRooms() {
  const std::string dir = std::string(EARSHOT_SOURCE_DIR) + "/samples/two_rooms/";
  auto map = loadMaterialMap(dir + "materials_map.json");
  if (!map) die(map.status());
  auto g = loadGltf(dir + "two_rooms.gltf", defaultMaterials(), *map);
  if (!g) die(g.status());
  Case c;
  c.name = "two_rooms";
  c.flat = g->mesh;
  c.scene = std::move(DynamicScene::create()).value();
  auto meshes = loadGltfIntoScene(dir + "two_rooms.gltf", defaultMaterials(), *map, {"door"}, *c.scene);
  if (!meshes) die(meshes.status());
  c.movable = meshes->movable[0].id;
  c.movableTriangles = 12;
  const AffineTransform hinge = meshes->movable[0].transform;
  c.move = [hinge](int k) { return hinge * AffineTransform::rotation({0, 0, 1}, -kPi / 2 * (k % 2)); };
  c.source = {3.0, 2.5, 1.5};
  c.listener = {9.2, 2.5, 1.5};
  return c;
}

/** furnished_room is one glTF node: its plant (the "foam" triangles) is split
 *  off as the movable mesh, in world coordinates, moved 1 cm per run. */
Case furnishedRoom() {
  const std::string dir = std::string(EARSHOT_SOURCE_DIR) + "/samples/furnished_room/";
  auto map = loadMaterialMap(dir + "materials_map.json");
  if (!map) die(map.status());
  auto g = loadGltf(dir + "furnished_room.glb", defaultMaterials(), *map);
  if (!g) die(g.status());
  const uint32_t foam = *defaultMaterials().find("foam");
  Case c;
  c.name = "furnished_room (plant movable)";
  c.flat = g->mesh;
  TriangleMesh room, plant;
  std::vector<uint32_t> roomIndex(g->mesh.positions.size(), ~0u), plantIndex(roomIndex);
  for (size_t t = 0; t < g->mesh.triangleCount(); ++t) {
    const bool isPlant = g->mesh.materialIds[t] == foam;
    TriangleMesh& to = isPlant ? plant : room;
    std::vector<uint32_t>& index = isPlant ? plantIndex : roomIndex;
    std::array<uint32_t, 3> tri;
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = g->mesh.triangles[t][k];
      if (index[v] == ~0u) {
        index[v] = uint32_t(to.positions.size());
        to.positions.push_back(g->mesh.positions[v]);
      }
      tri[k] = index[v];
    }
    to.triangles.push_back(tri);
    to.materialIds.push_back(g->mesh.materialIds[t]);
  }
  c.movableTriangles = plant.triangleCount();
  c.scene = std::move(DynamicScene::create()).value();
  if (auto id = c.scene->addMesh(std::move(room), MeshMotion::kStatic); !id) die(id.status());
  auto id = c.scene->addMesh(std::move(plant), MeshMotion::kMovable);
  if (!id) die(id.status());
  c.movable = *id;
  c.move = [](int k) { return AffineTransform::translation({0.01 * (k % 2), 0, 0}); };
  c.source = {2, 3.5, 1.5};
  c.listener = {7, 3.5, 1.5};
  return c;
}

void run(Case& c, int runs, ThreadPool& pool) {
  std::vector<double> createMs, commitMs, planesMs;
  for (int k = 0; k < runs; ++k) {
    auto t0 = std::chrono::steady_clock::now();
    auto rt = RayTracer::create(c.flat);
    createMs.push_back(msSince(t0));
    if (!rt) die(rt.status());
  }
  if (auto s = c.scene->commit(); !s) die(s.status());
  const DynamicSceneStats before = c.scene->stats();
  for (int k = 1; k <= runs; ++k) {
    auto t0 = std::chrono::steady_clock::now();
    if (Status s = c.scene->setTransform(c.movable, c.move(k)); !s) die(s);
    auto snap = c.scene->commit();
    commitMs.push_back(msSince(t0));
    if (!snap) die(snap.status());
    t0 = std::chrono::steady_clock::now();
    const PlaneSet planes = groupCoplanarTriangles((*snap)->mesh());
    planesMs.push_back(msSince(t0));
  }
  const DynamicSceneStats after = c.scene->stats();
  std::printf("%s: %zu triangles, movable %zu\n", c.name.c_str(), c.flat.triangleCount(), c.movableTriangles);
  std::printf("  RayTracer::create            median %7.3f ms\n", median(createMs));
  std::printf("  setTransform + commit        median %7.3f ms  (groupCoplanarTriangles from scratch: %.3f ms)\n",
              median(commitMs), median(planesMs));
  std::printf("  builds over %d commits: static %llu, mesh %llu, top-level %llu\n", runs,
              (unsigned long long)(after.staticBvhBuilds - before.staticBvhBuilds),
              (unsigned long long)(after.meshBvhBuilds - before.meshBvhBuilds),
              (unsigned long long)(after.topLevelBuilds - before.topLevelBuilds));

  // Tracing: the movable mesh back where the flat mesh has it.
  if (Status s = c.scene->setTransform(c.movable, c.move(0)); !s) die(s);
  auto snap = c.scene->commit();
  if (!snap) die(snap.status());
  auto flat = RayTracer::create(c.flat);
  if (!flat) die(flat.status());
  ReflectionSettings rs;  // 16384 rays x 12 bounces
  // Also a shared trace from the listener for 9 sources around the source:
  // its shadow rays go to Embree in streams (RayTracer::occludedMany).
  std::vector<SharedTraceSource> sources(9);
  for (int i = 0; i < 9; ++i) sources[size_t(i)].position = c.source + Vec3d(0.4 * (i % 3 - 1), 0.4 * (i / 3 - 1), 0);
  std::vector<double> flatMs, instMs, flatSharedMs, instSharedMs;
  const int traceRuns = std::max(5, runs / 2);
  for (int k = 0; k <= traceRuns; ++k) {  // run 0 warms up
    rs.seed = uint64_t(k + 1);
    auto a = traceReflections(**flat, defaultMaterials(), c.source, c.listener, rs, pool);
    auto b = traceReflections(**snap, defaultMaterials(), c.source, c.listener, rs, pool);
    if (!a) die(a.status());
    if (!b) die(b.status());
    auto t0 = std::chrono::steady_clock::now();
    auto sa = traceReflectionsShared(**flat, defaultMaterials(), c.listener, sources, rs, pool);
    const double saMs = msSince(t0);
    t0 = std::chrono::steady_clock::now();
    auto sb = traceReflectionsShared(**snap, defaultMaterials(), c.listener, sources, rs, pool);
    const double sbMs = msSince(t0);
    if (!sa) die(sa.status());
    if (!sb) die(sb.status());
    if (k == 0) continue;
    flatMs.push_back(a->stats.traceMs);
    instMs.push_back(b->stats.traceMs);
    flatSharedMs.push_back(saMs);
    instSharedMs.push_back(sbMs);
  }
  auto report = [&](const char* what, const std::vector<double>& f, const std::vector<double>& i) {
    std::printf("  %s flat %.2f ms, instanced %.2f ms (%+.1f %%), %d runs\n", what, median(f), median(i),
                100.0 * (median(i) / median(f) - 1.0), traceRuns);
  };
  char label[96];
  std::snprintf(label, sizeof label, "traceReflections 16k x 12, %u threads:", pool.threadCount());
  report(label, flatMs, instMs);
  report("traceReflectionsShared 16k x 12, 9 sources:", flatSharedMs, instSharedMs);
}

}  // namespace
}  // namespace earshot

int main(int argc, char** argv) {
  const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 20;
  earshot::ThreadPool pool(2);
  earshot::Case a = earshot::twoRooms();
  earshot::run(a, runs, pool);
  earshot::Case b = earshot::furnishedRoom();
  earshot::run(b, runs, pool);
  return 0;
}
