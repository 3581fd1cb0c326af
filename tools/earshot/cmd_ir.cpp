// `earshot ir`: the impulse response of one source/listener pair.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>

#include <nlohmann/json.hpp>

#include "command.h"
#include "earshot/core/thread_pool.h"
#include "earshot/io/atomic_file.h"
#include "earshot/io/input_file.h"
#include "earshot/io/wav.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/ir/ir_report.h"
#include "earshot/ir/third_octave.h"
#include "earshot/materials/material.h"
#include "earshot/scene/enclosure.h"
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
  std::string receiver = "binaural";
  std::string hrtf;
  int order = 1;
  std::array<double, 3> forward{0.0, 0.0, -1.0}, up{0.0, 1.0, 0.0};
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
  std::string quality = "balanced";
  uint32_t ismOrder = 3;
  uint32_t tailProbes = kEveryRay;
  double convergeDb = 0.0;
  std::string trace = "per-source";
  double shadowRoulette = ReflectionSettings{}.sharedShadowRoulette;
  bool noFlutterCones = false;
  std::string bands = "octave";
};

int run(const IrOptions& o, const CLI::App& cmd) {
  const auto t0 = std::chrono::steady_clock::now();
  nlohmann::json stats;
  if (o.receiver != "binaural" && !o.hrtf.empty()) {
    printError("--hrtf: an HRTF applies only to --receiver binaural");
    return 2;
  }
  if (o.receiver != "ambisonic" && cmd.count("--order")) {
    printError("--order: applies only to --receiver ambisonic");
    return 2;
  }
  const bool thirdOctave = o.bands == "third-octave";
  if (thirdOctave && o.trace != "per-source") {
    printError("--bands third-octave: traces per source (--trace per-source)");
    return 2;
  }
  auto air = parseCliAir(o.air);
  if (!check(air.status())) return 2;

  // Settings: the preset, then any explicit option over it.
  OmniIrSettings settings;
  auto preset = qualityPreset(o.quality);
  if (!preset.isOk()) {
    printError("--quality: " + preset.status().message());
    return 2;
  }
  apply(*preset, settings);
  if (cmd.count("--rays")) settings.rays = o.rays;
  if (cmd.count("--bounces")) settings.bounces = o.bounces;
  if (cmd.count("--ism-order")) settings.imageSourceOrder = o.ismOrder;
  if (cmd.count("--bin-ms")) settings.binSeconds = o.binMs / 1000.0;
  if (cmd.count("--tail-probes")) settings.tailProbes = o.tailProbes;
  settings.convergenceDb = o.convergeDb;
  settings.flutterCones = !o.noFlutterCones;
  settings.sharedShadowRoulette = o.shadowRoulette;
  settings.sampleRateHz = o.rate;
  settings.seed = o.seed;
  settings.air = *air;
  settings.receiverRadiusMeters = o.receiverRadius;
  if (o.length != "auto") {
    try {
      size_t used = 0;
      settings.lengthSeconds = std::stod(o.length, &used);
      if (used != o.length.size() || !(settings.lengthSeconds > 0)) throw std::invalid_argument("");
    } catch (...) {
      printError("--length: '" + o.length + "' is not a positive number of seconds or 'auto'");
      return 2;
    }
  }

  // Materials and geometry.
  auto tLoad = std::chrono::steady_clock::now();
  auto scene = loadSceneInputs(o.geometry, o.materials, o.materialMap);
  if (!check(scene.status())) return 2;
  const MaterialTable& materials = scene->materials;
  const TriangleMesh& mesh = scene->mesh;
  auto& tracer = scene->tracer;
  stats["load_and_bvh_ms"] = msSince(tLoad);
  stats["triangles"] = mesh.triangleCount();
  stats["planes"] = tracer->planes().planes.size();

  // Binaural receiver: the HRTF set (never a silent fallback to the default
  // when a file is named) and the listener's orientation.
  std::unique_ptr<BinauralReceiver> binaural;
  if (o.receiver == "binaural") {
    binaural = std::make_unique<BinauralReceiver>();
    binaural->orientation.forward = {o.forward[0], o.forward[1], o.forward[2]};
    binaural->orientation.up = {o.up[0], o.up[1], o.up[2]};
    if (!check(validate(binaural->orientation))) return 2;
    auto model = loadBinauralModel(o.hrtf, o.rate);
    if (!check(model.status())) return 2;
    binaural->model = *model;
    stats["hrtf"] = binaural->model->hrtf().path();
  }

  // Ambisonic receiver: AmbiX channels in the listener's frame (x forward,
  // y left, z up from --forward and --up).
  std::unique_ptr<AmbisonicReceiver> ambisonic;
  if (o.receiver == "ambisonic") {
    ListenerOrientation orientation;
    orientation.forward = {o.forward[0], o.forward[1], o.forward[2]};
    orientation.up = {o.up[0], o.up[1], o.up[2]};
    if (!check(validate(orientation))) return 2;
    ambisonic = std::make_unique<AmbisonicReceiver>();
    ambisonic->order = o.order;
    ambisonic->frame.worldToFrame = worldToAmbisonicFrame(orientation.forward, orientation.up);
    stats["ambisonic"] = {{"order", o.order}, {"channel_order", "ACN"}, {"normalisation", "SN3D"},
                          {"frame", "listener: x forward, y left, z up"}};
  }

  // Every input is read now: refuse an output that would replace one (or a
  // FIFO, a device) before computing (the writes check again).
  if (!check(checkOutputPaths({o.output, o.json}, {"-o", "--json"}))) return 2;
  if (!check(audioFormatForPath(o.output).status())) return 2;

  ThreadPool pool(o.threads);
  const Vec3d source{o.source[0], o.source[1], o.source[2]};
  const Vec3d listener{o.listener[0], o.listener[1], o.listener[2]};
  // Valid but probably not meant: say so (stderr and --json "warnings").
  std::vector<std::string> warnings = scene->warnings;
  if (!tracer->empty()) {
    const bool closed = isClosedMesh(mesh);
    for (auto [p, name] : {std::pair{listener, "listener"}, std::pair{source, "source"}})
      if (enclosureOf(*tracer, closed, p) == Enclosure::kOutside)
        warn(std::string(name) + " at " + std::to_string(p.x) + "," + std::to_string(p.y) + "," + std::to_string(p.z) +
                 " lies outside the closed volume of " + o.geometry,
             warnings);
  }
  const double minDistance = DirectPathSettings{}.minDistanceMeters;
  if (length(source - listener) < minDistance) {
    char text[160];
    std::snprintf(text, sizeof text, "source and listener are %.3g m apart: the direct sound's 1/r is clamped at %g m",
                  length(source - listener), minDistance);
    warn(text, warnings);
  }
  const TraceMode traceMode = *traceModeFromString(o.trace);
  if (traceMode == TraceMode::kShared && o.convergeDb > 0 &&
      !check(invalidArgument("--converge works with --trace per-source only (a shared trace traces every ray)")))
    return 2;
  if (traceMode != TraceMode::kShared && cmd.count("--shadow-roulette") &&
      !check(invalidArgument("--shadow-roulette applies to --trace shared only")))
    return 2;
  Result<std::vector<OmniIrResult>> result = std::vector<OmniIrResult>{};
  Result<ThirdOctaveIrResult> thirds = ThirdOctaveIrResult{};
  if (thirdOctave) {
    thirds = computeIrThirdOctave(*tracer, materials, source, listener, settings, pool, binaural.get(), ambisonic.get());
    if (!check(thirds.status())) return 2;
  } else {
    IrRequest request;
    request.source = source;
    request.directivity = settings.directivity;
    request.includeDirect = settings.includeDirect;
    result = computeIrs(*tracer, materials, listener, {request}, settings, traceMode, pool, binaural.get(),
                        ambisonic.get());
    if (!check(result.status())) return 2;
  }
  // The unshifted pass stands for a third-octave IR's top-level report.
  const OmniIrResult& r = thirdOctave ? thirds->passes[1] : result->front();
  const AudioBuffer& irOut = thirdOctave ? thirds->ir : r.ir;

  // The result's own report (shared with the Python package), then what
  // only the command knows.
  nlohmann::json report = nlohmann::json::parse(thirdOctave ? thirdOctaveReportJson(*thirds, settings, !tracer->empty())
                                                            : irReportJson(r, settings, !tracer->empty()));
  for (auto& [key, value] : report.items()) stats[key] = std::move(value);
  if (!thirdOctave) stats["bands"] = o.bands;
  stats["quality"] = o.quality;
  stats["receiver"] = o.receiver;
  stats["trace"] = o.trace;
  stats["threads"] = pool.threadCount();
  if (stats["silent"].get<bool>()) warn("the IR is silent: nothing of the source reaches the listener", warnings);
  for (const std::string& w : thirdOctave ? thirdOctaveIrWarnings(*thirds) : irWarnings(r)) warn(w, warnings);

  uint64_t clipped = 0;
  if (!check(writeAudioFile(o.output, irOut, &clipped))) return 2;
  if (clipped > 0)
    warn(std::to_string(clipped) + " samples beyond full scale were clipped in " + o.output +
             " (a source closer than 1 m; .wav keeps them as float)",
         warnings);
  stats["warnings"] = warnings;
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
  cmd->add_option("-o,--output", o->output, "Output audio file, format by extension: .wav (32-bit float; also for a name without one), .flac (24-bit), .ogg (Vorbis); binaural: 2 channels left, right; omni: 1; ambisonic: (order+1)^2 AmbiX (ACN, SN3D)")
      ->required();
  cmd->add_option("--materials", o->materials, "Materials JSON (default: the built-in materials/default.json)");
  cmd->add_option("--material-map", o->materialMap, "JSON object mapping glTF material names to acoustic materials");
  cmd->add_option("--receiver", o->receiver,
                  "Receiver: binaural (HRTF, 2 channels), omni (1 channel) or ambisonic (AmbiX: ACN order, SN3D, "
                  "(order+1)^2 channels in the listener's frame, x forward, y left, z up; W is the omni IR)")
      ->check(CLI::IsMember({"omni", "binaural", "ambisonic"}))
      ->capture_default_str();
  cmd->add_option("--order", o->order, "Ambisonic order, 1-3 (--receiver ambisonic)")
      ->check(CLI::Range(1, kMaxAmbisonicOrder))
      ->capture_default_str();
  cmd->add_option("--hrtf", o->hrtf, "HRTF set (SOFA SimpleFreeFieldHRIR); default: the shipped Neumann KU100 set")
      ->check(CLI::ExistingFile);
  addVec3Option(*cmd, "--forward", o->forward, "Listener forward vector (default 0,0,-1)");
  addVec3Option(*cmd, "--up", o->up, "Listener up vector (default 0,1,0)");
  cmd->add_option("--rate", o->rate, "Sample rate in Hz (binaural: at most 192000, the HRTF's)")->check(CLI::Range(8000.0, 384000.0))->capture_default_str();
  cmd->add_option("--rays", o->rays, "Rays traced (balanced: 16384)")->check(CLI::Range(1u, 100000000u));
  cmd->add_option("--bounces", o->bounces, "Reflections per ray (balanced: 12)")->check(CLI::Range(0u, 100000u));
  cmd->add_option("--length", o->length, "IR length in seconds, or auto")->capture_default_str();
  cmd->add_option("--seed", o->seed, "Random seed (same seed, same output, any thread count)")
      ->check(kUnsigned64())
      ->capture_default_str();
  cmd->add_option("--threads", o->threads, "Threads (0 = all cores)")->check(CLI::Range(0u, 256u))->capture_default_str();
  cmd->add_option("--air", o->air, "Air absorption: TEMP_C,HUMIDITY_PCT or off (ISO 9613-1)")->capture_default_str();
  cmd->add_option("--json", o->json, "Write statistics (rays, escaped energy, time per stage) to this JSON file");
  cmd->add_option("--bin-ms", o->binMs, "Energy histogram resolution in ms (balanced: 1)")->check(CLI::Range(0.01, 100.0));
  cmd->add_option("--receiver-radius", o->receiverRadius, "Receiver sphere radius for specular paths in m (0 = auto)")
      ->check(CLI::Range(0.0, 1000.0))->capture_default_str();
  cmd->add_option("--quality", o->quality, "Preset: draft | balanced | high | reference (explicit options override it)")
      ->check(CLI::IsMember({"draft", "balanced", "high", "reference"}))
      ->capture_default_str();
  cmd->add_option("--ism-order", o->ismOrder, "Image-source order of early specular reflections (0 = none)")
      ->check(CLI::Range(0u, kMaxImageSourceOrder));
  cmd->add_option("--tail-probes", o->tailProbes,
                  "Rays that carry on past the bounce limit until 60 dB down, detected by the receiver sphere "
                  "alone, to measure the tail (every preset: all rays; 0 = extrapolate at one rate)")
      ->check(CLI::Range(0u, 100000000u));
  cmd->add_flag("--no-flutter-cones", o->noFlutterCones,
               "Spread every ray evenly over the sphere; by default, where a pair of parallel walls reflects "
               "specularly, 1/8 of the rays sample directions near their normal densely (unbiased; flutter_axes and "
               "flutter_cone_rays in --json)");
  cmd->add_option("--trace", o->trace,
                  "How reflections are traced: per-source (rays leave the source, the listener detects them) or "
                  "shared (rays leave the listener, the source detects them: the runtime's one trace for many "
                  "sources; by reciprocity the same energies)")
      ->check(CLI::IsMember({"per-source", "shared"}))
      ->capture_default_str();
  cmd->add_option("--shadow-roulette", o->shadowRoulette,
                  "--trace shared: a reflection sends the source its shadow ray with probability min(1, this x R^2 "
                  "cos / d^2) (R: the source's detection sphere), the detection counting 1/p (unbiased; fewer "
                  "shadow rays, a little more noise; shadow_rays_rouletted in --json; 0 = every shadow ray)")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  cmd->add_option("--converge", o->convergeDb,
                  "Stop tracing once the late histogram's estimated error (every 10 ms window within 20 dB of its "
                  "peak) is below this many dB; rays_traced in --json says how many were (0 = all rays)")
      ->check(CLI::Range(0.0, 20.0))
      ->capture_default_str();
  cmd->add_option("--bands", o->bands,
                  "Frequency bands: octave (125 Hz - 8 kHz) or third-octave (100 Hz - 10 kHz, 21 bands: three "
                  "passes of the octave pipeline shifted by a third of an octave, combined; materials given in "
                  "third octaves are used as such; about 3x the time; every receiver; the per-band "
                  "traced decay in --json's third_octave)")
      ->check(CLI::IsMember({"octave", "third-octave"}))
      ->capture_default_str();
  cmd->callback([o, cmd] { setExitCode(run(*o, *cmd)); });
});

}  // namespace
}  // namespace earshot::cli
