// earshot._earshot: the engine for Python (pybind11). The Python package
// (python/earshot/) wraps these low-level calls: argument checks with
// Python's own exceptions there, the engine's checks here (every Status
// becomes an exception carrying its message). Heavy work runs with the GIL
// released.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "earshot/analysis/binaural.h"
#include "earshot/analysis/compare.h"
#include "earshot/analysis/room_acoustics.h"
#include "earshot/core/math.h"
#include "earshot/core/thread_pool.h"
#include "earshot/io/input_file.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/ir/ir_report.h"
#include "earshot/ir/third_octave.h"
#include "earshot/materials/material.h"
#include "earshot/offline/render_scene.h"
#include "earshot/render/scene_file.h"
#include "earshot/scene/enclosure.h"
#include "earshot/scene/gltf_loader.h"
#include "earshot/scene/ray_tracer.h"

namespace py = pybind11;
using namespace earshot;

namespace {

/** Raises the Python exception that fits `status` (called with the GIL held). */
[[noreturn]] void raise(const Status& status) {
  // The engine names the memory limit by the CLI's option; Python sets it
  // with earshot.set_memory_limit.
  const std::string msg = renamedMemoryLimit(status.message(), "earshot.set_memory_limit");
  switch (status.code()) {
    case StatusCode::kNotFound:
      PyErr_SetString(PyExc_FileNotFoundError, msg.c_str());
      throw py::error_already_set();
    case StatusCode::kIoError:
      PyErr_SetString(PyExc_OSError, msg.c_str());
      throw py::error_already_set();
    case StatusCode::kInvalidArgument:
    case StatusCode::kParseError:
    case StatusCode::kUnsupported:
    case StatusCode::kOutOfRange:
      throw py::value_error(msg);
    default:
      throw std::runtime_error(msg);
  }
}

template <typename T>
T take(Result<T>&& r) {
  if (!r.isOk()) raise(r.status());
  return std::move(r.value());
}

Vec3d vec(const std::array<double, 3>& a) { return {a[0], a[1], a[2]}; }

void checkVec(const char* name, const std::array<double, 3>& a) {
  for (double v : a)
    if (!std::isfinite(v)) throw py::value_error(std::string(name) + ": coordinates must be finite");
}

/** A loaded scene: materials, geometry in a tracer, and the HRTF models
 *  made for it so far (one per file and rate). Read-only once built, so IRs
 *  of one scene run on many threads at once. */
struct SceneData {
  MaterialTable materials;
  TriangleMesh mesh;
  std::unique_ptr<RayTracer> tracer;
  std::vector<std::string> warnings;
  std::string name;
  bool closed = false;
  std::mutex hrtfMutex;
  std::map<std::pair<std::string, double>, std::shared_ptr<const BinauralModel>> hrtfs;

  void finish() {
    tracer = take(RayTracer::create(mesh));
    closed = !tracer->empty() && isClosedMesh(mesh);
  }

