#pragma once
/** @file The runtime: sources and a listener in a scene, simulated on worker
 *  threads, heard through the audio thread. The one update path behind the
 *  C/C++ API (earshot.h) and `earshot render`.
 *
 *  Per source, the output (binaural: left, right) is
 *    - the reflections: the source's binaural IR without the direct sound
 *      (image sources, late field; ir_pipeline.h), simulated by simulate()
 *      and convolved in one ConvolutionMixer for all sources; new IRs reach
 *      the audio thread lock-free and are crossfaded;
 *    - the direct sound, rendered every audio block from the latest poses by
 *      a DirectVoice (delay line with Doppler, distance, occlusion from the
 *      last simulation, HRTF of the current head direction);
 *  or, for a source marked DirectMode::kInImpulseResponse (a static source),
 *  the complete IR including the direct sound, convolved exactly: the output
 *  is then the dry signal convolved with the IR `earshot ir` computes for the
 *  same poses and settings, delayed by latencyFrames() (an IR that ends
 *  within maxIrSeconds; a longer one is simulated only up to that cut:
 *  the same room's energies, another realisation of the noise).
 *
 *  Threads (docs/design.md): the game thread (sources, listener, scene: the
 *  set, add and remove calls), one simulation thread at a time (simulate()),
 *  and the audio thread (process()). A pose, and a source's controls
 *  (gains, distance curve, directivity), cross to the audio thread whole
 *  (latest_values.h: never some of one call and the rest of another); IRs
 *  through the mixer's lock-free mailbox. process() never allocates, locks,
 *  logs or throws. */
#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <future>
#include <memory>
#include <mutex>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/core/vec3.h"
#include "earshot/ir/ambisonic_decoder.h"
#include "earshot/ir/binaural_synthesis.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/ir/spherical_harmonics.h"
#include "earshot/materials/material.h"
#include "earshot/runtime/glide.h"
#include "earshot/runtime/latest_values.h"

namespace earshot {
class RayTracer;
class ThreadPool;
class ConvolutionMixer;
}  // namespace earshot

