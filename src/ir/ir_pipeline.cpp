#include "earshot/core/math.h"
#include "earshot/ir/ir_pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <string>

#include "earshot/analysis/room_acoustics.h"
#include "earshot/core/thread_pool.h"
#include "earshot/io/input_file.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot {

namespace {
double msSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}
}  // namespace

const std::vector<QualityPreset>& qualityPresets() {
  static const std::vector<QualityPreset> presets = {
      {"draft", 2048, 8, 2, 0.002, kEveryRay},
      {"balanced", 16384, 12, 3, 0.001, kEveryRay},
      {"high", 65536, 24, 3, 0.001, kEveryRay},
      {"reference", 262144, 64, 3, 0.0005, kEveryRay},
  };
  return presets;
}

Result<QualityPreset> qualityPreset(const std::string& name) {
  for (const auto& p : qualityPresets())
    if (p.name == name) return p;
  return invalidArgument("quality " + quotedName(name) + " is not one of draft, balanced, high, reference");
}

void apply(const QualityPreset& p, OmniIrSettings& s) {
  s.rays = p.rays;
  s.bounces = p.bounces;
  s.imageSourceOrder = p.imageSourceOrder;
  s.binSeconds = p.binSeconds;
  s.tailProbes = p.tailProbes;
}

std::vector<Arrival> arrivalsOf(const OmniIrResult& r, bool includeDirect) {
  std::vector<Arrival> arrivals;
  if (r.direct.audible && includeDirect) arrivals.push_back(toArrival(r.direct));
  for (const SpecularPath& p : r.early) {
    Arrival a;
    a.delaySeconds = p.delaySeconds;
    a.gain = p.spreadingGain;
    a.bandGain = p.bandGain;
    a.direction = p.directionFromListener;
    arrivals.push_back(a);
  }
  return arrivals;
}

std::vector<double> tracedEnergy(const OmniIrResult& r, int band) {
  const EnergyHistogram& h = r.late;
  const double bin = h.binSeconds();
  const std::vector<Arrival> arrivals = arrivalsOf(r, true);
  size_t bins = h.binCount();
  for (const Arrival& a : arrivals) bins = std::max(bins, size_t(a.delaySeconds / bin) + 1);
  std::vector<double> e(bins, 0.0);
  for (size_t i = 0; i < h.binCount(); ++i) e[i] = h.energy(i, band);
  for (const Arrival& a : arrivals) {
    const double g = a.gain * a.bandGain[size_t(band)];
    e[size_t(a.delaySeconds / bin)] += g * g;
  }
  return e;
}

TracedDecay tracedDecay(const OmniIrResult& r) {
  TracedDecay out;
  for (int b = 0; b < kNumBands; ++b) {
    const std::vector<double> e = tracedEnergy(r, b);
    std::vector<float> amplitude(e.size());
    for (size_t i = 0; i < e.size(); ++i) amplitude[i] = float(std::sqrt(e[i]));
    const analysis::BandMetrics m = analysis::analyzeBandSignal(amplitude.data(), amplitude.size(),
                                                                1.0 / r.late.binSeconds(), -1, 0,
                                                                analysis::NoiseTreatment::kNone);
    out.edtSeconds[size_t(b)] = m.edtS;
    out.t20Seconds[size_t(b)] = m.t20S;
    out.t30Seconds[size_t(b)] = m.t30S;
  }
  return out;
}

Result<OmniIrResult> computeOmniIr(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& source,
                                   const Vec3d& listener, const OmniIrSettings& s, ThreadPool& pool) {
  return computeIr(tracer, materials, source, listener, s, pool, nullptr);
}

namespace {
// The explicit length, within the cap (0: automatic).
double lengthOf(const OmniIrSettings& s) {
  return s.maxLengthSeconds > 0 && s.lengthSeconds > 0 ? std::min(s.lengthSeconds, s.maxLengthSeconds)
                                                       : s.lengthSeconds;
}
}  // namespace