  /** Loads a model once per (path, rate); called without the GIL. */
  Result<std::shared_ptr<const BinauralModel>> hrtf(const std::string& path, double rate) {
    std::lock_guard<std::mutex> lock(hrtfMutex);
    auto key = std::make_pair(path, rate);
    auto it = hrtfs.find(key);
    if (it != hrtfs.end()) return it->second;
    auto model = loadBinauralModel(path, rate);
    if (!model.isOk()) return model.status();
    hrtfs[key] = *model;
    return *model;
  }
};

MaterialTable materialsFrom(const std::optional<std::string>& path, const std::optional<std::string>& text) {
  if (path) return take(loadMaterials(*path));
  if (text) return take(parseMaterials(*text, "materials"));
  return defaultMaterials();
}

std::shared_ptr<SceneData> loadScene(const std::optional<std::string>& geometry,
                                     const std::optional<std::string>& materialsPath,
                                     const std::optional<std::string>& materialsText,
                                     const std::optional<std::string>& materialMapPath,
                                     const std::map<std::string, std::string>& materialMap, bool allowOutsidePaths,
                                     uint64_t maxMemoryBytes) {
  auto scene = std::make_shared<SceneData>();
  scene->materials = materialsFrom(materialsPath, materialsText);
  std::map<std::string, std::string> map = materialMap;
  if (materialMapPath) map = take(loadMaterialMap(*materialMapPath));
  if (geometry) {
    InputLimits limits = defaultInputLimits();
    limits.allowOutsidePaths = allowOutsidePaths;
    if (maxMemoryBytes > 0) limits.maxMemoryBytes = maxMemoryBytes;
    Result<GltfLoadResult> loaded = Status::ok();
    {
      py::gil_scoped_release release;
      loaded = loadGltf(*geometry, scene->materials, map, limits);
    }
    auto g = take(std::move(loaded));
    scene->warnings = std::move(g.warnings);
    scene->mesh = std::move(g.mesh);
    scene->name = *geometry;
  }
  scene->finish();
  return scene;
}

/** from_arrays: vertices (N, 3) float64, triangles (M, 3) int64, one index
 *  per triangle into `names` (materials looked up by name in the table). */
std::shared_ptr<SceneData> sceneFromArrays(py::array_t<double, py::array::c_style | py::array::forcecast> vertices,
                                           py::array_t<int64_t, py::array::c_style | py::array::forcecast> triangles,
                                           py::array_t<int64_t, py::array::c_style | py::array::forcecast> ids,
                                           const std::vector<std::string>& names,
                                           const std::optional<std::string>& materialsPath,
                                           const std::optional<std::string>& materialsText) {
  if (vertices.ndim() != 2 || vertices.shape(1) != 3) throw py::value_error("vertices: expected shape (N, 3)");
  if (triangles.ndim() != 2 || triangles.shape(1) != 3) throw py::value_error("triangles: expected shape (M, 3)");
  if (ids.ndim() != 1 || ids.shape(0) != triangles.shape(0))
    throw py::value_error("material_ids: expected one index per triangle, shape (" +
                          std::to_string(triangles.shape(0)) + ",)");
  // 2^32 - 1 indices at most (the mesh's index type).
  if (vertices.shape(0) >= (py::ssize_t(1) << 32)) throw py::value_error("vertices: more than 2^32 - 1");
  auto scene = std::make_shared<SceneData>();
  scene->materials = materialsFrom(materialsPath, materialsText);
  std::vector<uint32_t> tableIds;
  for (const auto& n : names) {
    auto id = scene->materials.find(n);
    if (!id) throw py::value_error("materials: no material named \"" + n + "\"");
    tableIds.push_back(*id);
  }
  const size_t n = size_t(vertices.shape(0)), m = size_t(triangles.shape(0));
  auto v = vertices.unchecked<2>();
  auto t = triangles.unchecked<2>();
  auto id = ids.unchecked<1>();
  scene->mesh.positions.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(v(i, k)) || std::abs(v(i, k)) > kMaxCoordinateMeters)
        throw py::value_error("vertices[" + std::to_string(i) + "]: coordinates must be finite and within " +
                              std::to_string(int(kMaxCoordinateMeters)) + " m");
    scene->mesh.positions.push_back({float(v(i, 0)), float(v(i, 1)), float(v(i, 2))});
  }
  scene->mesh.triangles.reserve(m);
  scene->mesh.materialIds.reserve(m);
  for (size_t i = 0; i < m; ++i) {
    std::array<uint32_t, 3> tri{};
    for (int k = 0; k < 3; ++k) {
      if (t(i, k) < 0 || size_t(t(i, k)) >= n)
        throw py::value_error("triangles[" + std::to_string(i) + "]: vertex index " + std::to_string(t(i, k)) +
                              " outside [0, " + std::to_string(n) + ")");
      tri[size_t(k)] = uint32_t(t(i, k));
    }
    if (id(i) < 0 || size_t(id(i)) >= tableIds.size())
      throw py::value_error("material_ids[" + std::to_string(i) + "]: " + std::to_string(id(i)) + " outside [0, " +
                            std::to_string(tableIds.size()) + ")");
    scene->mesh.triangles.push_back(tri);
    scene->mesh.materialIds.push_back(tableIds[size_t(id(i))]);
  }
  scene->name = "arrays";
  scene->finish();
  return scene;
}

/** What one ir() call asks for, checked. */
struct IrOptions {
  OmniIrSettings settings;
  bool binaural = false;
  int ambisonicOrder = 0;  ///< > 0: an ambisonic receiver of this order
  std::string hrtfPath;
  ListenerOrientation orientation;
  std::string quality;
  std::string receiver;
  TraceMode trace = TraceMode::kPerSource;
  bool thirdOctave = false;  ///< bands="third-octave": computeIrThirdOctave per source
};