namespace earshot::runtime {

class DirectVoice;

enum class OutputFormat {
  kBinaural,   ///< left, right
  kAmbisonic,  ///< (order+1)^2 AmbiX channels in the listener's frame
};

struct EngineSettings {
  double sampleRateHz = 48000.0;  ///< must equal the HRTF model's rate
  /** Convolver latency and smallest partition (frames, even, [8, 65536]); the
   *  output lags the input by exactly this. Host blocks may be any size. */
  size_t blockFrames = 256;
  size_t maxSources = 32;         ///< [1, 4096] source slots, allocated up front
  /** IRs are cut here with a 10 ms fade, and simulated no further (the
   *  simulation's OmniIrSettings::maxLengthSeconds: the trace's histogram,
   *  the tail and the synthesis end at the cut). (0, 60] */
  double maxIrSeconds = 3.0;
  /** Each slot keeps its latest IR for sourceIr() (with a shared tail, what
   *  the IR is made from: its histogram and paths). false: nothing is kept
   *  and sourceIr() gives no IR (sourceIrInfo() still counts); a slot then
   *  holds less (sourceSlotBytes(): e.g. `earshot render`, which never
   *  asks, renders twice the sources within the memory limit). */
  bool keepSourceIrs = true;
  size_t fadeFrames = 0;          ///< IR crossfade (frames); 0: one block
  /** Largest convolution partition (frames; 0: the convolver's automatic
   *  choice). Every source's partitions of one size fall due on the same
   *  block, so a smaller largest partition trades average cost for a lower
   *  worst block (see `earshot bench runtime --max-partition`). */
  size_t maxPartitionFrames = 0;
  OmniIrSettings simulation;      ///< rays, bounces, ISM order, air, seed... (rate taken from sampleRateHz)
  /** Threads that simulate, the simulate() caller's included (0: the
   *  cores less one, at least one: the audio thread keeps a core). */
  unsigned threads = 0;
  /** Added to the worker threads' nice value (Linux): they run below the
   *  audio thread and the game. The simulate() caller's thread is the
   *  caller's to set (the C API's built-in thread gets the same). */
  int workerNice = 5;
  double maxDistanceMeters = 343.0;  ///< direct-path delay line capacity
  /** How the reflections reach the ears (issue 15).
   *  0: a binaural IR per source with the listener's orientation baked in
   *  (each arrival through its exact HRTF; a head turn needs a new
   *  simulation to be heard in the reflections).
   *  1-3: an ambisonic IR per source in the world frame (AmbiX of this
   *  order, ambisonic_synthesis.h), every source convolved into one bus that
   *  is rotated by the head and decoded to two ears once per block
   *  (ambisonic_decoder.h): a head turn costs no simulation, and the audio
   *  thread's cost per source is (order+1)^2 channels of multiply-adds
   *  instead of 2, with one decoder for all. The direct sound stays per
   *  source through the HRTF of its current direction either way; a source
   *  whose IR holds the direct sound (DirectMode::kInImpulseResponse) has it
   *  in the bus, decoded with the reflections. Adds latencyFrames(): one
   *  block for the decoder's convolution plus its 2 ms bulk delay.
   *  The default, 1, is docs/ambisonics.md's choice: the orders' errors
   *  against the exact binaural reflections lie mostly within the floor of
   *  two binaural simulations of different seeds, and the audio thread's
   *  cost grows with the channels. */
  int ambisonicOrder = 1;
  /** What process() writes: two ears (binaural), or with ambisonic
   *  reflections the (ambisonicOrder+1)^2 AmbiX channels (ACN, SN3D) in the
   *  listener's frame (x forward, y left, z up): the bus rotated to the head
   *  and not decoded, each per-block direct sound encoded at its current
   *  direction (W is the omni pressure). */
  OutputFormat output = OutputFormat::kBinaural;
  /** With ambisonic reflections: each source's own IR is convolved up to
   *  this time (seconds after the emission, then a 10 ms crossfade); after
   *  it one late tail shared by every source is convolved once, for the sum
   *  of the sources' inputs each weighted by its own late level (the
   *  energy of its tail's W after this time). The shared tail is the
   *  latest simulated source's that has a tail, normalised; in a room whose late field is diffuse every
   *  source's tail has the same decay and differs in level only
   *  (docs/ambisonics.md measures what this costs). The audio thread's
   *  multiply-adds per source fall from the whole IR's length to this, and
   *  the other sources of a simulation are synthesised up to it only (W
   *  whole; sourceIr() makes the rest when asked).
   *  0, or at or after maxIrSeconds (IRs that short): every source's
   *  whole IR. Negative or NaN: refused. */
  double sharedTailSeconds = 0.15;
  /** With ambisonic reflections: the sources' and the shared tail's IR
   *  spectra stored as 16-bit floats (ConvolverSettings::compactSpectra):
   *  the bus streams half the bytes from memory each block, which is what
   *  limits it (32 sources: their spectra are ~3 MB, beyond the cache), for
   *  an error ~-74 dB of the reflections' level. false: floats, the exact
   *  convolution. Binaural reflections (ambisonicOrder 0), the exact
   *  reference, are always floats. */
  bool compactAmbisonicSpectra = true;
  /** How a simulation of several sources traces their reflections (issue
   *  16): kShared, one trace from the listener whose paths every source
   *  detects (traceReflectionsShared: a sphere test per segment and a
   *  shadow ray per reflection per source instead of a trace each);
   *  kPerSource, a trace from each source (one source per worker); kAuto
   *  (the default), shared for a simulation of kAutoSharedTraceSources (3)
   *  sources or more, where it is measured cheaper. A shared trace's paths
   *  and image-source candidates are kept (ListenerCache; the paths up to
   *  kSharedTracePathsBudgetBytes): while the listener stays in place,
   *  later shared simulations detect their sources in them without tracing
   *  (the same IRs). The two modes give the
   *  same energies (the regression suite runs with both). */
  TraceMode traceMode = TraceMode::kAuto;
  /** A simulation step (simulate()) goes through its sources in groups of
   *  at most this many, [1, 4096] (fewer where the memory limit says so),
   *  and posts each group's IRs as soon as the group is done; a source
   *  added while a step runs joins the step's next group. Smaller groups
   *  give fresher reflections and a new source (a one-shot) its
   *  reflections sooner, larger ones a little more throughput (each group
   *  of a shared trace detects its sources in the kept paths in a pass of
   *  its own, ~7 ms in the furnished room). With 32 sources moving in the
   *  furnished room (`earshot bench runtime --group-sources
   *  --one-shots-hz`, docs/performance.md), groups of 8 (the default)
   *  against all sources in one group: the median IR age 0.20 s against
   *  0.37 s, a one-shot's wait for its first reflections 0.08 s against
   *  0.39 s, for 7.5 % fewer updates (3.7 against 4.0 a second per
   *  source). The IRs are the same bits whatever the grouping. */
  size_t simulationGroupSources = 8;
  /** The source and listener positions the direct sound follows, each
   *  source's gains (its own, its direct sound's and its reflections') and
   *  the way it faces are followed with their changes spread over the
   *  interval at which the game makes them (glide.h: a game's 60 Hz updates
   *  are heard as steady Doppler and smooth fades and turns, not staircases
   *  of delay and level; one to two update intervals late). The listener's
   *  orientation is not (head tracking). false: each value is
   *  reached within the block that first sees it, for a caller that sets
   *  exact values at every block's end (`earshot render`). */
  bool glideGameUpdates = true;
};

enum class DirectMode {
  kPerBlock,           ///< direct sound rendered every block (moving sources)
  kInImpulseResponse,  ///< direct sound inside the convolved IR (static sources; exact)
};

/** How the direct sound falls off with distance d (pressure gain). The
 *  reflections stay physical whatever the curve. */
enum class DistanceModel {
  kPhysical,     ///< 1 / max(d, 0.1 m): the engine's physics (default)
  kInverse,      ///< min / (min + rolloff (D - min)), D = d clamped to [min, max]
  kLinear,       ///< 1 - rolloff (D - min) / (max - min), at least 0
  kExponential,  ///< (D / min)^-rolloff
  kTable,        ///< the user's points (distance, gain), linear between them, flat beyond the ends
};
constexpr int kMaxDistanceTablePoints = 16;
struct DistanceCurve {
  DistanceModel model = DistanceModel::kPhysical;
  double minDistance = 1.0;    ///< metres, (0, 1e6]; gain 1 up to here
  double maxDistance = 100.0;  ///< metres, >= minDistance; the curve stays flat beyond
  double rolloff = 1.0;        ///< [0, 100]
  /** kTable: up to kMaxDistanceTablePoints points, distances ascending in
   *  [0, 1e6] m, gains in [0, 10] (pressure). */
  std::vector<std::pair<double, double>> table;
};
/** The curve's pressure gain at distance d (metres, >= 0). */
double distanceGain(const DistanceCurve& curve, double d);

/** How the direct sound is occluded by geometry between source and listener. */
enum class OcclusionMode {
  kOff,         ///< never occluded (applies from the next block)
  kRay,         ///< one ray, source centre to listener (default)
  kVolumetric,  ///< the energy average over 16 rays to points on a sphere of radiusMeters around the source
};

struct SourceSettings {
  double gainDb = 0.0;  ///< [-120, 60]: the whole source (direct and reflections)
  DirectMode direct = DirectMode::kPerBlock;
  double directGainDb = 0.0;       ///< [-120, 60]: the per-block direct sound only
  double reflectionsGainDb = 0.0;  ///< [-120, 60]: the convolved IR (reflections, reverberation)
  DistanceCurve distance;          ///< the per-block direct sound's fall-off
  OcclusionMode occlusion = OcclusionMode::kRay;
  double radiusMeters = 0.5;       ///< kVolumetric's sphere, (0, 100]
  bool transmission = true;        ///< false: an occluded path is silent instead of filtered by the surfaces
  int priority = 0;                ///< higher first when simulate(count) cannot take every source
  /** The source's directivity pattern (direct_path.h Directivity: alpha 0
   *  omni .. 0.5 cardioid .. 1 figure-8, sharpness >= 1), about its forward
   *  vector (setSourceOrientation). The per-block direct sound follows it
   *  every block, the reflections at the next simulation. */
  double directivityAlpha = 0.0;
  double directivitySharpness = 1.0;
  /** A per-band table instead of directivityAlpha (e.g. omni at 125 Hz,
   *  cardioid at 4 kHz); the per-block direct sound applies it through its
   *  band shelves, as it does occlusion. */
  bool directivityPerBand = false;
  BandArrayD directivityBandAlpha{};
};
/** Error (naming the field) unless every value is in range. */
Status validate(const SourceSettings& settings);

struct SimulationStats {
  uint32_t sourcesSimulated = 0;
  double traceMs = 0, synthesisMs = 0, prepareMs = 0, totalMs = 0;
  bool pathsReused = false;  ///< a shared trace that reused the listener's kept paths (no ray traced)
  /** Groups the sources went through, each group's IRs in the making held
   *  at once and posted when it was done: ceil(sources /
   *  simulationGroupSources), more where the memory limit parted them (the
   *  same IRs). */
  uint32_t groups = 0;
};

/** What the audio path contained (Engine::containment()). */
struct ContainmentStats {
  /** Source chunks (of at most 256 frames) muted because an input sample was
   *  NaN, infinite or beyond kMaxInputSample. */
  uint64_t mutedSourceChunks = 0;
  /** Output chunks zeroed, with every source's convolution and direct-sound
   *  state cleared, because the output was not finite (an overflow). */
  uint64_t clearedOutputChunks = 0;
};

/** An input sample beyond this magnitude (+120 dB over full scale) is taken
 *  for corrupt and its chunk muted like a NaN. */
constexpr float kMaxInputSample = 1e6f;

/** A source's latest IR as its last simulation posted it (binaural: left,
 *  right; cut at maxIrSeconds with a 10 ms fade), shared, never modified. */
struct SourceIr {
  std::shared_ptr<const AudioBuffer> ir;  ///< null: not simulated since the source was added
  bool includesDirect = false;            ///< DirectMode::kInImpulseResponse: the IR holds the direct sound
  uint64_t simulations = 0;               ///< IRs posted for this source so far
  /** When the poses this IR was computed from were read (its age is now
   *  minus this). */
  std::chrono::steady_clock::time_point posed{};
};

/** A source's direct path as its last simulation found it: how much of
 *  each band gets through the geometry between it and the listener
 *  (pressure factor, air absorption not included: 1 clear, 0 blocked), by
 *  the source's occlusion mode (kRay: the one ray; kVolumetric: the energy
 *  average over rays across its radius; kOff: as kRay, not applied to its
 *  sound). What the direct sound is filtered with, for a game's own use
 *  (an AI's hearing, a muffled voice chat). */
struct SourceOcclusion {
  BandArrayD transmission = filledBands(1.0);  ///< per band, 125 Hz .. 8 kHz
  bool audible = true;    ///< false: no band gets through (or transmission off and a surface in the way)
  bool simulated = false; ///< false: not simulated since the source was added (then clear: all 1)
};

/** An HRTF model that may still be loading (e.g. std::async of
 *  loadBinauralModel): the engine waits for it only when a source is added or
 *  an IR is computed, never on the audio thread. */
using BinauralModelFuture = std::shared_future<Result<std::shared_ptr<const BinauralModel>>>;

class Engine {
 public:
  /** The shared state only: every source slot's state (its direct voice and
   *  convolution history, ~0.4 MB at the defaults, ~2 MB for 3 s binaural
   *  IRs) is allocated by addSource() the first time the slot is used, and
   *  kept for the slot's next source.
   *  Thread: any but audio. */
  static Result<std::unique_ptr<Engine>> create(const EngineSettings& settings,
                                                std::shared_ptr<const BinauralModel> model);
  /** As above with the model still loading: create() returns at once;
   *  addSource() and model() wait for the load and return its error if it
   *  failed. */
  static Result<std::unique_ptr<Engine>> create(const EngineSettings& settings, BinauralModelFuture model);
  ~Engine();
  Engine(const Engine&) = delete;
  Engine& operator=(const Engine&) = delete;

