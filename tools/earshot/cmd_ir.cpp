// `earshot ir`: the impulse response of one source/listener pair.
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>

#include <nlohmann/json.hpp>

#include "command.h"
#include "earshot/core/thread_pool.h"
#include "earshot/io/atomic_file.h"
#include "earshot/io/wav.h"
#include "earshot/ir/ir_synthesis.h"
#include "earshot/materials/material.h"
#include "earshot/propagation/direct_path.h"
#include "earshot/propagation/reflection_tracer.h"
#include "earshot/scene/gltf_loader.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot::cli {
namespace {

struct IrOptions {
  std::string geometry;
  std::array<double, 3> source{}, listener{};
  std::string output;
  std::string materials;
  std::string materialMap;
  std::string receiver = "omni";
  double rate = 48000;
  uint32_t rays = 16384;
  uint32_t bounces = 12;
  std::string length = "auto";
  uint64_t seed = 1;
  unsigned threads = 0;
  std::string air = "20,50";
  std::string json;
  double binMs = 1.0;
  double receiverRadius = 0.0;
};

double msSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

Result<std::map<std::string, std::string>> loadMaterialMap(const std::string& path) {
  std::ifstream f(path);
  if (!f) return notFound(path + ": cannot open material map");
  nlohmann::json j = nlohmann::json::parse(f, nullptr, false);
  if (j.is_discarded()) return parseError(path + ": not valid JSON");
  if (!j.is_object()) return parseError(path + ": material map must be an object {\"gltf name\": \"acoustic name\"}");
  std::map<std::string, std::string> map;
  for (auto& [k, v] : j.items()) {
    if (!v.is_string()) return parseError(path + ": \"" + k + "\" must map to a material name (string)");
    map[k] = v.get<std::string>();
  }
  return map;
}

Result<AirConditions> parseAir(const std::string& text) {
  AirConditions air;
  if (text == "off") {
    air.enabled = false;
    return air;
  }
  double t = 0, h = 0;
  char comma = 0, extra = 0;
  std::istringstream ss(text);
  if (!(ss >> t >> comma >> h) || comma != ',' || (ss >> extra))
    return invalidArgument("--air: '" + text + "' is not TEMP_C,HUMIDITY_PCT or 'off'");
  air.temperatureC = t;
  air.humidityPercent = h;
  Status s = validate(air);
  if (!s.isOk()) return invalidArgument("--air: " + s.message());
  return air;
}

int run(const IrOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  nlohmann::json stats;
  if (o.receiver != "omni") {
    printError("--receiver " + o.receiver + ": only 'omni' is available in this version");
    return 2;
  }
  auto air = parseAir(o.air);
  if (!check(air.status())) return 2;

  // Materials.
  MaterialTable materials = defaultMaterials();
  if (!o.materials.empty()) {
    auto m = loadMaterials(o.materials);
    if (!check(m.status())) return 2;
    materials = std::move(m.value());
  }
  std::map<std::string, std::string> materialMap;
  if (!o.materialMap.empty()) {
    auto m = loadMaterialMap(o.materialMap);
    if (!check(m.status())) return 2;
    materialMap = std::move(m.value());
  }

  // Geometry.
  auto tLoad = std::chrono::steady_clock::now();
  TriangleMesh mesh;
  if (!o.geometry.empty()) {
    auto g = loadGltf(o.geometry, materials, materialMap);
    if (!check(g.status())) return 2;
    for (const auto& w : g->warnings) std::cerr << "earshot: warning: " << w << "\n";
    mesh = std::move(g->mesh);
  }
  stats["load_ms"] = msSince(tLoad);
  auto tBuild = std::chrono::steady_clock::now();
  auto tracer = RayTracer::create(mesh);
  if (!tracer.isOk()) {
    printError(o.geometry + ": " + tracer.status().message());
    return 2;
  }
  stats["bvh_build_ms"] = msSince(tBuild);
  stats["triangles"] = mesh.triangleCount();

  const Vec3d source{o.source[0], o.source[1], o.source[2]};
  const Vec3d listener{o.listener[0], o.listener[1], o.listener[2]};

  // Direct path.
  auto tDirect = std::chrono::steady_clock::now();
  DirectPathSettings ds;
  ds.air = *air;
  DirectPath direct = computeDirectPath(tracer->get(), materials, source, listener, ds);
  stats["direct_ms"] = msSince(tDirect);
  stats["direct"] = {{"distance_m", direct.distanceMeters}, {"delay_s", direct.delaySeconds},
                     {"surfaces_crossed", direct.surfacesCrossed}, {"audible", direct.audible}};

  // Reflections.
  IrSynthesisSettings is;
  is.sampleRateHz = o.rate;
  is.seed = o.seed;
  if (o.length != "auto") {
    try {
      size_t used = 0;
      is.lengthSeconds = std::stod(o.length, &used);
      if (used != o.length.size() || !(is.lengthSeconds > 0)) throw std::invalid_argument("");
    } catch (...) {
      printError("--length: '" + o.length + "' is not a positive number of seconds or 'auto'");
      return 2;
    }
  }
  if (!check(validate(is))) return 2;
  ReflectionSettings rs;
  rs.rays = o.rays;
  rs.bounces = o.bounces;
  rs.seed = o.seed;
  rs.air = *air;
  rs.binSeconds = o.binMs / 1000.0;
  rs.receiverRadiusMeters = o.receiverRadius;
  if (is.lengthSeconds > 0) rs.maxTimeSeconds = is.lengthSeconds;
  if (!check(validate(rs))) return 2;

  std::unique_ptr<ThreadPool> pool = std::make_unique<ThreadPool>(o.threads);
  std::optional<ReflectionResult> reflections;
  if (!(*tracer)->empty() && o.bounces > 0) {
    auto r = traceReflections(**tracer, materials, source, listener, rs, *pool);
    if (!check(r.status())) return 2;
    reflections = std::move(r.value());
    const auto& st = reflections->stats;
    stats["rays_traced"] = st.raysTraced;
    stats["rays_escaped"] = st.raysEscaped;
    stats["segments_traced"] = st.segmentsTraced;
    stats["shadow_rays"] = st.shadowRays;
    stats["energy_escaped_fraction"] = st.energyEscaped;
    stats["energy_after_histogram"] = st.energyLate;
    stats["receiver_radius_m"] = st.receiverRadiusMeters;
    stats["trace_ms"] = st.traceMs;
  } else {
    stats["rays_traced"] = 0;
    stats["reflections"] = (*tracer)->empty() ? "skipped: no geometry" : "skipped: 0 bounces";
  }
  stats["threads"] = pool->threadCount();

  // Synthesis.
  auto tSynth = std::chrono::steady_clock::now();
  auto ir = synthesizeOmniIr(direct.audible ? &direct : nullptr, reflections ? &reflections->histogram : nullptr, is);
  if (!check(ir.status())) return 2;
  stats["synthesis_ms"] = msSince(tSynth);
  stats["ir_samples"] = ir->frameCount();
  stats["sample_rate_hz"] = o.rate;

  if (!check(writeWavFloat(o.output, *ir))) return 2;
  stats["total_ms"] = msSince(t0);
  if (!o.json.empty() && !check(writeTextFileAtomically(o.json, stats.dump(2) + "\n"))) return 2;
  return 0;
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<IrOptions>();
  CLI::App* cmd = root.add_subcommand("ir", "Compute the impulse response from a source to a listener");
  cmd->add_option("geometry", o->geometry, "Scene geometry (glTF 2.0, .gltf or .glb); omit for free field")
      ->check(CLI::ExistingFile);
  addVec3Option(*cmd, "--source", o->source, "Source position in metres")->required();
  addVec3Option(*cmd, "--listener", o->listener, "Listener position in metres")->required();
  cmd->add_option("-o,--output", o->output, "Output WAV (32-bit float; 1 channel for omni)")->required();
  cmd->add_option("--materials", o->materials, "Materials JSON (default: the built-in materials/default.json)");
  cmd->add_option("--material-map", o->materialMap, "JSON object mapping glTF material names to acoustic materials");
  cmd->add_option("--receiver", o->receiver, "Receiver: omni (binaural comes with HRTF support)")
      ->check(CLI::IsMember({"omni", "binaural"}))
      ->capture_default_str();
  cmd->add_option("--rate", o->rate, "Sample rate in Hz")->check(CLI::Range(8000.0, 384000.0))->capture_default_str();
  cmd->add_option("--rays", o->rays, "Rays traced")->check(CLI::Range(1u, 100000000u))->capture_default_str();
  cmd->add_option("--bounces", o->bounces, "Reflections per ray")->check(CLI::Range(0u, 100000u))->capture_default_str();
  cmd->add_option("--length", o->length, "IR length in seconds, or auto")->capture_default_str();
  cmd->add_option("--seed", o->seed, "Random seed (same seed, same output, any thread count)")->capture_default_str();
  cmd->add_option("--threads", o->threads, "Threads (0 = all cores)")->check(CLI::Range(0u, 256u))->capture_default_str();
  cmd->add_option("--air", o->air, "Air absorption: TEMP_C,HUMIDITY_PCT or off (ISO 9613-1)")->capture_default_str();
  cmd->add_option("--json", o->json, "Write statistics (rays, escaped energy, time per stage) to this JSON file");
  cmd->add_option("--bin-ms", o->binMs, "Energy histogram resolution in ms")->check(CLI::Range(0.01, 100.0))->capture_default_str();
  cmd->add_option("--receiver-radius", o->receiverRadius, "Receiver sphere radius for specular paths in m (0 = auto)")
      ->check(CLI::Range(0.0, 1000.0))->capture_default_str();
  cmd->callback([o] { setExitCode(run(*o)); });
});

}  // namespace
}  // namespace earshot::cli
