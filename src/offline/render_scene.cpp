// Offline rendering of a scene file: see render_scene.h.
#include "earshot/offline/render_scene.h"

#include <algorithm>
#include <thread>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <future>
#include <memory>
#include <string>

#include "earshot/core/math.h"
#include "earshot/ir/binaural_synthesis.h"
#include "earshot/io/input_file.h"
#include "earshot/io/wav.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/materials/material.h"
#include "earshot/render/dry_audio.h"
#include "earshot/runtime/engine.h"
#include "earshot/scene/enclosure.h"
#include "earshot/scene/gltf_loader.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot {

namespace {

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

constexpr double kTailSeconds = 2.0;
constexpr double kMaxIrSeconds = 10.0;
// IR updates crossfade over this long (43 ms at 48 kHz): long enough that a
// tone's phase change between two IRs is a glide, not a jolt (a crossfade of
// length T between two different phases of a sine at f changes its slope by
// up to 1 / (2 pi f T): 1.2 % at 300 Hz), short next to the update interval.
constexpr size_t kRenderFadeFrames = 2048;

// What a source's last simulation saw (relative poses decide re-simulation).
struct SimulatedPose {
  bool valid = false;
  Vec3d source, listener, forward, up, sourceForward;
  // Close enough to `o` that the reflections need no new simulation: neither
  // end moved more than minMove metres, the head turned less than minTurn
  // radians. Zero thresholds: any change at all.
  bool closeTo(const SimulatedPose& o, double minMove, double minTurn) const {
    if (!valid || !o.valid) return false;
    if (minMove <= 0 && minTurn <= 0)
      return source == o.source && listener == o.listener && forward == o.forward && up == o.up &&
             sourceForward == o.sourceForward;
    auto angle = [](const Vec3d& a, const Vec3d& b) {
      return std::acos(std::clamp(dot(normalize(a), normalize(b)), -1.0, 1.0));
    };
    return length(source - o.source) <= minMove && length(listener - o.listener) <= minMove &&
           angle(forward, o.forward) <= minTurn && angle(up, o.up) <= minTurn &&
           angle(sourceForward, o.sourceForward) <= minTurn;
  }
};

std::string formatNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

double clampGainDb(double db) { return std::clamp(std::isfinite(db) ? db : -120.0, -120.0, 60.0); }

}  // namespace

double defaultSceneDuration(const SceneDescription& scene, const std::vector<double>& dryLengths) {
  double end = 0.0;
  for (size_t i = 0; i < scene.sources.size() && i < dryLengths.size(); ++i)
    end = std::max(end, scene.sources[i].startSeconds + dryLengths[i]);
  return end + kTailSeconds;
}

Result<size_t> renderOutputChannels(const SceneDescription& scene, const RenderOptions& options) {
  const int order = options.ambisonicOrder.value_or(scene.settings.ambisonicOrder);
  const std::string format = options.outputFormat.value_or(scene.settings.output);
  if (order < 0 || order > kMaxAmbisonicOrder)
    return invalidArgument("ambisonic order " + std::to_string(order) + " is outside [0, 3]");
  if (format == "binaural") return size_t(2);
  if (format != "ambisonic")
    return invalidArgument("output format " + quotedName(format) + " is not binaural or ambisonic");
  if (order == 0) return invalidArgument("ambisonic output needs an ambisonic order of 1-3 (settings.ambisonic_order)");
  return size_t(ambisonicChannels(order));
}