  const EngineSettings& settings() const { return mSettings; }
  /** The HRTF model, waiting for it if it is still loading (game or
   *  simulation thread, never the audio thread). */
  Result<std::shared_ptr<const BinauralModel>> model() const;
  /** Counts of NaN/Inf containment on the audio path since creation. Any thread. */
  ContainmentStats containment() const;
  size_t latencyFrames() const;
  /** The decoder of the ambisonic bus (ambisonicOrder > 0), once the HRTF
   *  model has loaded and a source was added; null before, or in binaural mode. */
  std::shared_ptr<const AmbisonicDecoder> ambisonicDecoder() const;

  // ---- game thread ----
  /** Replaces the scene (an immutable snapshot; null: free field). The next
   *  simulate() uses it; the previous one is released when no longer used. */
  void setScene(std::shared_ptr<const RayTracer> tracer, std::shared_ptr<const MaterialTable> materials);
  /** A source slot: its direct sound (DirectMode::kPerBlock) plays from the
   *  next process() call, its reflections once simulated. Error when all
   *  maxSources slots are in use, the settings are out of range, the HRTF
   *  model failed to load, or memory for the slot's state ran out. The first
   *  use of a slot allocates its state (and waits for a loading model); it
   *  is refused (kOutOfRange) when the slots in use would hold more than
   *  the memory limit (defaultInputLimits().maxMemoryBytes) with their IRs:
   *  sourceSlotBytes() each. The slot: a free one whose last source's
   *  reverberation has rung out or never played (removeSource), else one
   *  never used (within the memory limit), else the one that played
   *  longest ago. The source is at the origin, facing (0, 0, -1), until
   *  setSourcePosition() and setSourceOrientation(); the audio thread may
   *  play its first block there in between, so a source that plays at once
   *  (a one-shot) is better added where it is, with the overload below. */
  Result<uint32_t> addSource(const SourceSettings& settings);
  /** addSource() at `position` (finite, within 1e6 m of the origin) facing
   *  `forward` (finite, non-zero): its first block plays from there, its
   *  first simulation traces from there, and until then its late level is
   *  the nearest simulated source's (as after setSourcePosition). Nothing
   *  is added when either is refused (the same errors as
   *  setSourcePosition() and setSourceOrientation()). */
  Result<uint32_t> addSource(const SourceSettings& settings, const Vec3d& position,
                             const Vec3d& forward = {0, 0, -1});
  /** What one source slot may hold, from above: its direct voice, its
   *  convolution state, the three IRs the convolver may hold for it at
   *  once (the one playing, the one it fades from, one waiting) and what
   *  it keeps for sourceIr() (keepSourceIrs): its IR, or with a shared tail
   *  the histogram the IR is made from (up to the cut, maxIrSeconds). Not
   *  counted: a shared-tail source's few early paths, and the shared state
   *  (the decoder, the shared tail, the one whole IR sourceIr() made last;
   *  a simulation leaves room beside the slots for it). */
  size_t sourceSlotBytes() const;
  /** The same for an engine of these settings, before one is made (e.g.
   *  to refuse a scene's sources before loading it). Error: settings the
   *  convolver refuses. */
  static Result<size_t> sourceSlotBytes(const EngineSettings& settings);
  /** Frees the source's slot: it plays no more from the next process()
   *  call, and what it already played still arrives: its direct sound in
   *  flight (DirectVoice::ringOutFrames: its delay, up to maxDistanceMeters
   *  / c) and its reverberation, which rings out through its IR over up to
   *  maxIrSeconds. A source released before its first IR landed, having
   *  played, is still owed that IR: the next simulate(count) makes it
   *  (where the source was) and what it played is heard through it. A
   *  NULL input in process() is silence the same way. Its slot goes to a
   *  new source only once that has rung out, unless no other slot can be
   *  had (addSource): a new source in a ringing slot cuts the direct sound
   *  in flight and fades the reverberation out (within a block of the
   *  convolution's longest level), then starts the slot's convolution
   *  anew (if its own first IR lands before that, the rest of the old
   *  sound goes through it). */
  Status removeSource(uint32_t source);
  /** The direct sound follows from the next process() call, gliding as
   *  EngineSettings::glideGameUpdates says; the reflections at the source's next
   *  simulation. */
  Status setSourcePosition(uint32_t source, const Vec3d& position);
  Status setSourceGainDb(uint32_t source, double gainDb);
  /** Every control but the direct mode (fixed at addSource), all at once:
   *  the audio thread and the simulation never take some of one call's
   *  and the rest of another's (nor of setSourceGainDb's). Gains glide
   *  as positions do (EngineSettings::glideGameUpdates), the distance
   *  curve ramps over the next block; the occlusion mode kOff
   *  applies from the next block, the others (and transmission) at the
   *  source's next simulation. */
  Status setSourceControls(uint32_t source, const SourceSettings& settings);
  /** The source's forward vector (world frame; finite, non-zero): the axis
   *  of its directivity. Default (0, 0, -1). The direct sound follows it
   *  gliding as positions do; the reflections at the next simulation. */
  Status setSourceOrientation(uint32_t source, const Vec3d& forward);
  Result<SourceSettings> sourceControls(uint32_t source) const;
  /** The direct path's occlusion of the source's last simulation, whole
   *  (never some bands of one simulation and the rest of another's).
   *  Game or simulation thread; never the audio thread (takes a lock). */
  Result<SourceOcclusion> sourceOcclusion(uint32_t source) const;
  Status setListener(const Vec3d& position, const ListenerOrientation& orientation);