IrOptions makeRequest(const std::string& receiver, const std::array<double, 3>& forward,
                      const std::array<double, 3>& up, const std::string& quality, std::optional<uint32_t> rays,
                      std::optional<uint32_t> bounces, std::optional<uint32_t> ismOrder, std::optional<double> binMs,
                      std::optional<uint32_t> tailProbes, uint64_t seed, double sampleRate,
                      std::optional<double> lengthSeconds, const std::string& air, const std::string& hrtf,
                      double receiverRadius, double convergeDb, bool flutterCones, int order,
                      const std::string& trace, const std::string& bands) {
  IrOptions q;
  if (bands != "octave" && bands != "third-octave")
    throw py::value_error("bands: expected 'octave' or 'third-octave', got '" + bands.substr(0, 32) + "'");
  q.thirdOctave = bands == "third-octave";
  auto mode = traceModeFromString(trace);
  if (!mode.isOk()) throw py::value_error("trace: expected 'per-source', 'shared' or 'auto', got '" + trace.substr(0, 32) + "'");
  q.trace = *mode;
  if (receiver != "omni" && receiver != "binaural" && receiver != "ambisonic")
    throw py::value_error("receiver: expected 'omni', 'binaural' or 'ambisonic', got '" + receiver.substr(0, 32) + "'");
  if (receiver != "binaural" && !hrtf.empty()) throw py::value_error("hrtf: an HRTF applies only to receiver='binaural'");
  if (receiver == "ambisonic") {
    if (order < 1 || order > kMaxAmbisonicOrder) throw py::value_error("order: expected 1 .. 3");
    q.ambisonicOrder = order;
  }
  q.receiver = receiver;
  q.binaural = receiver == "binaural";
  q.hrtfPath = hrtf;
  q.quality = quality;
  OmniIrSettings& s = q.settings;
  apply(take(qualityPreset(quality)), s);
  // The same ranges as `earshot ir`'s options.
  if (rays) {
    if (*rays < 1 || *rays > 100000000u) throw py::value_error("rays: expected 1 .. 100000000");
    s.rays = *rays;
  }
  if (bounces) {
    if (*bounces > 100000u) throw py::value_error("bounces: expected 0 .. 100000");
    s.bounces = *bounces;
  }
  if (ismOrder) {
    if (*ismOrder > kMaxImageSourceOrder)
      throw py::value_error("ism_order: expected 0 .. " + std::to_string(kMaxImageSourceOrder));
    s.imageSourceOrder = *ismOrder;
  }
  if (binMs) {
    if (!(*binMs >= 0.01 && *binMs <= 100.0)) throw py::value_error("bin_ms: expected 0.01 .. 100");
    s.binSeconds = *binMs / 1000.0;
  }
  if (tailProbes) {
    if (*tailProbes > 100000000u) throw py::value_error("tail_probes: expected 0 .. 100000000");
    s.tailProbes = *tailProbes;
  }
  if (!(sampleRate >= 8000.0 && sampleRate <= 384000.0))
    throw py::value_error("sample_rate: expected 8000 .. 384000 Hz, got " + std::to_string(sampleRate));
  s.sampleRateHz = sampleRate;
  s.seed = seed;
  if (lengthSeconds) {
    if (!(*lengthSeconds > 0 && *lengthSeconds <= 600)) throw py::value_error("length: expected seconds in (0, 600]");
    s.lengthSeconds = *lengthSeconds;
  }
  s.air = take(parseAirConditions(air));
  if (!(receiverRadius >= 0 && receiverRadius <= 1000)) throw py::value_error("receiver_radius: expected 0 .. 1000 m");
  s.receiverRadiusMeters = receiverRadius;
  if (!(convergeDb >= 0 && convergeDb <= 20)) throw py::value_error("converge: expected 0 .. 20 dB");
  s.convergenceDb = convergeDb;
  if (q.thirdOctave && q.trace != TraceMode::kPerSource)
    throw py::value_error("bands: 'third-octave' traces per source (trace='per-source')");
  if (convergeDb > 0 && q.trace != TraceMode::kPerSource)
    throw py::value_error("converge: works with trace='per-source' only (a shared trace traces every ray)");
  s.flutterCones = flutterCones;
  checkVec("forward", forward);
  checkVec("up", up);
  q.orientation.forward = vec(forward);
  q.orientation.up = vec(up);
  if (q.binaural || q.ambisonicOrder > 0) {
    Status v = validate(q.orientation);
    if (!v.isOk()) raise(v);
  }
  return q;
}

/** One computed IR, still in C++ (no GIL needed to make it). */
struct IrOut {
  Status status = Status::ok();
  AudioBuffer ir;
  std::string report;
  std::vector<std::string> warnings;
};

/** The IRs of `sources` at one listener, traced as q.trace says
 *  (computeIrs: per source, bit-identical to computeIr, or one shared
 *  listener-centred trace), in `sources` order. */