ReflectionSettings reflectionSettingsOf(const OmniIrSettings& s) {
  ReflectionSettings rs;
  rs.directivity = s.directivity;
  rs.rays = s.rays;
  rs.bounces = s.bounces;
  rs.seed = s.seed;
  rs.speedOfSound = s.speedOfSound;
  rs.air = s.air;
  rs.binSeconds = s.binSeconds;
  rs.receiverRadiusMeters = s.receiverRadiusMeters;
  rs.tailProbes = s.completeTail ? s.tailProbes : 0;
  rs.russianRoulette = s.russianRoulette;
  rs.flutterCones = s.flutterCones;
  rs.sharedShadowRoulette = s.sharedShadowRoulette;
  rs.convergenceDb = s.convergenceDb;
  if (lengthOf(s) > 0)
    rs.maxTimeSeconds = lengthOf(s);
  else if (s.maxLengthSeconds > 0)
    rs.maxTimeSeconds = std::min(rs.maxTimeSeconds, s.maxLengthSeconds);
  return rs;
}

namespace {

// An IR in the making: computeIr's stages, which computeIrs interleaves
// with one shared trace.
struct IrJob {
  OmniIrResult out;
  ImageSourceResult ism;
  IrSynthesisSettings synth;
  bool hasImageSources = false;
  std::chrono::steady_clock::time_point start;
};

ImageSourceSettings imageSourceSettingsOf(const OmniIrSettings& s) {
  ImageSourceSettings is;
  is.maxOrder = s.imageSourceOrder;
  is.speedOfSound = s.speedOfSound;
  is.air = s.air;
  is.seed = s.seed;
  is.candidateRays = std::min<uint32_t>(s.rays, 16384);
  return is;
}

IrSynthesisSettings synthesisSettingsOf(const OmniIrSettings& s, const Vec3d& source, const Vec3d& listener) {
  IrSynthesisSettings synth;
  synth.sampleRateHz = s.sampleRateHz;
  synth.lengthSeconds = lengthOf(s);
  synth.seed = s.seed;
  synth.noiseKey = noiseKeyOf(source, listener);
  synth.bandShiftOctaves = s.air.bandShiftOctaves;
  synth.partialFrames = s.ambisonicPartialFrames;
  return synth;
}

// The IR of a result: what finishIr and synthesizeIrOf make.
Result<AudioBuffer> synthesize(const OmniIrResult& out, const IrSynthesisSettings& synth, bool includeDirect,
                               const BinauralReceiver* binaural, const AmbisonicReceiver* ambisonic) {
  const EnergyHistogram* late = out.lateTraced ? &out.late : nullptr;
  const std::vector<Arrival> arrivals = arrivalsOf(out, includeDirect);
  return binaural    ? synthesizeBinauralIr(arrivals, late, synth, *binaural->model, binaural->orientation)
         : ambisonic ? synthesizeAmbisonicIr(arrivals, late, synth, ambisonic->order, ambisonic->frame)
                     : synthesizeOmniIr(arrivals, late, synth);
}

// Checks, the direct sound and the image sources.
Status prepareIr(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& source, const Vec3d& listener,
                 const OmniIrSettings& s, const BinauralReceiver* binaural, const AmbisonicReceiver* ambisonic,
                 IrJob& job, const std::vector<PlaneSequence>* candidates = nullptr, ThreadPool* pool = nullptr) {
  job.start = std::chrono::steady_clock::now();
  if (!isFinite(source) || !isFinite(listener)) return invalidArgument("source or listener position is not finite");
  if (!withinCoordinateRange(source) || !withinCoordinateRange(listener))
    return outOfRange("source or listener position is farther than 1e6 m from the origin on some axis");
  if (!(s.maxLengthSeconds >= 0 && s.maxLengthSeconds <= 600))
    return invalidArgument("IR length cap " + std::to_string(s.maxLengthSeconds) + " s is outside [0, 600]");
  OmniIrResult& out = job.out;
  IrSynthesisSettings& synth = job.synth;
  synth = synthesisSettingsOf(s, source, listener);
  EARSHOT_RETURN_IF_ERROR(validate(synth));
  if (binaural && ambisonic) return invalidArgument("a receiver is binaural or ambisonic, not both");
  if (ambisonic && (ambisonic->order < 1 || ambisonic->order > kMaxAmbisonicOrder))
    return invalidArgument("ambisonic order " + std::to_string(ambisonic->order) + " is outside [1, " +
                           std::to_string(kMaxAmbisonicOrder) + "]");
  if (binaural) {
    if (!binaural->model) return invalidArgument("binaural receiver without an HRTF model");
    EARSHOT_RETURN_IF_ERROR(validate(binaural->orientation));
    if (binaural->model->sampleRateHz() != s.sampleRateHz)
      return invalidArgument("sample rate " + std::to_string(s.sampleRateHz) + " Hz differs from the HRTF set's " +
                             std::to_string(binaural->model->sampleRateHz()) + " Hz");
  }

  // Direct sound.
  auto t = std::chrono::steady_clock::now();
  DirectPathSettings ds;
  ds.speedOfSound = s.speedOfSound;
  ds.air = s.air;
  ds.directivity = s.directivity;
  EARSHOT_RETURN_IF_ERROR(validate(ds.air));
  EARSHOT_RETURN_IF_ERROR(validate(s.directivity));
  out.direct = computeDirectPath(&tracer, materials, source, listener, ds);
  out.timings.directMs = msSince(t);
  if (tracer.empty()) out.skipped.push_back("reflections: no geometry");
  if (!tracer.empty() && !out.direct.occlusionTested)
    out.skipped.push_back("direct-path occlusion test: no surface's plane separates source and listener");
  else if (out.direct.surfacesCrossed == 0 && !tracer.empty())
    out.skipped.push_back("transmission: nothing between source and listener");

  // Early specular reflections.
  if (!tracer.empty() && s.imageSourceOrder > 0) {
    t = std::chrono::steady_clock::now();
    ImageSourceSettings is = imageSourceSettingsOf(s);
    is.candidates = candidates;
    // On the pool's threads when one is given (the same paths whatever the threads).
    auto r = findImageSources(tracer, materials, source, listener, is, pool);
    if (!r.isOk()) return r.status();
    job.ism = std::move(r.value());
    job.hasImageSources = true;
    out.timings.imageSourcesMs = msSince(t);
    out.early = job.ism.paths;
    if (!s.directivity.isOmni()) {
      // Each path leaves the source along its first segment: the straight
      // line image source -> listener, unfolded through its planes from the
      // last to the first (v -> v - 2 (v.n) n each).
      const BandArrayD ms = s.directivity.meanSquares();
      const auto& planes = tracer.planes().planes;
      for (SpecularPath& p : out.early) {
        Vec3d v = normalize(listener - p.imageSource);
        for (int k = int(p.order) - 1; k >= 0; --k) {
          const uint32_t id = p.planes[size_t(k)];
          if (id >= planes.size()) continue;
          const Vec3d& n = planes[id].normal;
          v = v - n * (2.0 * dot(v, n));
        }
        const BandArrayD d = s.directivity.energyFactors(v, ms);
        for (int b = 0; b < kNumBands; ++b) p.bandGain[size_t(b)] *= std::sqrt(d[size_t(b)]);
      }
    }
    out.imageSourceCandidates = job.ism.candidates;
    out.imageSourcesExhaustive = job.ism.exhaustive;
  }
  return Status::ok();
}

bool tracesReflections(const RayTracer& tracer, const OmniIrSettings& s) { return !tracer.empty() && s.bounces > 0; }

ReflectionSettings reflectionSettingsOf(const OmniIrSettings& s, const IrJob& job) {
  ReflectionSettings rs = reflectionSettingsOf(s);
  rs.excludedSpecular = job.hasImageSources ? &job.ism.found : nullptr;
  rs.excludedMaxOrder = job.hasImageSources ? s.imageSourceOrder : 0;
  return rs;
}

// The tail completion's settings (calibrationStartSeconds: after the image sources, per IR).
TailCompletionSettings tailSettingsOf(const OmniIrSettings& s) {
  TailCompletionSettings ts;
  ts.lengthSeconds = lengthOf(s);
  if (s.maxLengthSeconds > 0) ts.maxAutoSeconds = std::min(ts.maxAutoSeconds, s.maxLengthSeconds);
  ts.speedOfSound = s.speedOfSound;
  ts.air = s.air;
  return ts;
}

// Tail completion and synthesis; `traced` null when nothing was traced
// (`shared`: by a shared trace, whose detector is the source). `rates`: the
// tail's rates made once for a shared trace's sources (or null), their time
// `ratesMs` charged to this IR.
Status finishIr(IrJob& job, ReflectionResult* traced, bool shared, const OmniIrSettings& s,
                const BinauralReceiver* binaural, const AmbisonicReceiver* ambisonic,
                const TailRates* rates = nullptr, double ratesMs = 0.0) {
  OmniIrResult& out = job.out;
  if (traced) {
    ReflectionResult& r = *traced;
    out.traceStats = r.stats;
    if (r.stats.raysTraced < s.rays)
      out.skipped.push_back("rays: " + std::to_string(s.rays - r.stats.raysTraced) + " of " + std::to_string(s.rays) +
                            " not traced, the histogram had converged to " + std::to_string(r.stats.estimatedErrorDb) +
                            " dB");
    if (r.stats.shadowRaysSkipped > 0 && r.stats.shadowRays == 0)
      out.skipped.push_back(std::string("occlusion tests of diffuse reflections: the room is convex around the ") +
                            (shared ? "source" : "listener"));
    out.timings.traceMs = r.stats.traceMs;
    auto t = std::chrono::steady_clock::now();
    if (s.completeTail) {
      TailCompletionSettings ts = tailSettingsOf(s);
      for (const SpecularPath& p : out.early) ts.calibrationStartSeconds = std::max(ts.calibrationStartSeconds, p.delaySeconds);
      auto c = completeTail(r.histogram, r.tail, ts, &out.tail, rates);
      if (!c.isOk()) return c.status();
      out.late = std::move(c.value());
      if (!out.tail.extended) out.skipped.push_back("tail completion: no ray reached the bounce limit");
    } else {
      out.late = std::move(r.histogram);
    }
    out.timings.tailMs = msSince(t) + ratesMs;
    out.lateTraced = true;
  }

  auto t = std::chrono::steady_clock::now();
  auto ir = synthesize(out, job.synth, s.includeDirect, binaural, ambisonic);
  if (!ir.isOk()) return ir.status();
  out.ir = std::move(ir.value());
  out.timings.synthesisMs = msSince(t);
  out.timings.totalMs = msSince(job.start);
  return Status::ok();
}

}  // namespace