  // ---- one simulation thread at a time (never the audio thread) ----
  /** Simulates `count` active sources (count 0 or >= active: all), from
   *  the poses set so far: traces, synthesises and posts their IRs, and
   *  updates their direct paths' occlusion. The order: higher priority
   *  first; then sources never simulated; then sources waiting for twice a
   *  round (2 ceil(active / count) steps since their last simulation: a
   *  source that stands still while others move is still updated, e.g.
   *  after a door opened or it turned); then those whose geometry changed
   *  most since their IR (the distance the source moved plus the distance
   *  the listener moved); equal ones in round-robin order from after the
   *  last simulated. Sources released before their first IR landed count
   *  as active sources never simulated (removeSource). */
  Status simulate(uint32_t count = 0);
  /** Simulates exactly these sources (in this order). */
  Status simulate(const std::vector<uint32_t>& sources);
  SimulationStats lastSimulation() const;
  /** The source's latest IR (a shared copy of what is being convolved;
   *  with a shared tail, the source's whole IR, whose tail the shared one
   *  stands for). A source whose tail another's stood for in its
   *  simulation was synthesised in part: its whole IR is made when asked
   *  (the same bits; milliseconds). The engine keeps the last one made
   *  (one, not one a source: the same source asked again, before another
   *  source's IR is made or its next simulation, costs nothing).
   *  Game or simulation thread; never the audio thread (takes a lock). */
  SourceIr sourceIr(uint32_t source) const;
  /** sourceIr() without the IR (`ir` null): its count and when it was
   *  posed, never synthesising. Game or simulation thread. */
  SourceIr sourceIrInfo(uint32_t source) const;