std::vector<IrOut> computeGroup(SceneData& scene, const IrOptions& q, const std::vector<std::array<double, 3>>& sources,
                                const std::array<double, 3>& lis, uint64_t seed, ThreadPool& pool) {
  std::vector<IrOut> outs(sources.size());
  auto fail = [&](const Status& st) {
    for (IrOut& o : outs) o.status = st;
    return outs;
  };
  OmniIrSettings s = q.settings;
  s.seed = seed;
  std::unique_ptr<BinauralReceiver> bin;
  if (q.binaural) {
    auto model = scene.hrtf(q.hrtfPath, s.sampleRateHz);
    if (!model.isOk()) return fail(model.status());
    bin = std::make_unique<BinauralReceiver>();
    bin->model = *model;
    bin->orientation = q.orientation;
  }
  std::unique_ptr<AmbisonicReceiver> amb;
  if (q.ambisonicOrder > 0) {
    amb = std::make_unique<AmbisonicReceiver>();
    amb->order = q.ambisonicOrder;
    amb->frame.worldToFrame = worldToAmbisonicFrame(q.orientation.forward, q.orientation.up);
  }
  const Vec3d listener = vec(lis);
  const bool checkInside = !scene.tracer->empty() && scene.closed;
  const bool listenerOutside = checkInside && enclosureOf(*scene.tracer, true, listener) == Enclosure::kOutside;
  std::vector<IrRequest> requests(sources.size());
  for (size_t k = 0; k < sources.size(); ++k) {
    requests[k].source = vec(sources[k]);
    requests[k].directivity = s.directivity;
    requests[k].includeDirect = s.includeDirect;
    if (listenerOutside) outs[k].warnings.push_back("listener lies outside the closed volume of " + scene.name);
    if (checkInside && enclosureOf(*scene.tracer, true, requests[k].source) == Enclosure::kOutside)
      outs[k].warnings.push_back("source lies outside the closed volume of " + scene.name);
  }
  if (q.thirdOctave) {
    // Three passes per source, each traced from the source (third_octave.h).
    for (size_t k = 0; k < sources.size(); ++k) {
      auto r = computeIrThirdOctave(*scene.tracer, scene.materials, requests[k].source, listener, s, pool, bin.get(),
                                    amb.get());
      if (!r.isOk()) {
        outs[k].status = r.status();
        continue;
      }
      outs[k].report = thirdOctaveReportJson(*r, s, !scene.tracer->empty());
      for (std::string& w : thirdOctaveIrWarnings(*r)) outs[k].warnings.push_back(std::move(w));
      outs[k].ir = std::move(r->ir);
    }
    return outs;
  }
  auto r = computeIrs(*scene.tracer, scene.materials, listener, requests, s, q.trace, pool, bin.get(), amb.get());
  if (!r.isOk()) return fail(r.status());
  for (size_t k = 0; k < sources.size(); ++k) {
    OmniIrResult& result = (*r)[k];
    outs[k].report = irReportJson(result, s, !scene.tracer->empty());
    for (std::string& w : irWarnings(result)) outs[k].warnings.push_back(std::move(w));
    outs[k].ir = std::move(result.ir);
  }
  return outs;
}

IrOut computeOne(SceneData& scene, const IrOptions& q, const std::array<double, 3>& src,
                 const std::array<double, 3>& lis, uint64_t seed, ThreadPool& pool) {
  return std::move(computeGroup(scene, q, {src}, lis, seed, pool).front());
}

/** `traced`: the trace the IR got (kAuto resolved). */
py::dict toPython(IrOut&& o, const IrOptions& q, TraceMode traced) {
  if (!o.status.isOk()) raise(o.status);
  const size_t c = o.ir.channelCount(), n = o.ir.frameCount();
  py::array_t<float> samples({py::ssize_t(c), py::ssize_t(n)});
  auto w = samples.mutable_unchecked<2>();
  for (size_t ch = 0; ch < c; ++ch)
    std::copy(o.ir.channels[ch].begin(), o.ir.channels[ch].end(), w.mutable_data(py::ssize_t(ch), 0));
  py::dict d;
  d["samples"] = samples;
  d["sample_rate"] = o.ir.sampleRateHz;
  d["report"] = o.report;
  d["warnings"] = o.warnings;
  d["quality"] = q.quality;
  d["receiver"] = q.receiver;
  d["trace"] = toString(traced);
  return d;
}

using P3 = std::array<double, 3>;

py::dict irOne(SceneData& scene, const P3& source, const P3& listener, const IrOptions& q, unsigned threads) {
  checkVec("source", source);
  checkVec("listener", listener);
  IrOut out;
  {
    py::gil_scoped_release release;
    ThreadPool pool(threads);
    out = computeOne(scene, q, source, listener, q.settings.seed, pool);
  }
  return toPython(std::move(out), q, effectiveTraceMode(q.trace, 1));
}

/** Per source (q.trace kPerSource): pair i with seed + i, pairs handed out
 *  one at a time to `threads` (each IR on one thread: IRs are bit-identical
 *  whatever the thread count, and whole IRs in parallel scale better than
 *  one IR's stages). Shared (or auto, for listeners with at least
 *  kAutoSharedTraceSources pairs): the pairs with the same listener are one
 *  group, traced together on all threads with seed + the index of the
 *  group's first pair; auto's smaller groups go per source as above. Only
 *  the IRs' samples and reports are kept until all are done. */