Result<RenderResult> renderScene(const SceneDescription& scene, const RenderOptions& options) {
  const auto t0 = Clock::now();
  RenderResult out;
  const SceneSettings& ss = scene.settings;
  const double fs = ss.sampleRateHz;
  if (scene.sources.empty()) return invalidArgument(scene.sceneFile + ": no sources");

  // Simulation settings: the preset, the scene's overrides, the options'.
  runtime::EngineSettings es;
  es.sampleRateHz = fs;
  es.maxSources = scene.sources.size();
  es.maxIrSeconds = kMaxIrSeconds;
  es.keepSourceIrs = false;  // a render never asks for a source's IR: its slots hold less
  // Offline nothing plays in real time: every core simulates (the engine's
  // own default keeps one for an audio thread), at normal priority.
  es.threads = options.threads > 0 ? options.threads : std::max(1u, std::thread::hardware_concurrency());
  es.workerNice = 0;
  es.fadeFrames = kRenderFadeFrames;
  es.glideGameUpdates = false;  // every block is given the exact poses at its end (setPoses below)
  es.ambisonicOrder = options.ambisonicOrder.value_or(ss.ambisonicOrder);
  auto traceMode = traceModeFromString(options.trace.value_or(ss.trace));
  if (!traceMode.isOk()) return traceMode.status();
  es.traceMode = *traceMode;
  // A listener that stays in place (it may turn): the shared trace's paths,
  // kept, serve every later simulation without a ray traced, whatever the
  // number of sources (a choice the scene file alone makes).
  const bool listenerInPlace = scene.listener.trajectory.isStationary();
  if (es.traceMode == TraceMode::kAuto && listenerInPlace) es.traceMode = TraceMode::kShared;
  auto outChannels = renderOutputChannels(scene, options);
  if (!outChannels.isOk()) return outChannels.status();
  const size_t channels = *outChannels;
  if (channels != 2) es.output = runtime::OutputFormat::kAmbisonic;  // AmbiX: 4, 9 or 16
  const bool ambisonic = es.ambisonicOrder > 0;
  auto preset = qualityPreset(options.quality.value_or(ss.quality));
  if (!preset.isOk()) return preset.status();
  apply(*preset, es.simulation);
  if (ss.rays && !options.quality) es.simulation.rays = *ss.rays;
  if (ss.bounces && !options.quality) es.simulation.bounces = *ss.bounces;
  es.simulation.seed = options.seed.value_or(ss.seed);
  es.simulation.speedOfSound = ss.speedOfSound;
  es.simulation.air.enabled = ss.air.enabled;
  es.simulation.air.temperatureC = ss.air.temperatureC;
  es.simulation.air.humidityPercent = ss.air.humidityPercent;
  es.simulation.air.pressureKpa = ss.air.pressureKpa;
  out.log.push_back(ambisonic ? "reflections: world-frame ambisonics of order " + std::to_string(es.ambisonicOrder) +
                                    ", rotated by the head every block (a head turn needs no simulation)"
                              : std::string("reflections: a binaural IR per source (re-simulated when the head turns)"));
  out.log.push_back(es.traceMode == TraceMode::kShared && *traceMode == TraceMode::kAuto
                        ? std::string("tracing: one listener-centred trace for the sources simulated together, its paths "
                                      "kept (the listener stays in place)")
                    : es.traceMode == TraceMode::kShared ? std::string("tracing: one listener-centred trace for the sources simulated together")
                    : es.traceMode == TraceMode::kAuto
                        ? std::string("tracing: one listener-centred trace for 3 or more sources simulated together, else one from each")
                        : std::string("tracing: a trace from each source"));
  out.log.push_back("quality " + preset->name + ": " + std::to_string(es.simulation.rays) + " rays, " +
                    std::to_string(es.simulation.bounces) + " bounces, image sources to order " +
                    std::to_string(es.simulation.imageSourceOrder) + ", seed " + std::to_string(es.simulation.seed));

  // What the engine will hold before it holds it.
  const uint64_t budget = defaultInputLimits().maxMemoryBytes;
  // Each source's slot with the IRs it may hold (Engine::sourceSlotBytes,
  // which addSource() checks again).
  auto slotBytes = runtime::Engine::sourceSlotBytes(es);
  if (!slotBytes.isOk()) return slotBytes.status();
  const double engineBytes = double(scene.sources.size()) * double(*slotBytes);
  if (engineBytes > double(budget))
    return outOfRange(scene.sceneFile + ": sources: " + std::to_string(scene.sources.size()) +
                      " sources need about " + formatBytes(uint64_t(engineBytes)) +
                      " of convolution state, over the memory limit of " + formatBytes(budget) + " (--max-memory)");
  double heldBytes = engineBytes;
  // And a simulation's trace (its rays' and histogram's state,
  // traceMemoryBytes): the scene's ray count is refused here, naming it,
  // rather than by the first simulation.
  {
    const ReflectionSettings traced = reflectionSettingsOf(es.simulation);
    const double traceBytes = traceMemoryBytes(traced, 1, es.threads);
    if (heldBytes + traceBytes > double(budget))
      return outOfRange(scene.sceneFile + ": " + (ss.rays && !options.quality ? "settings.rays: " : "") +
                        std::to_string(traced.rays) + " rays need about " + formatBytes(uint64_t(traceBytes)) +
                        " for a trace" + (engineBytes > 0 ? " besides " + formatBytes(uint64_t(engineBytes)) +
                        " of convolution state" : std::string()) + ", over the memory limit of " +
                        formatBytes(budget) + " (--max-memory)");
    heldBytes += traceBytes;
  }

  // The HRTF (~0.6 s for the default set) loads on another thread while
  // the geometry and the dry audio load here.
  std::future<Result<std::shared_ptr<const BinauralModel>>> modelLoad = std::async(
      std::launch::async, [path = ss.hrtfPath, fs]() -> Result<std::shared_ptr<const BinauralModel>> {
        try {
          return loadBinauralModel(path, fs);
        } catch (const std::bad_alloc&) {
          return outOfRange("HRTF: out of memory while loading it");
        }
      });
  struct WaitForModel {  // an early return waits for the loader, never leaves it running
    std::future<Result<std::shared_ptr<const BinauralModel>>>& f;
    ~WaitForModel() {
      if (f.valid()) f.wait();
    }
  } waitForModel{modelLoad};

  // Geometry and materials.
  auto materials = std::make_shared<MaterialTable>(defaultMaterials());
  if (!scene.materialsPath.empty()) {
    auto m = loadMaterials(scene.materialsPath);
    if (!m.isOk()) return m.status();
    *materials = std::move(m.value());
  }
  TriangleMesh mesh;
  if (!scene.geometryPath.empty()) {
    auto g = loadGltf(scene.geometryPath, *materials, scene.materialMap);
    if (!g.isOk()) return g.status();
    for (const auto& w : g->warnings) out.log.push_back("warning: " + w);
    mesh = std::move(g->mesh);
    out.log.push_back(scene.geometryPath + ": " + std::to_string(mesh.triangleCount()) + " triangles");
  } else {
    out.log.push_back("no geometry: free field");
  }
  auto tracer = RayTracer::create(mesh);
  if (!tracer.isOk()) return Status(tracer.status().code(), scene.geometryPath + ": " + tracer.status().message());
  std::shared_ptr<const RayTracer> sharedTracer = std::move(tracer.value());
  if (!sharedTracer->empty()) {  // valid, but a listener outside a closed room hears nothing of it
    const bool closed = isClosedMesh(mesh);
    if (enclosureOf(*sharedTracer, closed, scene.listener.trajectory.at(0).position) == Enclosure::kOutside)
      out.log.push_back("warning: the listener starts outside the closed volume of " + displayPath(scene.geometryPath));
    for (const SceneSource& src : scene.sources)
      if (enclosureOf(*sharedTracer, closed, src.trajectory.at(src.startSeconds).position) == Enclosure::kOutside)
        out.log.push_back("warning: source " + quotedName(src.name) + " starts outside the closed volume of " +
                          displayPath(scene.geometryPath));
  }

  // Dry audio, while the HRTF still loads: each file once, however many
  // sources play it (dry[dryOf[i]] is source i's).
  std::vector<DryAudio> dry;
  std::vector<size_t> dryOf;
  std::vector<double> dryLengths;
  for (const SceneSource& src : scene.sources) {
    size_t k = 0;
    while (k < dryOf.size() && scene.sources[k].audioPath != src.audioPath) ++k;
    if (k < dryOf.size()) {
      dryOf.push_back(dryOf[k]);
      out.log.push_back("source " + quotedName(src.name) + ": the audio of source " + quotedName(scene.sources[k].name));
    } else {
      std::string line;
      auto d = loadDryAudio(src.audioPath, fs, &line);
      if (!d.isOk()) return Status(d.status().code(), "source " + quotedName(src.name) + ": " + d.status().message());
      out.log.push_back("source " + quotedName(src.name) + ": " + line);
      heldBytes += double(d->samples.size()) * sizeof(float);
      if (heldBytes > double(budget))
        return outOfRange("source " + quotedName(src.name) + ": " + src.audioPath + ": the sources' dry audio and convolution "
                          "state need over the memory limit of " + formatBytes(budget) + " (--max-memory)");
      dryOf.push_back(dry.size());
      dry.push_back(std::move(d.value()));
    }
    dryLengths.push_back(double(dry[dryOf.back()].samples.size()) / fs);
  }

  // HRTF and engine.
  auto model = modelLoad.get();
  if (!model.isOk()) return model.status();
  out.log.push_back("HRTF: " + (*model)->hrtf().path());
  auto created = runtime::Engine::create(es, *model);
  if (!created.isOk()) return created.status();
  runtime::Engine& engine = **created;
  engine.setScene(sharedTracer, materials);

  // Sources.
  std::vector<uint32_t> ids;
  std::vector<long long> startFrame;
  const bool listenerStatic = scene.listener.trajectory.isStatic();
  for (const SceneSource& src : scene.sources) {
    runtime::SourceSettings s;
    s.gainDb = clampGainDb(src.gainDb);
    s.directivityAlpha = src.directivityAlpha;
    s.directivitySharpness = src.directivitySharpness;
    if (src.directivityBands.size() == size_t(kNumBands)) {
      s.directivityPerBand = true;
      for (int b = 0; b < kNumBands; ++b) s.directivityBandAlpha[size_t(b)] = src.directivityBands[size_t(b)];
    }
    s.directGainDb = src.directGainDb;
    s.reflectionsGainDb = src.reflectionsGainDb;
    s.distance.model = src.distanceModel == "inverse"       ? runtime::DistanceModel::kInverse
                       : src.distanceModel == "linear"      ? runtime::DistanceModel::kLinear
                       : src.distanceModel == "exponential" ? runtime::DistanceModel::kExponential
                       : src.distanceModel == "table"       ? runtime::DistanceModel::kTable
                                                            : runtime::DistanceModel::kPhysical;
    s.distance.table = src.distanceTable;
    s.distance.minDistance = src.minDistance;
    s.distance.maxDistance = src.maxDistance;
    s.distance.rolloff = src.rolloff;
    s.occlusion = src.occlusion == "off"          ? runtime::OcclusionMode::kOff
                  : src.occlusion == "volumetric" ? runtime::OcclusionMode::kVolumetric
                                                  : runtime::OcclusionMode::kRay;
    s.radiusMeters = src.radius;
    s.transmission = src.transmission;
    s.priority = src.priority;
    // With ambisonic reflections the direct sound always follows the head
    // per block (its exact HRTF), and a still source (whatever the head
    // does, if the listener stays in place) is simulated once.
    const bool still = (ambisonic ? scene.listener.trajectory.isStationary() : listenerStatic) &&
                       src.trajectory.isStatic();
    s.direct = still && !ambisonic ? runtime::DirectMode::kInImpulseResponse : runtime::DirectMode::kPerBlock;
    out.log.push_back("source " + quotedName(src.name) + ": " +
                      (still && !ambisonic ? "static: simulated once, direct sound inside its IR (exact convolution)"
                       : still ? "static: simulated once, direct sound rendered per block"
                               : "moving: direct sound rendered per block; reflections checked " +
                                     formatNumber(ss.updateRateHz) + " times a second, simulated again after " +
                                     formatNumber(options.minMoveMeters) + " m of motion" +
                                     (ambisonic ? std::string()
                                                : " or " + formatNumber(options.minTurnDegrees) +
                                                      " degrees of head turn")));
    auto id = engine.addSource(s);
    if (!id.isOk()) return id.status();
    ids.push_back(*id);
    startFrame.push_back(std::llround(src.startSeconds * fs));
  }

  // Time window.
  const double duration = ss.durationSeconds.value_or(defaultSceneDuration(scene, dryLengths));
  const double to = options.toSeconds.value_or(duration);
  if (!(options.fromSeconds >= 0) || !(to > options.fromSeconds))
    return invalidArgument("--from " + std::to_string(options.fromSeconds) + " / --to " + std::to_string(to) +
                           ": the window must satisfy 0 <= from < to");
  const double begin = std::max(0.0, options.fromSeconds - std::max(0.0, options.preRollSeconds));
  const long long firstFrame = std::llround(begin * fs);
  const long long outFirstFrame = std::llround(options.fromSeconds * fs);
  const long long endFrame = std::llround(to * fs);
  const size_t outFrames = size_t(endFrame - outFirstFrame);
  const size_t latency = engine.latencyFrames();
  const size_t block = latency;
  const size_t processFrames = size_t(endFrame - firstFrame) + latency;
  const double outBytes = double(outFrames) * double(channels) * sizeof(float);
  if (options.sink && outBytes > double(kMaxWavBytes))
    return outOfRange(scene.sceneFile + ": " + formatNumber(to - options.fromSeconds) + " s of " +
                      std::to_string(channels) + "-channel audio at " + formatNumber(fs) + " Hz is " +
                      formatBytes(uint64_t(outBytes)) +
                      ", more than a WAV file holds (4 GiB); render it in parts with --from/--to");
  if (!options.sink && heldBytes + outBytes > double(budget))
    return outOfRange(scene.sceneFile + ": " + formatNumber(to - options.fromSeconds) +
                      " s of output held in memory need " + formatBytes(uint64_t(outBytes)) +
                      ", over the memory limit of " + formatBytes(budget) + " (--max-memory)");
  if (!options.sink) out.audio = AudioBuffer(channels, outFrames, fs);
  else out.audio = AudioBuffer(channels, 0, fs);
  std::vector<std::vector<float>> pending(channels);
  if (options.sink)
    for (auto& p : pending) p.reserve(block);

  std::vector<std::vector<float>> input(ids.size(), std::vector<float>(block, 0.0f));
  std::vector<const float*> inputs(es.maxSources, nullptr);
  for (size_t i = 0; i < ids.size(); ++i) inputs[ids[i]] = input[i].data();
  std::vector<std::vector<float>> rendered(channels, std::vector<float>(block));
  std::vector<float*> renderedPtrs(channels);
  for (size_t c = 0; c < channels; ++c) renderedPtrs[c] = rendered[c].data();
  std::vector<SimulatedPose> simulated(ids.size());
  const long long updateFrames = std::max<long long>(1, std::llround(fs / ss.updateRateHz));
  long long nextUpdate = firstFrame;
  double lastProgress = -1.0;

  auto setPoses = [&](double t) -> Status {
    const Pose lp = scene.listener.trajectory.at(t);
    EARSHOT_RETURN_IF_ERROR(engine.setListener(lp.position, {lp.forward, lp.up}));
    for (size_t i = 0; i < ids.size(); ++i) {
      const Pose sp = scene.sources[i].trajectory.at(t);
      EARSHOT_RETURN_IF_ERROR(engine.setSourcePosition(ids[i], sp.position));
      // The pattern's axis; the engine weights the direct sound toward the
      // listener and each reflection by its own emission direction.
      EARSHOT_RETURN_IF_ERROR(engine.setSourceOrientation(ids[i], sp.forward));
    }
    return Status::ok();
  };

  for (size_t f = 0; f < processFrames; f += block) {
    const long long sceneFrame = firstFrame + (long long)f;
    // Acoustic update: re-simulate the sources whose relative pose changed.
    if (sceneFrame >= nextUpdate) {
      const double t = double(sceneFrame) / fs;
      EARSHOT_RETURN_IF_ERROR(setPoses(t));
      const Pose lp = scene.listener.trajectory.at(t);
      std::vector<uint32_t> changed;
      for (size_t i = 0; i < ids.size(); ++i) {
        const Pose sp = scene.sources[i].trajectory.at(t);
        SimulatedPose now{true, sp.position, lp.position, lp.forward, lp.up,
                          // A directional source's reflections change when it turns.
                          scene.sources[i].directivityAlpha == 0.0 && scene.sources[i].directivityBands.empty()
                              ? Vec3d{0, 0, -1}
                              : sp.forward};
        if (ambisonic) {  // the head's turn is the audio thread's
          now.forward = {0, 0, -1};
          now.up = {0, 1, 0};
        }
        if (!now.closeTo(simulated[i], options.minMoveMeters, options.minTurnDegrees * kPi / 180.0)) {
          changed.push_back(ids[i]);
          simulated[i] = now;
        }
      }
      if (!changed.empty()) {
        const auto ts = Clock::now();
        EARSHOT_RETURN_IF_ERROR(engine.simulate(changed));
        out.simulationSeconds += secondsSince(ts);
        out.simulations += changed.size();
      }
      while (nextUpdate <= sceneFrame) nextUpdate += updateFrames;
    }
    // Poses at the block's end: the direct sound moves across the block.
    EARSHOT_RETURN_IF_ERROR(setPoses(double(sceneFrame + (long long)block) / fs));
    for (size_t i = 0; i < ids.size(); ++i) {
      const std::vector<float>& x = dry[dryOf[i]].samples;
      for (size_t k = 0; k < block; ++k) {
        const long long at = sceneFrame + (long long)k - startFrame[i];
        input[i][k] = at >= 0 && at < (long long)x.size() ? x[size_t(at)] : 0.0f;
      }
    }
    const auto ta = Clock::now();
    engine.process(inputs.data(), renderedPtrs.data(), block);
    out.audioProcessSeconds += secondsSince(ta);
    // Output frame f is scene frame firstFrame + f - latency.
    for (auto& p : pending) p.clear();
    for (size_t k = 0; k < block; ++k) {
      const long long sceneOut = firstFrame + (long long)(f + k) - (long long)latency;
      const long long o = sceneOut - outFirstFrame;
      if (o >= 0 && o < (long long)outFrames) {
        for (size_t c = 0; c < channels; ++c) {
          const float v = rendered[c][k];
          out.peak = std::max(out.peak, double(std::fabs(v)));
          if (options.sink)
            pending[c].push_back(v);
          else
            out.audio.channels[c][size_t(o)] = v;
        }
      }
    }
    if (options.sink && !pending[0].empty()) {
      std::vector<const float*> planar(channels);
      for (size_t c = 0; c < channels; ++c) planar[c] = pending[c].data();
      EARSHOT_RETURN_IF_ERROR(options.sink(planar.data(), pending[0].size()));
    }
    if (options.progress) {
      const double fraction = double(f + block) / double(processFrames);
      if (fraction - lastProgress >= 0.01 || f + block >= processFrames) {
        options.progress(std::min(1.0, fraction));
        lastProgress = fraction;
      }
    }
  }
  out.clipped = out.peak > 1.0;
  out.audioSeconds = double(outFrames) / fs;
  out.wallSeconds = secondsSince(t0);
  return out;
}

}  // namespace earshot