  // ---- audio thread ----
  /** Renders `frames` frames: inputs[s] is source slot s's dry mono input
   *  (maxSources pointers; nullptr or an inactive slot: silence); left and
   *  right are overwritten. An input may be one of the outputs (the same
   *  start: processing in place); no other overlap. No allocation, lock,
   *  log or exception. */
  void process(const float* const* inputs, float* left, float* right, size_t frames);
  /** As above into outputChannels() buffers (binaural: left, right; ambisonic
   *  output: the AmbiX channels in ACN order), each overwritten. */
  void process(const float* const* inputs, float* const* outputs, size_t frames);
  /** 2, or (ambisonicOrder+1)^2 for OutputFormat::kAmbisonic. Any thread. */
  size_t outputChannels() const { return mOutputChannels; }

  struct Slot;  // one source's state (engine.cpp)

 private:
  Engine() = default;
  bool validSource(uint32_t s) const;
  // takeNewcomers: sources added while it runs join its next group.
  Status simulateLocked(const std::vector<uint32_t>& sources, bool takeNewcomers);
  // Sources simulated together (their IRs in the making held at once)
  // within the memory limit; at least 1.
  size_t simulationGroupSize() const;
  Status createDecoder(const BinauralModel& model);  // under mAddMutex
  Status allocateSlot(uint32_t slot);                // under mAddMutex: a slot's first source's state
  Result<uint32_t> addSourceAt(const SourceSettings& settings, const Vec3d& position, const Vec3d& forward,
                               bool placed);        // addSource(); placed: the late level from the nearest
  void estimateLateLevel(Slot& slot, const Vec3d& position);  // until simulated: the nearest simulated source's
  size_t ringOutFrames() const;  // frames after which a removed source's slot has nothing left to play
  // Audio thread: the bus (mInputs convolved) rotated to the head and decoded into ears[0..1].
  // With OutputFormat::kAmbisonic, `ears` are the output's channels and the bus is not decoded.
  void processAmbisonicBus(const ListenerOrientation& head, float* const* ears, size_t m, bool tailUsed);