py::list irBatch(SceneData& scene, const std::vector<std::pair<P3, P3>>& pairs, const IrOptions& q,
                 unsigned threads) {
  for (size_t i = 0; i < pairs.size(); ++i) {
    checkVec(("pairs[" + std::to_string(i) + "] source").c_str(), pairs[i].first);
    checkVec(("pairs[" + std::to_string(i) + "] listener").c_str(), pairs[i].second);
  }
  // Groups of pairs by listener, in the order of their first pair.
  std::vector<std::vector<size_t>> groups;
  std::vector<size_t> single;  // pairs traced on their own
  if (q.trace == TraceMode::kPerSource) {
    for (size_t i = 0; i < pairs.size(); ++i) single.push_back(i);
  } else {
    std::map<P3, size_t> groupOf;
    for (size_t i = 0; i < pairs.size(); ++i) {
      auto [it, added] = groupOf.try_emplace(pairs[i].second, groups.size());
      if (added) groups.emplace_back();
      groups[it->second].push_back(i);
    }
    std::vector<std::vector<size_t>> shared;
    for (auto& g : groups) {
      if (effectiveTraceMode(q.trace, g.size()) == TraceMode::kShared) shared.push_back(std::move(g));
      else single.insert(single.end(), g.begin(), g.end());
    }
    groups = std::move(shared);
    std::sort(single.begin(), single.end());
  }
  std::vector<IrOut> outs(pairs.size());
  {
    py::gil_scoped_release release;
    ThreadPool pool(threads);
    IrOptions perSource = q;
    perSource.trace = TraceMode::kPerSource;
    if (single.size() <= 1 || pool.threadCount() == 1) {
      for (size_t k : single)
        outs[k] = computeOne(scene, perSource, pairs[k].first, pairs[k].second, q.settings.seed + k, pool);
    } else {
      // IRs side by side share the memory limit: each is checked against
      // the limit / the IRs at once. One refused by its share alone is made
      // again afterwards, one at a time under the whole limit, on every
      // thread or, if that passes the limit (a trace's state grows with
      // its threads), on one (the same bits: an IR does not depend on the
      // thread count).
      const size_t atOnce = std::min<size_t>(pool.threadCount(), single.size());
      const uint64_t share = defaultInputLimits().maxMemoryBytes / atOnce;
      std::vector<uint8_t> again(pairs.size(), 0);
      pool.parallelFor(single.size(), [&](size_t j, unsigned) {
        ThreadPool one(1);
        const size_t k = single[j];
        MemoryLimitShare mine(share);
        outs[k] = computeOne(scene, perSource, pairs[k].first, pairs[k].second, q.settings.seed + k, one);
        again[k] = !outs[k].status.isOk() && mine.refusedWithinTheLimit();
      });
      ThreadPool one(1);
      for (size_t k : single)
        if (again[k]) {
          outs[k] = computeOne(scene, perSource, pairs[k].first, pairs[k].second, q.settings.seed + k, pool);
          if (!outs[k].status.isOk())
            outs[k] = computeOne(scene, perSource, pairs[k].first, pairs[k].second, q.settings.seed + k, one);
          outs[k].warnings.push_back("made alone after the batch: with " + std::to_string(atOnce) +
                                     " IRs at once its share of the memory limit (" + formatBytes(share) +
                                     ") was too small; a higher limit (set_memory_limit) or fewer threads "
                                     "avoids the second run");
        }
    }
    for (const auto& g : groups) {
      std::vector<P3> sources;
      for (size_t k : g) sources.push_back(pairs[k].first);
      IrOptions shared = q;
      shared.trace = TraceMode::kShared;
      std::vector<IrOut> r = computeGroup(scene, shared, sources, pairs[g.front()].second, q.settings.seed + g.front(), pool);
      for (size_t j = 0; j < g.size(); ++j) outs[g[j]] = std::move(r[j]);
    }
  }
  std::vector<bool> traced(pairs.size(), false);  // in a shared trace
  for (const auto& g : groups)
    for (size_t k : g) traced[k] = true;
  py::list results;
  for (size_t k = 0; k < outs.size(); ++k)
    results.append(toPython(std::move(outs[k]), q, traced[k] ? TraceMode::kShared : TraceMode::kPerSource));
  return results;
}

// ---- analysis ----

AudioBuffer bufferFrom(py::array_t<float, py::array::c_style | py::array::forcecast> samples, double rate) {
  if (samples.ndim() != 2) throw py::value_error("samples: expected shape (channels, frames)");
  AudioBuffer b;
  b.sampleRateHz = rate;
  auto r = samples.unchecked<2>();
  b.channels.resize(size_t(samples.shape(0)));
  for (py::ssize_t c = 0; c < samples.shape(0); ++c)
    b.channels[size_t(c)].assign(r.data(c, 0), r.data(c, 0) + samples.shape(1));
  return b;
}

py::dict bandDict(const analysis::BandMetrics& m) {
  py::dict d;
  d["band_hz"] = m.bandCenterHz;
  for (auto metric : analysis::kAllMetrics) {
    d[analysis::metricName(metric)] = m.value(metric);
    if (!m.reason(metric).empty()) d[(std::string(analysis::metricName(metric)) + "_na").c_str()] = m.reason(metric);
  }
  d["onset_s"] = m.onsetS;
  d["decay_end_s"] = m.decayEndS;
  d["noise_floor_found"] = m.noiseFloorFound;
  d["noise_floor_db"] = m.noiseFloorDb;
  d["dynamic_range_db"] = m.dynamicRangeDb;
  return d;
}