Result<OmniIrResult> computeIr(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& source,
                               const Vec3d& listener, const OmniIrSettings& s, ThreadPool& pool,
                               const BinauralReceiver* binaural, const AmbisonicReceiver* ambisonic) {
  IrJob job;
  EARSHOT_RETURN_IF_ERROR(prepareIr(tracer, materials, source, listener, s, binaural, ambisonic, job, nullptr, &pool));
  std::optional<Result<ReflectionResult>> traced;
  if (tracesReflections(tracer, s)) {
    traced = traceReflections(tracer, materials, source, listener, reflectionSettingsOf(s, job), pool);
    if (!traced->isOk()) return traced->status();
  }
  EARSHOT_RETURN_IF_ERROR(finishIr(job, traced ? &traced->value() : nullptr, false, s, binaural, ambisonic));
  return std::move(job.out);
}

Result<AudioBuffer> synthesizeIrOf(const OmniIrResult& result, const OmniIrSettings& settings, const Vec3d& source,
                                   const Vec3d& listener, const BinauralReceiver* binaural,
                                   const AmbisonicReceiver* ambisonic) {
  if (binaural && ambisonic) return invalidArgument("a receiver is binaural or ambisonic, not both");
  if (binaural && !binaural->model) return invalidArgument("binaural receiver without an HRTF model");
  const IrSynthesisSettings synth = synthesisSettingsOf(settings, source, listener);
  EARSHOT_RETURN_IF_ERROR(validate(synth));
  return synthesize(result, synth, settings.includeDirect, binaural, ambisonic);
}