  EngineSettings mSettings;
  BinauralModelFuture mModel;
  mutable std::mutex mAddMutex;  // serialises addSource() (slot state allocation, the decoder)
  std::unique_ptr<ThreadPool> mPool;
  std::vector<std::unique_ptr<ThreadPool>> mWorkerPools;  // one single-thread pool per worker of mPool
  std::unique_ptr<ConvolutionMixer> mMixer;
  // Ambisonic reflections (ambisonicOrder > 0): the bus's decoder, made at the
  // first addSource (it needs the model), published to the audio thread.
  std::shared_ptr<const AmbisonicDecoder> mDecoder;
  std::unique_ptr<ConvolutionMixer> mDecoderMixer;
  std::atomic<ConvolutionMixer*> mDecoderMixerLive{nullptr};
  size_t mLatency = 0;
  size_t mOutputChannels = 2;
  std::unique_ptr<ShRotation> mRotation;
  // The shared late tail (sharedTailSeconds > 0, ambisonic reflections).
  std::unique_ptr<ConvolutionMixer> mTailMixer;
  std::vector<float> mTailInput, mTailBus;  // audio thread: chunk, channels x chunk
  std::vector<float> mRamp;  // audio thread: (k + 1) / m of the chunk's m frames, the gains' ramp
  std::vector<float> mBus, mRotated;  // audio thread: channels x chunk
  std::vector<float> mLastRotation;   // audio thread: the bus's rotation at the end of the last chunk
  bool mHaveRotation = false;         // audio thread
  std::vector<std::unique_ptr<Slot>> mSlots;
  LatestValues<std::array<double, 9>> mListener;  // position, forward, up: set and read whole
  std::array<double, 9> mHeardListener{};  // audio thread: the pose it took in this process() call
  PoseGlide mListenerGlide;          // audio thread: the listener position the direct sound follows