analysis::AnalysisOptions analysisOptions(const std::string& noise, double windowStart, double windowEnd,
                                          const std::string& origin, bool excludeDirect) {
  analysis::AnalysisOptions o;
  if (noise == "lundeby") o.noise = analysis::NoiseTreatment::kLundeby;
  else if (noise == "none") o.noise = analysis::NoiseTreatment::kNone;
  else throw py::value_error("noise: expected 'lundeby' or 'none'");
  if (origin == "emission") o.windowOrigin = analysis::WindowOrigin::kEmission;
  else if (origin == "direct") o.windowOrigin = analysis::WindowOrigin::kDirectSound;
  else throw py::value_error("window_origin: expected 'emission' or 'direct'");
  if (!(windowStart >= 0) || !(windowEnd > windowStart))
    throw py::value_error("window: expected 0 <= start < end");
  o.windowStartS = windowStart;
  o.windowEndS = windowEnd;
  o.direct = excludeDirect ? analysis::DirectSound::kExclude : analysis::DirectSound::kInclude;
  return o;
}

py::list analyze(py::array_t<float, py::array::c_style | py::array::forcecast> samples, double rate,
                 const std::string& noise, double windowStart, double windowEnd, const std::string& origin,
                 bool excludeDirect, const std::string& bands) {
  auto opts = analysisOptions(noise, windowStart, windowEnd, origin, excludeDirect);
  if (bands == "third-octave") opts.bands = analysis::AnalysisOptions::Bands::kThirdOctave;
  else if (bands != "octave") throw py::value_error("bands: expected 'octave' or 'third-octave'");
  AudioBuffer b = bufferFrom(samples, rate);
  Result<analysis::IrAnalysis> r = Status::ok();
  {
    py::gil_scoped_release release;
    r = analysis::analyzeAudio(b, opts);
  }
  auto a = take(std::move(r));
  py::list channels;
  for (const auto& ch : a.channels) {
    py::list bands;
    for (const auto& m : ch) bands.append(bandDict(m));
    channels.append(bands);
  }
  return channels;
}

py::dict binaural(py::array_t<float, py::array::c_style | py::array::forcecast> samples, double rate) {
  AudioBuffer b = bufferFrom(samples, rate);
  Result<analysis::BinauralMetrics> r = Status::ok();
  {
    py::gil_scoped_release release;
    r = analysis::analyzeBinaural(b);
  }
  auto m = take(std::move(r));
  py::dict d;
  d["onset_s"] = m.onsetS;
  d["itd_s"] = m.itdS;
  if (!m.itdReason.empty()) d["itd_na"] = m.itdReason;
  d["ild_db"] = m.ildDb;
  d["iacc_e3"] = m.iaccE3;
  d["iacc_l3"] = m.iaccL3;
  py::list iacc;
  for (const auto& band : m.iacc) {
    py::dict x;
    x["band_hz"] = band.bandCenterHz;
    x["early"] = band.early;
    x["late"] = band.late;
    if (!band.earlyReason.empty()) x["early_na"] = band.earlyReason;
    if (!band.lateReason.empty()) x["late_na"] = band.lateReason;
    iacc.append(x);
  }
  d["iacc"] = iacc;
  return d;
}

py::dict compare(py::array_t<float, py::array::c_style | py::array::forcecast> test,
                 py::array_t<float, py::array::c_style | py::array::forcecast> reference, double rate,
                 const std::optional<std::string>& toleranceText, double jnd, const std::vector<std::string>& bands,
                 const std::string& noise) {
  analysis::CompareOptions co;
  if (toleranceText) co.tolerance = take(analysis::parseTolerance(*toleranceText, "tolerance"));
  else {
    if (!(jnd > 0 && std::isfinite(jnd))) throw py::value_error("tolerance: expected a number of JND > 0");
    co.tolerance = analysis::ToleranceSpec(jnd);
  }
  for (const auto& b : bands) co.bands.push_back(take(analysis::parseBandName(b)));
  const auto ao = analysisOptions(noise, 0.0, std::numeric_limits<double>::infinity(), "emission", false);
  AudioBuffer t = bufferFrom(test, rate), r = bufferFrom(reference, rate);
  Result<analysis::AudioComparison> c = Status::ok();
  {
    py::gil_scoped_release release;
    c = analysis::compareAudio(t, r, co, ao);
  }
  auto cmp = take(std::move(c));
  py::list rows;
  for (size_t i = 0; i < cmp.channels.size(); ++i)
    for (const auto& row : cmp.channels[i].rows) {
      py::dict x;
      x["channel"] = cmp.channelIndices[i];
      x["metric"] = analysis::metricName(row.metric);
      x["band"] = analysis::bandLabel(row.band);
      x["band_hz"] = row.band < kNumBands ? kBandCentersHz[size_t(row.band)] : 0.0;
      x["test"] = row.testValue;
      x["reference"] = row.referenceValue;
      x["difference_jnd"] = row.differenceJnd;
      x["limit_jnd"] = row.limitJnd;
      x["verdict"] = row.verdict == analysis::Verdict::kPass   ? "pass"
                     : row.verdict == analysis::Verdict::kFail ? "fail"
                                                               : "skipped";
      x["note"] = row.note;
      rows.append(x);
    }
  py::dict d;
  d["rows"] = rows;
  d["failures"] = cmp.failures;
  d["worst_jnd"] = cmp.worstJnd;
  d["within_tolerance"] = cmp.withinTolerance();
  return d;
}

