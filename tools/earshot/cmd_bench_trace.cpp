// `earshot bench trace`: ray tracing speed (16k rays x 12 bounces by default)
// on a scene, reported as the median of repeated runs, beside the Embree
// limit: the same queries replayed through plain Embree calls in the same
// run (issue 16).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>

#include <nlohmann/json.hpp>

#include "command.h"
#include "earshot/core/math.h"
#include "earshot/core/thread_pool.h"
#include "earshot/ir/ir_synthesis.h"
#include "earshot/materials/material.h"
#include "earshot/propagation/reflection_tracer.h"
#include "earshot/scene/embree_limit.h"
#include "earshot/scene/gltf_loader.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot::cli {
namespace {

struct BenchTraceOptions {
  std::string geometry;
  std::string materialMap;
  std::array<double, 3> source{2, 3.5, 1.5}, listener{7, 3.5, 1.5};
  uint32_t rays = 16384, bounces = 12;
  unsigned threads = 2;
  int runs = 15;
  bool embree = true;
  unsigned sharedSources = 0;
  bool perSource = true;  // with sharedSources: also a trace from each source
  double shadowRoulette = ReflectionSettings{}.sharedShadowRoulette;
};

// `count` sources spread over the benchmarks' ring (ringPosition).
std::vector<Vec3d> ringSources(const RayTracer& tracer, unsigned count) {
  std::vector<Vec3d> out;
  for (unsigned i = 0; i < count; ++i) out.push_back(ringPosition(tracer, 2 * kPi * (double(i) + 0.5) / double(count)));
  return out;
}

// One shared trace for `sources` beside a trace per source, same run.
int runShared(const BenchTraceOptions& o, const RayTracer& tracer, const MaterialTable& materials, ThreadPool& pool) {
  ReflectionSettings s;
  s.rays = o.rays;
  s.bounces = o.bounces;
  s.sharedShadowRoulette = o.shadowRoulette;
  const Vec3d lis{o.listener[0], o.listener[1], o.listener[2]};
  const std::vector<Vec3d> positions = ringSources(tracer, o.sharedSources);
  std::vector<SharedTraceSource> sources(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) sources[i].position = positions[i];
  std::vector<double> sharedMs, perSourceMs, recordMs, reusedMs;
  uint64_t sharedSegments = 0, sharedShadows = 0, perSegments = 0, perShadows = 0;
  uint64_t detections = 0, probeDetections = 0;  // the shared trace's, every source's summed
  size_t keptBytes = 0;
  const int runs = std::max(1, std::min(o.runs, 5));
  for (int i = 0; i < runs + 1; ++i) {  // the first run warms up and is dropped
    s.seed = uint64_t(i + 1);
    auto t0 = std::chrono::steady_clock::now();
    auto r = traceReflectionsShared(tracer, materials, lis, sources, s, pool);
    if (!check(r.status())) return 2;
    const double shared = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    sharedSegments = r->front().stats.segmentsTraced;
    sharedShadows = 0;
    detections = probeDetections = 0;
    for (const ReflectionResult& x : *r) {
      sharedShadows += x.stats.shadowRays;
      detections += x.stats.detections;
      probeDetections += x.stats.probeDetections;
    }
    // The same trace keeping its paths, then again from them (SharedTracePaths).
    SharedTracePaths paths;
    auto t1 = std::chrono::steady_clock::now();
    auto recorded = traceReflectionsShared(tracer, materials, lis, sources, s, pool, &paths);
    auto t2 = std::chrono::steady_clock::now();
    auto reused = traceReflectionsShared(tracer, materials, lis, sources, s, pool, &paths);
    auto t3 = std::chrono::steady_clock::now();
    if (!check(recorded.status()) || !check(reused.status())) return 2;
    keptBytes = paths.bytes();
    double per = 0;
    perSegments = perShadows = 0;
    if (o.perSource) {
      for (const Vec3d& p : positions) {
        auto one = traceReflections(tracer, materials, p, lis, s, pool);
        if (!check(one.status())) return 2;
        per += one->stats.traceMs;
        perSegments += one->stats.segmentsTraced;
        perShadows += one->stats.shadowRays;
      }
    }
    if (i == 0) continue;
    sharedMs.push_back(shared);
    perSourceMs.push_back(per);
    recordMs.push_back(std::chrono::duration<double, std::milli>(t2 - t1).count());
    reusedMs.push_back(reused->front().stats.pathsReused ? std::chrono::duration<double, std::milli>(t3 - t2).count()
                                                         : -1.0);
  }
  const double sh = median(sharedMs), per = median(perSourceMs);
  std::printf("shared_trace sources=%u threads=%u runs=%d shared_ms=%.1f (segments=%llu shadow_rays=%llu "
              "detections=%llu of_them_tail_probes=%llu) ",
              o.sharedSources, pool.threadCount(), runs, sh, (unsigned long long)sharedSegments,
              (unsigned long long)sharedShadows, (unsigned long long)detections,
              (unsigned long long)probeDetections);
  if (o.perSource)
    std::printf("per_source_ms=%.1f (segments=%llu shadow_rays=%llu) ratio_per_source_over_shared=%.2f\n", per,
                (unsigned long long)perSegments, (unsigned long long)perShadows, per / sh);
  else
    std::printf("(no per-source traces)\n");
  std::printf("kept_paths sources=%u keeping_ms=%.1f reused_ms=%.1f kept_mb=%.1f ratio_shared_over_reused=%.2f "
              "(the same trace keeping the listener's paths, then detecting the sources in them: SharedTracePaths)\n",
              o.sharedSources, median(recordMs), median(reusedMs), double(keptBytes) / 1048576.0,
              sh / median(reusedMs));
  return 0;
}

int run(const BenchTraceOptions& o) {
  std::map<std::string, std::string> map;
  if (!o.materialMap.empty()) {
    auto m = loadMaterialMap(o.materialMap);
    if (!check(m.status())) return 2;
    map = std::move(m.value());
  }
  const MaterialTable& materials = defaultMaterials();
  auto g = loadGltf(o.geometry, materials, map);
  if (!check(g.status())) return 2;
  std::vector<double> buildMs;
  std::unique_ptr<RayTracer> tracer;
  for (int i = 0; i < 5; ++i) {
    auto t0 = std::chrono::steady_clock::now();
    auto rt = RayTracer::create(g->mesh);
    buildMs.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    if (!check(rt.status())) return 2;
    tracer = std::move(rt.value());
  }
  ThreadPool pool(o.threads);
  if (o.sharedSources > 0) return runShared(o, *tracer, materials, pool);
  ReflectionSettings s;
  s.rays = o.rays;
  s.bounces = o.bounces;
  const Vec3d src{o.source[0], o.source[1], o.source[2]}, lis{o.listener[0], o.listener[1], o.listener[2]};
  std::vector<double> traceMs, synthMs;
  uint64_t queries = 0;
  for (int i = 0; i < o.runs + 1; ++i) {  // the first run warms up and is dropped
    s.seed = uint64_t(i + 1);
    auto r = traceReflections(*tracer, materials, src, lis, s, pool);
    if (!check(r.status())) return 2;
    auto t0 = std::chrono::steady_clock::now();
    IrSynthesisSettings is;
    auto ir = synthesizeOmniIr(nullptr, &r->histogram, is);
    if (!check(ir.status())) return 2;
    if (i == 0) continue;
    synthMs.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    traceMs.push_back(r->stats.traceMs);
    queries = r->stats.segmentsTraced + r->stats.shadowRays;
  }
  const double t = median(traceMs);
  std::printf("trace scene=%s triangles=%zu rays=%u bounces=%u threads=%u runs=%d trace_ms=%.2f min_ms=%.2f "
              "queries=%llu mrays_per_s=%.1f bvh_build_ms=%.2f synthesis_ms=%.2f\n",
              o.geometry.c_str(), g->mesh.triangleCount(), o.rays, o.bounces, pool.threadCount(), o.runs, t,
              *std::min_element(traceMs.begin(), traceMs.end()), (unsigned long long)queries, double(queries) / t / 1e3,
              median(buildMs), median(synthMs));
  if (!o.embree) return 0;

  // The Embree limit: the queries of one trace (seed 1, recorded on one
  // thread so that they keep the tracer's order), replayed through plain
  // Embree calls on the same threads, in each mode; per query, against the
  // tracer's time per query above.
  QueryLog log;
  {
    ThreadPool one(1);
    s.seed = 1;
    QueryRecording recording(*tracer, log);
    auto r = traceReflections(*tracer, materials, src, lis, s, one);
    if (!check(r.status())) return 2;
  }
  const EmbreeReplay replay(*tracer, log);
  const double perQuery = t / double(queries);
  double best = 0;
  const char* bestName = "";
  for (EmbreeMode mode : {EmbreeMode::kSingle, EmbreeMode::kStream, EmbreeMode::kPacket8}) {
    std::vector<double> ms;
    size_t hits = 0;
    for (int i = 0; i < o.runs + 1; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      hits = replay.run(mode, pool);
      if (i > 0) ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    }
    const double m = median(ms);
    const double q = double(replay.intersectCount() + replay.shadowCount());
    if (best == 0 || m / q < best) {
      best = m / q;
      bestName = embreeModeName(mode);
    }
    std::printf("embree mode=%s queries=%.0f (nearest=%zu shadow=%zu) hits=%zu ms=%.2f mrays_per_s=%.1f\n",
                embreeModeName(mode), q, replay.intersectCount(), replay.shadowCount(), hits, m, q / m / 1e3);
  }
  std::printf("ratio earshot_per_query/embree_per_query=%.2f (best plain mode: %s; earshot %.1f ns, embree %.1f ns "
              "per query)\n",
              perQuery / best, bestName, perQuery * 1e6, best * 1e6);
  return 0;
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<BenchTraceOptions>();
  CLI::App& bench = subcommandGroup(root, "bench", "Measure the speed of earshot's stages");
  CLI::App* cmd = bench.add_subcommand("trace", "Ray tracing speed: median time of repeated reflection traces");
  cmd->add_option("geometry", o->geometry, "Scene geometry (glTF)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--material-map", o->materialMap, "JSON object mapping glTF material names to acoustic materials");
  addVec3Option(*cmd, "--source", o->source, "Source position in metres (default 2,3.5,1.5)");
  addVec3Option(*cmd, "--listener", o->listener, "Listener position in metres (default 7,3.5,1.5)");
  cmd->add_option("--rays", o->rays, "Rays")->check(CLI::Range(1u, 100000000u))->capture_default_str();
  cmd->add_option("--bounces", o->bounces, "Bounces")->check(CLI::Range(0u, 100000u))->capture_default_str();
  cmd->add_option("--threads", o->threads, "Threads")->check(CLI::Range(1u, 256u))->capture_default_str();
  cmd->add_option("--runs", o->runs, "Timed runs (median reported)")->check(CLI::Range(1, 10000))->capture_default_str();
  CLI::Option* shared = cmd->add_option("--shared-sources", o->sharedSources,
                  "Instead: one shared listener-centred trace for this many sources (on a ring at 0.6 of the "
                  "scene's half extents, z up) beside a trace from each of them, same run (median of up to 5)")
      ->check(CLI::Range(1u, 4096u));
  cmd->add_flag("!--no-per-source", o->perSource,
                "With --shared-sources: skip the trace from each source (times the shared trace and the detection "
                "in kept paths alone)")
      ->needs(shared);
  cmd->add_option("--shadow-roulette", o->shadowRoulette,
                  "With --shared-sources: the shared trace's shadow-ray roulette (a source gets a reflection's "
                  "shadow ray with probability min(1, this x R^2 cos / d^2); 0: every shadow ray)")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  cmd->add_flag("!--no-embree-limit", o->embree,
                "Skip the Embree limit (the same queries replayed through plain Embree calls, every mode)");
  cmd->callback([o] { setExitCode(run(*o)); });
});

}  // namespace
}  // namespace earshot::cli
