#pragma once
/** @file One source/listener pair to an impulse response, omnidirectional or
 *  binaural: the direct path, early specular reflections (image sources),
 *  stochastic late reflections (with the image-source paths excluded), tail
 *  completion, synthesis. The one implementation behind `earshot ir`,
 *  `earshot tradeoff`, rendering and the runtime. */
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "earshot/core/audio_buffer.h"
#include "earshot/core/status.h"
#include "earshot/ir/ambisonic_synthesis.h"
#include "earshot/ir/binaural_synthesis.h"
#include "earshot/ir/ir_synthesis.h"
#include "earshot/propagation/direct_path.h"
#include "earshot/propagation/image_sources.h"
#include "earshot/propagation/reflection_tracer.h"
#include "earshot/propagation/tail_completion.h"

namespace earshot {

class RayTracer;
class ThreadPool;

struct OmniIrSettings {
  /** The source's directivity (direct_path.h): the direct sound, each image
   *  source and each traced ray weighted by it; omni by default. */
  Directivity directivity;
  double sampleRateHz = 48000.0;
  double lengthSeconds = 0.0;      ///< 0: automatic (from the decay)
  /** > 0: the reflections end here at the latest: the trace's histogram
   *  (ReflectionSettings::maxTimeSeconds), the automatic length's cap
   *  (TailCompletionSettings::maxAutoSeconds, else 30 s) and an explicit
   *  lengthSeconds are cut to it. For a caller that cuts its IRs there
   *  anyway (the runtime: EngineSettings::maxIrSeconds), what it would cut
   *  is neither traced, kept nor synthesised. 0: no cap. [0, 600] */
  double maxLengthSeconds = 0.0;
  uint32_t rays = 16384;
  uint32_t bounces = 12;
  uint32_t imageSourceOrder = 3;   ///< 0: no image sources (all reflections stochastic)
  uint64_t seed = 1;
  double speedOfSound = 343.0;
  /** Also the bands': air.bandShiftOctaves != 0 shifts every band of the
   *  IR (air absorption, synthesis, a binaural model's band energies; the materials table must be shifted
   *  to match, MaterialTable::atBandShift): one pass of computeIrThirdOctave. */
  AirConditions air;
  double binSeconds = 0.001;
  double receiverRadiusMeters = 0.0;  ///< 0: automatic
  bool completeTail = true;
  /** Rays that carry on past the bounce limit to measure the tail's decay
   *  (ReflectionSettings::tailProbes); 0: extrapolate at one rate. */
  uint32_t tailProbes = kEveryRay;
  bool russianRoulette = true;     ///< end rays 60 dB down (unbiased; ReflectionSettings)
  bool flutterCones = true;        ///< sample flutter axes densely (ReflectionSettings::flutterCones)
  /** A shared trace's roulette on shadow rays (ReflectionSettings::sharedShadowRoulette); 0: every shadow ray. */
  double sharedShadowRoulette = ReflectionSettings{}.sharedShadowRoulette;
  /** > 0: stop tracing when the late histogram's estimated error is below
   *  this (dB; ReflectionSettings::convergenceDb). 0: every ray. */
  double convergenceDb = 0.0;
  bool includeDirect = true;       ///< false: reflections only (the runtime renders the direct path per block)
  /** Ambisonic IRs: IrSynthesisSettings::partialFrames (the channels after
   *  W made up to this frame only; W whole). 0: whole. */
  size_t ambisonicPartialFrames = 0;
};

/** A binaural receiver: the HRTF model and the listener's orientation. */
struct BinauralReceiver {
  std::shared_ptr<const BinauralModel> model;
  ListenerOrientation orientation;
};

/** An ambisonic receiver (ambisonic_synthesis.h): AmbiX channels of
 *  `order` in `frame` (worldAmbisonicFrame() for the runtime's world-frame
 *  bus, or a listener's frame: worldToAmbisonicFrame(forward, up)). */
struct AmbisonicReceiver {
  int order = 1;
  AmbisonicFrame frame;
};

/** Named quality presets: rays, bounces, image-source order, histogram bin, tail probes. */
struct QualityPreset {
  std::string name;
  uint32_t rays, bounces, imageSourceOrder;
  double binSeconds;
  uint32_t tailProbes;
};
/** "draft", "balanced" (the defaults), "high", "reference". */
Result<QualityPreset> qualityPreset(const std::string& name);
const std::vector<QualityPreset>& qualityPresets();
void apply(const QualityPreset& preset, OmniIrSettings& settings);

struct OmniIrTimings {
  double directMs = 0, imageSourcesMs = 0, traceMs = 0, tailMs = 0, synthesisMs = 0, totalMs = 0;
};

struct OmniIrResult {
  AudioBuffer ir;                      ///< 1 channel (omni), 2 (binaural: left, right) or (order+1)^2 (ambisonic, ACN)
  DirectPath direct;
  std::vector<SpecularPath> early;     ///< image-source paths rendered
  EnergyHistogram late;                ///< completed stochastic histogram
  ReflectionStats traceStats;
  TailInfo tail;
  uint64_t imageSourceCandidates = 0;
  bool imageSourcesExhaustive = true;
  OmniIrTimings timings;
  std::vector<std::string> skipped;    ///< work not needed for this scene, with why
  bool lateTraced = false;             ///< `late` was traced (else the IR has no late part)
};

/** The IR of one source/listener pair: binaural when `binaural` is given (its
 *  model's rate must equal settings.sampleRateHz), ambisonic when
 *  `ambisonic` is (not both), else omnidirectional. */
Result<OmniIrResult> computeIr(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& source,
                               const Vec3d& listener, const OmniIrSettings& settings, ThreadPool& pool,
                               const BinauralReceiver* binaural, const AmbisonicReceiver* ambisonic = nullptr);

/** The IR computeIr or computeIrs synthesised for `result` (its direct
 *  sound, early paths and late histogram), the same bits, made again from
 *  them: e.g. whole after a synthesis with ambisonicPartialFrames.
 *  `settings`, `source`, `listener` and the receiver are the ones it was
 *  computed with (with any IrRequest's overrides applied). */
Result<AudioBuffer> synthesizeIrOf(const OmniIrResult& result, const OmniIrSettings& settings, const Vec3d& source,
                                   const Vec3d& listener, const BinauralReceiver* binaural,
                                   const AmbisonicReceiver* ambisonic = nullptr);

/** How the late reflections of several sources at one listener are traced
 *  (issue 16). */
enum class TraceMode {
  kPerSource,  ///< a trace from each source (traceReflections)
  kShared,     ///< one trace from the listener for all of them (traceReflectionsShared)
  /** kShared for kAutoSharedTraceSources sources or more, else kPerSource. */
  kAuto,
};
/** kAuto's threshold. Measured (`earshot bench trace --shared-sources N`,
 *  2 threads, balanced): the shared trace of 2 sources costs 0.55x their
 *  two traces in the shoebox but 1.2x in the furnished room with the
 *  listener by the furniture, where the listener's small detection sphere
 *  (0.41 m) gives each trace from a source only 4096 tail probes while the
 *  sources' larger spheres give the shared trace every ray as one; from 3
 *  sources it is cheaper there too (0.93x at 3, 0.5x at 8, 0.3x at 32). */
constexpr size_t kAutoSharedTraceSources = 3;
/** The mode a computeIrs of `sources` sources uses (kAuto resolved). */
TraceMode effectiveTraceMode(TraceMode mode, size_t sources);
/** The reflection trace's settings of an IR with these settings (without
 *  its image sources' exclusions): e.g. for traceMemoryBytes. */
ReflectionSettings reflectionSettingsOf(const OmniIrSettings& settings);
/** "per-source", "shared" or "auto". */
Result<TraceMode> traceModeFromString(const std::string& name);
const char* toString(TraceMode mode);

/** One source of computeIrs: what differs from source to source. */
struct IrRequest {
  Vec3d source;
  Directivity directivity;     ///< instead of the settings' directivity
  bool includeDirect = true;   ///< instead of the settings' includeDirect
  std::string name;            ///< in error messages; empty: "source <index in the requests>"
  size_t ambisonicPartialFrames = 0;  ///< instead of the settings' ambisonicPartialFrames
};

/** What computeIrs keeps from one shared simulation for the next from the
 *  same place, each part reused only for the same scene, listener position
 *  and settings (the same results; anything else replaces it): the
 *  listener's paths (SharedTracePaths: no ray traced), the tail's rates
 *  made from them (tailRates: ~400 k exponentials), and the image sources'
 *  candidate sequences from the listener (imageSourceCandidates: 16384
 *  rays of up to 3 reflections in the furnished room). Not thread-safe:
 *  one computeIrs at a time. */
struct ListenerCache {
  SharedTracePaths paths;
  std::optional<TailRates> rates;  ///< made from the paths of `ratesGeneration`
  uint64_t ratesGeneration = 0;
  struct Candidates {
    bool valid = false;
    uint64_t tracer = 0;  ///< RayTracer::id()
    Vec3d listener{};
    uint32_t maxOrder = 0, rays = 0;
    uint64_t seed = 0;
    std::vector<PlaneSequence> sequences;
  } candidates;
};

/** computeIrs's shared traces take at most as many sources at once as keep
 *  their per-thread sums and results within this; the sources beyond go
 *  through further traces (balanced, 4 s of 1 ms bins, 2 threads: ~80 at a
 *  time). A source's result does not depend on which others share its
 *  trace. */
constexpr size_t kSharedTraceBudgetBytes = size_t(256) << 20;

/** The IRs of several sources at one listener, in `requests` order (kAuto:
 *  effectiveTraceMode). kPerSource: computeIr for each in turn (each traced on all of pool's
 *  threads): bit-identical to it. kShared: the sources' direct sounds and
 *  image sources one per thread, one listener-centred trace for all of them
 *  (traceReflectionsShared) on every thread, then tail completion and
 *  synthesis one per thread; each result's traceStats.traceMs is the
 *  shared trace's time over the number of sources. Any error names the
 *  first source that had one. Results do not depend on the thread count.
 *  `cache` (kShared, optional): what the last shared simulation kept from
 *  the listener, reused from the same place (ListenerCache). */
Result<std::vector<OmniIrResult>> computeIrs(const RayTracer& tracer, const MaterialTable& materials,
                                             const Vec3d& listener, const std::vector<IrRequest>& requests,
                                             const OmniIrSettings& settings, TraceMode mode, ThreadPool& pool,
                                             const BinauralReceiver* binaural = nullptr,
                                             const AmbisonicReceiver* ambisonic = nullptr,
                                             ListenerCache* cache = nullptr);

/** The discrete arrivals a result's IR was synthesised from: the direct sound
 *  (if audible and `includeDirect`) and the image-source paths. */
std::vector<Arrival> arrivalsOf(const OmniIrResult& result, bool includeDirect);

/** The decay of the traced energies per band: the completed histogram plus
 *  the direct sound and image sources, at the histogram's bins, through
 *  Schroeder integration with no noise treatment. This is what the IR's
 *  octave bands decay at, without the synthesis's noise (an IR's T20 and T30
 *  agree within 5 %: TracedDecay.* tests). NaN where the energies do not
 *  span the metric's range. (TailInfo::t60Seconds is something else: the
 *  decay rate of the rays still in flight, which continues the tail past
 *  where they were traced.) */
/** One band's traced energy per histogram bin: the completed histogram plus
 *  the direct sound and image sources, each in the bin of its delay (long
 *  enough for the latest arrival). tracedDecay's input. */
std::vector<double> tracedEnergy(const OmniIrResult& result, int band);

struct TracedDecay {
  BandArrayD edtSeconds{}, t20Seconds{}, t30Seconds{};
};
TracedDecay tracedDecay(const OmniIrResult& result);

/** computeIr without a binaural receiver. */
Result<OmniIrResult> computeOmniIr(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& source,
                                   const Vec3d& listener, const OmniIrSettings& settings, ThreadPool& pool);

}  // namespace earshot