// ---- offline render ----

py::dict render(const std::string& text, const std::string& baseDirectory, const std::string& displayName,
                std::optional<std::string> quality, std::optional<uint64_t> seed, unsigned threads, double from,
                std::optional<double> to, bool strict, bool allowOutsidePaths) {
  SceneParseOptions po;
  po.strict = strict;
  po.allowOutsidePaths = allowOutsidePaths;
  std::vector<std::string> warnings;
  auto scene = take(parseSceneText(text, baseDirectory, displayName, po, &warnings));
  if (!(from >= 0) || !std::isfinite(from)) throw py::value_error("start: expected seconds >= 0");
  if (to && !(std::isfinite(*to) && *to > from)) throw py::value_error("end: expected seconds after start");
  RenderOptions ro;
  ro.quality = quality;
  ro.seed = seed;
  ro.threads = threads;
  ro.fromSeconds = from;
  ro.toSeconds = to;
  Result<RenderResult> r = Status::ok();
  {
    py::gil_scoped_release release;
    r = renderScene(scene, ro);
  }
  auto res = take(std::move(r));
  const size_t c = res.audio.channelCount(), n = res.audio.frameCount();
  py::array_t<float> samples({py::ssize_t(c), py::ssize_t(n)});
  auto w = samples.mutable_unchecked<2>();
  for (size_t ch = 0; ch < c; ++ch)
    std::copy(res.audio.channels[ch].begin(), res.audio.channels[ch].end(), w.mutable_data(py::ssize_t(ch), 0));
  py::dict d;
  d["samples"] = samples;
  d["sample_rate"] = res.audio.sampleRateHz;
  d["audio_seconds"] = res.audioSeconds;
  d["wall_seconds"] = res.wallSeconds;
  d["simulation_seconds"] = res.simulationSeconds;
  d["simulations"] = res.simulations;
  d["peak"] = res.peak;
  d["clipped"] = res.clipped;
  d["log"] = res.log;
  d["warnings"] = warnings;
  return d;
}

}  // namespace