  std::mutex mSceneMutex;  // game and simulation threads only
  std::shared_ptr<const RayTracer> mTracer;
  std::shared_ptr<const MaterialTable> mMaterials;
  std::shared_ptr<const RayTracer> mEmptyTracer;
  std::mutex mSimulationMutex;  // serialises simulate()
  std::unique_ptr<ListenerCache> mListenerCache;  // under mSimulationMutex: what the last shared simulation kept
  // Slot::lastIr, mMadeIr; a slot's generation bump and what a simulation
  // writes into its source (IR post, late level, occlusion) after checking
  // it. Game and simulation threads only; nothing is freed under it.
  mutable std::mutex mIrMutex;
  // The whole IR sourceIr() made last for a source synthesised in part, and
  // what it was made from (that source's latest): one for the engine, not
  // one a slot.
  mutable std::shared_ptr<const AudioBuffer> mMadeIr;
  mutable std::weak_ptr<const void> mMadeIrFrom;
  uint32_t mNextRoundRobin = 0;
  uint64_t mSimulations = 0;  // under mSimulationMutex: simulation steps so far
  SimulationStats mStats;
  std::atomic<uint64_t> mMutedSourceChunks{0}, mClearedOutputChunks{0};  // written by the audio thread
  std::atomic<uint64_t> mFramesProcessed{0};  // written by the audio thread: frames process() has rendered

  std::vector<const float*> mInputs;  // audio thread scratch
};

}  // namespace earshot::runtime