Result<TraceMode> traceModeFromString(const std::string& name) {
  if (name == "per-source") return TraceMode::kPerSource;
  if (name == "shared") return TraceMode::kShared;
  if (name == "auto") return TraceMode::kAuto;
  return invalidArgument("trace mode " + quotedName(name) + " is not one of per-source, shared, auto");
}

const char* toString(TraceMode mode) {
  return mode == TraceMode::kShared ? "shared" : mode == TraceMode::kAuto ? "auto" : "per-source";
}

TraceMode effectiveTraceMode(TraceMode mode, size_t sources) {
  if (mode != TraceMode::kAuto) return mode;
  return sources >= kAutoSharedTraceSources ? TraceMode::kShared : TraceMode::kPerSource;
}

Result<std::vector<OmniIrResult>> computeIrs(const RayTracer& tracer, const MaterialTable& materials,
                                             const Vec3d& listener, const std::vector<IrRequest>& requests,
                                             const OmniIrSettings& s, TraceMode mode, ThreadPool& pool,
                                             const BinauralReceiver* binaural, const AmbisonicReceiver* ambisonic,
                                             ListenerCache* cache) {
  if (requests.size() > kMaxSharedTraceSources)
    return invalidArgument(std::to_string(requests.size()) + " sources, over " + std::to_string(kMaxSharedTraceSources));
  auto settingsOf = [&](const IrRequest& r) {
    OmniIrSettings rs = s;
    rs.directivity = r.directivity;
    rs.includeDirect = r.includeDirect;
    rs.ambisonicPartialFrames = r.ambisonicPartialFrames;
    return rs;
  };
  auto named = [&](size_t i, const Status& st) {
    const std::string& name = requests[i].name;
    return Status(st.code(), (name.empty() ? "source " + std::to_string(i) : name) + ": " + st.message());
  };
  std::vector<OmniIrResult> out;
  out.reserve(requests.size());
  if (effectiveTraceMode(mode, requests.size()) == TraceMode::kPerSource) {
    for (size_t i = 0; i < requests.size(); ++i) {
      auto r = computeIr(tracer, materials, requests[i].source, listener, settingsOf(requests[i]), pool, binaural,
                         ambisonic);
      if (!r.isOk()) return named(i, r.status());
      out.push_back(std::move(r.value()));
    }
    return out;
  }
  // Shared: every source's checks, direct sound and image sources (one per
  // thread), one trace from the listener on every thread, then each
  // source's tail and synthesis (one per thread).
  if (requests.empty()) return out;
  std::vector<IrJob> jobs(requests.size());
  std::vector<Status> status(requests.size());
  // Where the image sources' candidates come from rays (many planes), the
  // listener's rays find them once for every source (imageSourceCandidates).
  std::vector<PlaneSequence> ownCandidates;
  const std::vector<PlaneSequence>* candidates = &ownCandidates;
  const ImageSourceSettings is = imageSourceSettingsOf(s);
  const bool listenerCandidates = !tracer.empty() && s.imageSourceOrder > 0 && isFinite(listener) &&
                                  tracer.planes().planes.size() > is.maxPlanesExhaustive;
  double candidatesMs = 0;
  if (listenerCandidates) {
    const auto t = std::chrono::steady_clock::now();
    ListenerCache::Candidates* kept = cache ? &cache->candidates : nullptr;
    const bool same = kept && kept->valid && kept->tracer == tracer.id() && kept->listener.x == listener.x &&
                      kept->listener.y == listener.y && kept->listener.z == listener.z &&
                      kept->maxOrder == is.maxOrder && kept->rays == is.candidateRays && kept->seed == is.seed;
    if (same) {
      candidates = &kept->sequences;
    } else {
      ownCandidates = imageSourceCandidates(tracer, listener, is, true, &pool);
      if (kept) {
        *kept = ListenerCache::Candidates{true, tracer.id(), listener, is.maxOrder, is.candidateRays, is.seed,
                                          std::move(ownCandidates)};
        candidates = &kept->sequences;
      }
    }
    candidatesMs = msSince(t) / double(requests.size());  // each source is charged its part
  }
  pool.parallelFor(requests.size(), [&](size_t i, unsigned) {
    status[i] = prepareIr(tracer, materials, requests[i].source, listener, settingsOf(requests[i]), binaural,
                          ambisonic, jobs[i], listenerCandidates ? candidates : nullptr);
    jobs[i].out.timings.imageSourcesMs += candidatesMs;
  });
  for (size_t i = 0; i < requests.size(); ++i)
    if (!status[i].isOk()) return named(i, status[i]);
  // Sources go through the trace in groups whose sums and results fit
  // kSharedTraceBudgetBytes (or the memory limit, if lower): per source,
  // each thread keeps a histogram and the probes' detections, and its
  // result a histogram and the tail data until its IR is made
  // (traceMemoryBytes, affine in the sources). A single source over the
  // limit is refused by the trace.
  const ReflectionSettings sized = reflectionSettingsOf(s);
  const double one = traceMemoryBytes(sized, 1, pool.threadCount());
  const double perSource = traceMemoryBytes(sized, 2, pool.threadCount()) - one;
  const double budget = std::min(double(kSharedTraceBudgetBytes), double(defaultInputLimits().maxMemoryBytes));
  const size_t group = size_t(std::clamp(std::floor((budget - (one - perSource)) / perSource), 1.0,
                                         double(kMaxSharedTraceSources)));
  for (size_t g0 = 0; g0 < requests.size(); g0 += group) {
    const size_t g1 = std::min(requests.size(), g0 + group);
    std::vector<ReflectionResult> traced;
    if (tracesReflections(tracer, s)) {
      std::vector<SharedTraceSource> sources(g1 - g0);
      for (size_t i = g0; i < g1; ++i) {
        const ReflectionSettings rs = reflectionSettingsOf(settingsOf(requests[i]), jobs[i]);
        SharedTraceSource& src = sources[i - g0];
        src.position = requests[i].source;
        src.directivity = requests[i].directivity;
        src.excludedSpecular = rs.excludedSpecular;
        src.excludedMaxOrder = rs.excludedMaxOrder;
        src.receiverRadiusMeters = rs.receiverRadiusMeters;
      }
      auto r = traceReflectionsShared(tracer, materials, listener, sources, reflectionSettingsOf(s, jobs[g0]), pool,
                                      cache ? &cache->paths : nullptr);
      if (!r.isOk()) return r.status();
      traced = std::move(r.value());
      // The trace's time is shared: each source is charged its part.
      for (ReflectionResult& t : traced) t.stats.traceMs /= double(traced.size());
    }
    // The tail's decay rates and cut rays are the listener's rays': made
    // once for the group (the same bits as each source making them).
    // A trace from kept paths has their tail data: the rates made from
    // them before serve again.
    std::optional<TailRates> ownRates;
    const TailRates* rates = nullptr;
    double ratesMs = 0;
    if (!traced.empty() && s.completeTail) {
      const auto t = std::chrono::steady_clock::now();
      const TailCompletionSettings ts = tailSettingsOf(s);
      const double binSeconds = traced.front().histogram.binSeconds();
      const size_t binCount = traced.front().histogram.binCount();
      if (cache && traced.front().stats.pathsReused && cache->rates &&
          cache->ratesGeneration == cache->paths.generation() && cache->rates->settings.sameRatesAs(ts) &&
          cache->rates->binSeconds == binSeconds && cache->rates->tracedBins == binCount) {
        rates = &*cache->rates;
      } else {
        auto made = tailRates(traced.front().tail, binSeconds, binCount, ts);
        if (!made.isOk()) return made.status();
        ownRates = std::move(made.value());
        rates = &*ownRates;
        if (cache) {
          cache->rates = *ownRates;
          cache->ratesGeneration = cache->paths.generation();
        }
      }
      ratesMs = msSince(t) / double(traced.size());
    }
    pool.parallelFor(g1 - g0, [&](size_t k, unsigned) {
      const size_t i = g0 + k;
      status[i] = finishIr(jobs[i], traced.empty() ? nullptr : &traced[k], true, settingsOf(requests[i]), binaural,
                           ambisonic, rates, ratesMs);
    });
  }
  for (size_t i = 0; i < requests.size(); ++i) {
    if (!status[i].isOk()) return named(i, status[i]);
    out.push_back(std::move(jobs[i].out));
  }
  return out;
}

}  // namespace earshot