PYBIND11_MODULE(_earshot, m) {
  m.doc() = "earshot engine bindings (use the earshot package, not this module)";

  py::class_<SceneData, std::shared_ptr<SceneData>>(m, "_Scene")
      .def_static("load", &loadScene, py::arg("geometry"), py::arg("materials_path"), py::arg("materials_text"),
                  py::arg("material_map_path"), py::arg("material_map"), py::arg("allow_outside_paths"),
                  py::arg("max_memory_bytes"))
      .def_static("from_arrays", &sceneFromArrays, py::arg("vertices"), py::arg("triangles"),
                  py::arg("material_ids"), py::arg("names"), py::arg("materials_path"), py::arg("materials_text"))
      .def_property_readonly("triangle_count", [](const SceneData& s) { return s.mesh.triangleCount(); })
      .def_property_readonly("warnings", [](const SceneData& s) { return s.warnings; })
      .def_property_readonly("closed", [](const SceneData& s) { return s.closed; })
      .def_property_readonly("material_names",
                             [](const SceneData& s) {
                               std::vector<std::string> names;
                               for (const auto& mat : s.materials.all()) names.push_back(mat.name);
                               return names;
                             })
      .def("enclosure",
           [](const SceneData& s, const P3& p) {
             checkVec("point", p);
             switch (enclosureOf(*s.tracer, s.closed, vec(p))) {
               case Enclosure::kInside: return "inside";
               case Enclosure::kOutside: return "outside";
               default: return "open";
             }
           })
      .def("arrays",
           [](const SceneData& s) {
             const size_t n = s.mesh.positions.size(), m = s.mesh.triangleCount();
             py::array_t<double> v({py::ssize_t(n), py::ssize_t(3)});
             py::array_t<int64_t> t({py::ssize_t(m), py::ssize_t(3)});
             auto vw = v.mutable_unchecked<2>();
             auto tw = t.mutable_unchecked<2>();
             for (size_t i = 0; i < n; ++i) {
               vw(i, 0) = s.mesh.positions[i].x;
               vw(i, 1) = s.mesh.positions[i].y;
               vw(i, 2) = s.mesh.positions[i].z;
             }
             for (size_t i = 0; i < m; ++i)
               for (int k = 0; k < 3; ++k) tw(i, k) = s.mesh.triangles[i][size_t(k)];
             return py::make_tuple(v, t);
           })
      .def_property_readonly("bounds",
                             [](const SceneData& s) {
                               std::array<double, 3> lo{0, 0, 0}, hi{0, 0, 0};
                               bool first = true;
                               for (const auto& p : s.mesh.positions) {
                                 const double c[3] = {p.x, p.y, p.z};
                                 for (int k = 0; k < 3; ++k) {
                                   lo[k] = first ? c[k] : std::min(lo[k], c[k]);
                                   hi[k] = first ? c[k] : std::max(hi[k], c[k]);
                                 }
                                 first = false;
                               }
                               return std::make_pair(lo, hi);
                             })
      .def("ir",
           [](SceneData& s, const P3& source, const P3& listener, const std::string& receiver, const P3& forward,
              const P3& up, const std::string& quality, std::optional<uint32_t> rays, std::optional<uint32_t> bounces,
              std::optional<uint32_t> ismOrder, std::optional<double> binMs, std::optional<uint32_t> tailProbes,
              uint64_t seed, double sampleRate, std::optional<double> length, const std::string& air,
              const std::string& hrtf, double receiverRadius, double converge, bool flutterCones, unsigned threads,
              int order, const std::string& trace, const std::string& bands) {
             const IrOptions q = makeRequest(receiver, forward, up, quality, rays, bounces, ismOrder, binMs, tailProbes,
                                             seed, sampleRate, length, air, hrtf, receiverRadius, converge,
                                             flutterCones, order, trace, bands);
             return irOne(s, source, listener, q, threads);
           },
           py::arg("source"), py::arg("listener"), py::arg("receiver"), py::arg("forward"), py::arg("up"), py::arg("quality"), py::arg("rays"),
           py::arg("bounces"), py::arg("ismOrder"), py::arg("binMs"), py::arg("tailProbes"), py::arg("seed"),
           py::arg("sampleRate"), py::arg("length"), py::arg("air"), py::arg("hrtf"), py::arg("receiverRadius"),
           py::arg("converge"), py::arg("flutterCones"), py::arg("threads"), py::arg("order"), py::arg("trace"),
           py::arg("bands"))
      .def("ir_batch",
           [](SceneData& s, const std::vector<std::pair<P3, P3>>& pairs, const std::string& receiver,
              const P3& forward, const P3& up, const std::string& quality, std::optional<uint32_t> rays,
              std::optional<uint32_t> bounces, std::optional<uint32_t> ismOrder, std::optional<double> binMs,
              std::optional<uint32_t> tailProbes, uint64_t seed, double sampleRate, std::optional<double> length,
              const std::string& air, const std::string& hrtf, double receiverRadius, double converge,
              bool flutterCones, unsigned threads, int order, const std::string& trace, const std::string& bands) {
             const IrOptions q = makeRequest(receiver, forward, up, quality, rays, bounces, ismOrder, binMs, tailProbes,
                                             seed, sampleRate, length, air, hrtf, receiverRadius, converge,
                                             flutterCones, order, trace, bands);
             return irBatch(s, pairs, q, threads);
           },
           py::arg("pairs"), py::arg("receiver"), py::arg("forward"), py::arg("up"), py::arg("quality"), py::arg("rays"),
           py::arg("bounces"), py::arg("ismOrder"), py::arg("binMs"), py::arg("tailProbes"), py::arg("seed"),
           py::arg("sampleRate"), py::arg("length"), py::arg("air"), py::arg("hrtf"), py::arg("receiverRadius"),
           py::arg("converge"), py::arg("flutterCones"), py::arg("threads"), py::arg("order"), py::arg("trace"),
           py::arg("bands"));

  m.def("_analyze", &analyze);
  m.def("_binaural", &binaural);
  m.def("_compare", &compare);
  m.def("_render", &render);
  m.def("_jnd_size", [](const std::string& metric, double reference) {
    return analysis::jndSize(take(analysis::parseMetric(metric)), reference);
  });
  m.def("_difference_in_jnd", [](const std::string& metric, double test, double reference) {
    return analysis::differenceInJnd(take(analysis::parseMetric(metric)), test, reference);
  });
  m.def("_set_memory_limit", [](uint64_t bytes) { setDefaultMaxMemoryBytes(bytes); });
  m.def("_memory_limit", []() { return defaultInputLimits().maxMemoryBytes; });
  m.attr("__version__") = EARSHOT_VERSION;
  m.attr("bands_hz") = std::vector<double>(kBandCentersHz.begin(), kBandCentersHz.end());
  m.attr("max_coordinate_m") = kMaxCoordinateMeters;
}
