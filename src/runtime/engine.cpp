// The runtime engine: see engine.h.
#include "earshot/runtime/engine.h"

#include <algorithm>
#include <chrono>
#include <thread>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>
#include <utility>

#include "earshot/core/denormals.h"
#include "earshot/core/math.h"
#include "earshot/core/thread_pool.h"
#include "earshot/dsp/convolution_mixer.h"
#include "earshot/dsp/prepared_ir.h"
#include "earshot/io/input_file.h"
#include "earshot/runtime/direct_voice.h"
#include "earshot/runtime/glide.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot::runtime {

namespace {
double msSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}
constexpr double kIrFadeSeconds = 0.010;
// The crossfade from a source's own IR into the shared tail.
constexpr double kTailFadeSeconds = 0.010;

// An IR longer than maxFrames is cut there with a short fade rather than a
// step, and the samples cut are released (a slot may keep the IR: without
// shrink_to_fit it kept the capacity of the whole, e.g. 30 s of an
// automatic length instead of the 3 s convolved).
void cutIr(AudioBuffer& ir, size_t maxFrames, double sampleRateHz) {
  if (ir.frameCount() <= maxFrames) return;
  const size_t fade = std::min(maxFrames, size_t(kIrFadeSeconds * sampleRateHz));
  for (auto& ch : ir.channels) {
    ch.resize(maxFrames);
    ch.shrink_to_fit();
    for (size_t k = 0; k < fade; ++k) ch[maxFrames - 1 - k] *= float(k) / float(fade);
  }
}
// Frames per inner step of process(): bounds the per-source scratch.
constexpr size_t kProcessChunk = 1024;
// The ambisonic decoder's bulk delay: 2 ms (the ears' onsets lie within
// +-0.7 ms of the head centre's; the rest is the fit's spread).
size_t ambisonicDecoderDelayFrames(double rateHz) { return size_t(std::ceil(0.002 * rateHz)); }

// A vector of three of an array's numbers, from `first`.
template <size_t N>
Vec3d vecOf(const std::array<double, N>& v, size_t first = 0) {
  return {v[first], v[first + 1], v[first + 2]};
}

Status validPosition(const Vec3d& p) {
  if (!isFinite(p)) return invalidArgument("source position is not finite");
  if (!withinCoordinateRange(p)) return outOfRange("source position is farther than 1e6 m from the origin");
  return Status::ok();
}

Status validForward(const Vec3d& forward) {
  if (!isFinite(forward) || !(length(forward) > 0)) return invalidArgument("source forward is zero or not finite");
  return Status::ok();
}

// A source's controls (its SourceSettings but the direct mode, fixed at
// addSource()), as the audio thread and the simulation use them.
// setSourceControls() and addSource() store them whole, setSourceGain()
// changes the gain among them, and readers read them whole (a
// LatestValues). Each number in an atomic of its own, a read that
// overlapped a store could mix two calls' distance curves (a linear curve
// with the other's rolloff is silent where both are at full gain), one
// call's source gain with the other's direct gain (a source faded from
// its direct sound to its whole at -120 dB both ways heard at 0 dB), a
// pattern with the other's normalisation, and two game threads' tables
// mixed for good in the one buffer both wrote.
struct Controls {
  double gain = 0, directGain = 0, reflectionsGain = 0;
  // As given, for sourceControls() (back from the linear gains, -0 and the
  // tiny values, |dB| < ~1e-3, came back changed).
  double gainDb = 0, directGainDb = 0, reflectionsGainDb = 0;
  int distanceModel = 0;
  double distanceMin = 0, distanceMax = 0, rolloff = 0;
  int tableCount = 0;
  std::pair<double, double> table[kMaxDistanceTablePoints] = {};
  int occlusion = 0;
  double radius = 0;
  bool transmissionOn = false;
  int priority = 0;
  double directivityAlpha = 0, directivitySharpness = 0;
  bool directivityPerBand = false;
  double directivityBandAlpha[kNumBands] = {};
  double directivityMeanSquare[kNumBands] = {};  // the pattern's, once per store, not per audio block
};

Controls controlsOf(const SourceSettings& s);
}  // namespace

struct Engine::Slot {
  // What a source's whole IR is synthesised from again (synthesizeIrOf).
  struct WholeIr {
    OmniIrResult result;  // without its IR
    OmniIrSettings settings;
    Vec3d source, listener;
    AmbisonicReceiver ambisonic;
    size_t maxFrames = 0;
    uint32_t denormalMode = 0;  // the one it was synthesised in (currentDenormalMode())
  };
  std::atomic<bool> active{false};
  // Engine::mFramesProcessed at the end of the last chunk this slot's
  // source fed its reflections (0: never). Until that has rung out
  // (ringOutFrames) a new source goes to another slot where one is free
  // (addSource). Written by the audio thread.
  std::atomic<uint64_t> fedUntilFrame{0};
  // The frame by which the direct voice's sound in flight has all come out
  // (0: it never played). Written by the audio thread.
  std::atomic<uint64_t> voiceUntilFrame{0};
  std::atomic<uint32_t> generation{0};           // bumped by add/remove
  std::atomic<uint32_t> simulatedGeneration{~0u};  // generation of the last simulation posted
  // The generation of the source the audio thread last fed the reflections
  // of (written by the audio thread).
  std::atomic<uint32_t> fedGeneration{~0u};
  // A source released before its first IR landed, having played (a
  // one-shot released once its last sample was passed): its generation,
  // else -1. What it played waits in the slot's convolution history for
  // that IR, which the next simulate() makes (from where it was) and posts
  // unless a new source took the slot (addSource() clears it). Changed
  // under Engine::mIrMutex.
  std::atomic<int64_t> owedFirstIr{-1};
  std::atomic<int> direct{0};
  // The pose, set whole by the game thread and read whole (latest_values.h);
  // the audio thread keeps its source's (heardPosition, heardForward): a
  // voice running out keeps its own while a new source takes the slot.
  LatestValues<std::array<double, 3>> position{{0.0, 0.0, 0.0}};
  // The controls (gains, distance curve, occlusion, directivity), set whole
  // by the game thread and read whole (Controls); the audio thread keeps
  // its source's (heardControls), as the pose.
  LatestValues<Controls> controls{controlsOf(SourceSettings{})};
  Controls heardControls = controlsOf(SourceSettings{});  // audio thread
  LatestValues<std::array<double, 3>> forward{{0.0, 0.0, -1.0}};
  Vec3d heardPosition{0, 0, 0}, heardForward{0, 0, -1};  // audio thread
  // The direct path's occlusion as the last simulation found it, written
  // whole by the simulation (reset by addSource()) and taken whole by the
  // audio thread, which keeps its source's (heardOcclusion), as the pose:
  // each band and the blocked flag in an atomic of its own, a block could
  // take some bands of one simulation with the rest of the next's, or one's
  // "blocked" with the other's open bands (silent where both are heard).
  LatestValues<SourceOcclusion> occlusion{SourceOcclusion{}};
  SourceOcclusion heardOcclusion;  // audio thread
  std::unique_ptr<DirectVoice> voiceOwner;   // allocated by the slot's first addSource()
  std::atomic<DirectVoice*> voice{nullptr};  // the audio thread's view of voiceOwner
  uint32_t voiceGeneration = ~0u;      // audio thread
  bool live = false;                   // audio thread: playing in this process() call
  bool reflectionsLive = false;        // audio thread: its IR is this source's (simulated since added)
  // Audio thread: a per-block source not yet simulated feeds its
  // convolution (no IR of its own yet) so that its first IR brings the
  // reflections of what it played meanwhile (feedsEarly), once the
  // convolution holds nothing of the slot's last source (startsAnew until then).
  bool feedsEarly = false;
  bool startsAnew = false;
  bool mutedChunk = false;             // audio thread: this chunk's input was not finite (muted)
  bool voicePlayed = false;            // audio thread: the direct voice played (live, per block) in the last call
  // Audio thread: frames the voice still runs on silence after its source
  // stopped playing (input NULL, or released): its sound in flight; and
  // the generation it runs out for (a new source in the slot ends it).
  size_t drainLeft = 0;
  uint32_t drainGeneration = 0;
  // Audio thread: what the game sets once a frame, as the audio follows
  // it (glide.h): the position and facing the direct voice follows, the
  // source's gain (the voice's and the reflections'), the direct sound's
  // gain and the reflections' gain.
  PoseGlide glide, facingGlide;
  GainGlide gainGlide, directGlide, reflectionsGlide;
  void resetVoiceGlides() {  // the direct voice's: it starts where they are set now
    glide.reset();
    facingGlide.reset();
    directGlide.reset();
  }
  void resetInputGlides() {  // the source's input: its gains start where they are set now
    gainGlide.reset();
    reflectionsGlide.reset();
  }
  double appliedGain = 1.0;            // audio thread: gain at the end of the last chunk
  double appliedReflectionsGain = 1.0; // audio thread: the reflections' gain at the end of the last chunk
  std::vector<float> scaled;           // audio thread: gained input for the mixer
  // Audio thread: the chunk's input as given, for the direct voice, which
  // runs after the mixer has written the outputs (an input may be one of
  // them: a host processing in place).
  std::vector<float> input;
  // Shared tail: the source's late level (sqrt of its tail's W energy),
  // written by the simulation, ramped by the audio thread.
  std::atomic<double> tailGain{0.0};
  // Until its first simulation (tailGainSimulated false), an estimate:
  // the late level of the simulated source nearest to where the game put
  // it, or before it was put anywhere their power mean (addSource,
  // setSourcePosition; the game thread's).
  std::atomic<double> tailGainEstimate{0.0};
  std::atomic<bool> tailGainSimulated{false};
  double lateLevel() const {  // any thread
    return tailGainSimulated.load(std::memory_order_acquire) ? tailGain.load(std::memory_order_relaxed)
                                                             : tailGainEstimate.load(std::memory_order_relaxed);
  }
  double appliedTailGain = 0.0;        // audio thread
  // Poses of the last simulation (simulation thread only): how far the
  // source and the listener moved since orders the next simulations.
  Vec3d simulatedSource, simulatedListener;
  uint64_t simulatedStep = 0;  // Engine::mSimulations when it was last simulated
  // The last IR posted (guarded by Engine::mIrMutex; never the audio thread).
  std::chrono::steady_clock::time_point lastIrPosed{};
  std::shared_ptr<const AudioBuffer> lastIr;
  // A source whose tail the shared one stands for was synthesised in part
  // (its own IR, W whole): what its whole IR is made from when sourceIr()
  // asks for it, lastIr null until then.
  std::shared_ptr<const WholeIr> lastIrInputs;
  bool lastIrIncludesDirect = false;
  uint64_t irCount = 0;
};

namespace {

double dbToGain(double db) { return std::pow(10.0, db / 20.0); }

std::string seconds(double s) {
  char text[32];
  std::snprintf(text, sizeof text, "%g s", s);
  return text;
}

bool hasSharedTail(const EngineSettings& s) { return s.ambisonicOrder > 0 && s.sharedTailSeconds > 0; }

// The convolver of the sources' own IRs.
ConvolverSettings convolverSettingsOf(const EngineSettings& s) {
  ConvolverSettings cs;
  cs.latencyFrames = s.blockFrames;
  cs.maxIrFrames = size_t(std::ceil(s.maxIrSeconds * s.sampleRateHz));
  if (hasSharedTail(s))  // the sources' own IRs end with the crossfade into the shared tail
    cs.maxIrFrames = std::min(cs.maxIrFrames, size_t(std::ceil((s.sharedTailSeconds + kTailFadeSeconds) * s.sampleRateHz)) + 2);
  cs.channels = s.ambisonicOrder > 0 ? size_t(ambisonicChannels(s.ambisonicOrder)) : 2;
  cs.fadeFrames = s.fadeFrames;
  cs.maxPartitionFrames = s.maxPartitionFrames;
  cs.compactSpectra = s.ambisonicOrder > 0 && s.compactAmbisonicSpectra;
  return cs;
}

// The engine's latency: its convolver's, and with ambisonic reflections
// heard binaurally the decoder's convolution (one more block) and its bulk
// delay.
size_t latencyOf(const EngineSettings& s, size_t mixerLatencyFrames) {
  if (s.ambisonicOrder > 0 && s.output == OutputFormat::kBinaural)
    return mixerLatencyFrames + s.blockFrames + ambisonicDecoderDelayFrames(s.sampleRateHz);
  return mixerLatencyFrames;
}

// Every source's direct voice.
DirectVoiceSettings voiceSettingsOf(const EngineSettings& s, size_t latencyFrames) {
  DirectVoiceSettings ds;
  ds.sampleRateHz = s.sampleRateHz;
  ds.speedOfSound = s.simulation.speedOfSound;
  ds.air = s.simulation.air;
  ds.maxDelaySeconds = s.maxDistanceMeters / s.simulation.speedOfSound;
  ds.extraDelayFrames = latencyFrames;
  return ds;
}

// What the engine simulates with: the settings' simulation at the engine's
// rate, its reflections ending where the IRs are cut (maxIrSeconds and the
// cut's fade): an automatic length of up to 30 s in a reverberant room was
// traced, kept and synthesised, then cut.
OmniIrSettings simulationSettingsOf(const EngineSettings& s) {
  OmniIrSettings o = s.simulation;
  o.sampleRateHz = s.sampleRateHz;
  const double cut = s.maxIrSeconds + kIrFadeSeconds;
  o.maxLengthSeconds = o.maxLengthSeconds > 0 ? std::min(o.maxLengthSeconds, cut) : cut;
  return o;
}

// The longest histogram and IR a simulation of these settings makes (the
// set length, else the automatic one's cap; within maxLengthSeconds).
double simulatedSeconds(const OmniIrSettings& o) {
  double seconds = o.lengthSeconds > 0 ? o.lengthSeconds
                                       : std::max(TailCompletionSettings{}.maxAutoSeconds,
                                                  reflectionSettingsOf(o).maxTimeSeconds);
  if (o.maxLengthSeconds > 0) seconds = std::min(seconds, o.maxLengthSeconds);
  return seconds;
}

// A completed histogram of this many seconds, from above (a bin out of its
// range, which simulate() refuses, counted as the smallest valid one).
double histogramBytes(double seconds, double binSeconds) {
  const double bin = binSeconds >= 1e-5 ? binSeconds : 1e-5;
  return (std::ceil(seconds / bin) + 1) * EnergyHistogram::kStride * sizeof(double);
}

// Engine::sourceSlotBytes for the engine's convolver `mixer` and latency.
// A slot keeps for sourceIr() its IR, or with a shared tail what the IR is
// made from (its completed histogram; its few early paths not counted).
size_t slotBytesOf(const EngineSettings& s, const ConvolutionMixer& mixer, size_t latencyFrames) {
  const size_t channels = mixer.settings().channels;
  const OmniIrSettings sim = simulationSettingsOf(s);
  const size_t kept =
      !s.keepSourceIrs ? 0
      : hasSharedTail(s)
          ? size_t(histogramBytes(simulatedSeconds(sim), sim.binSeconds))
          : size_t(std::ceil(s.maxIrSeconds * s.sampleRateHz)) * channels * sizeof(float);
  return DirectVoice::stateBytes(voiceSettingsOf(s, latencyFrames)) + mixer.sourceStateBytes() +
         3 * PreparedIr::bytesFor(mixer.layout(), channels) + kept +
         2 * kProcessChunk * sizeof(float);  // the chunk's input, gained and as given
}

/** The pattern of a source's settings (its axis is set apart: orientation). */
Directivity directivityOf(const SourceSettings& s) {
  Directivity d;
  d.alpha = s.directivityAlpha;
  d.sharpness = s.directivitySharpness;
  d.perBand = s.directivityPerBand;
  d.bandAlpha = s.directivityBandAlpha;
  return d;
}

}  // namespace

double tableGain(const std::pair<double, double>* t, size_t n, double d) {
  if (n == 0) return 1.0;
  if (d <= t[0].first) return t[0].second;
  for (size_t i = 1; i < n; ++i)
    if (d <= t[i].first) {
      const double span = t[i].first - t[i - 1].first;
      const double f = span > 0 ? (d - t[i - 1].first) / span : 1.0;
      return t[i - 1].second + f * (t[i].second - t[i - 1].second);
    }
  return t[n - 1].second;
}

double distanceGain(const DistanceCurve& c, double d) {
  // Physical: the direct voice's own 1/r with its 0.1 m clamp.
  if (c.model == DistanceModel::kPhysical) return 1.0 / std::max(d, DirectVoiceSettings{}.minDistanceMeters);
  const double D = std::clamp(d, c.minDistance, std::max(c.minDistance, c.maxDistance));
  switch (c.model) {
    case DistanceModel::kInverse:
      return c.minDistance / (c.minDistance + c.rolloff * (D - c.minDistance));
    case DistanceModel::kLinear:
      if (c.maxDistance <= c.minDistance) return 1.0;
      return std::max(0.0, 1.0 - c.rolloff * (D - c.minDistance) / (c.maxDistance - c.minDistance));
    case DistanceModel::kExponential:
      return std::pow(D / c.minDistance, -c.rolloff);
    case DistanceModel::kTable:
      return tableGain(c.table.data(), c.table.size(), d);
    default:
      return 1.0 / std::max(d, 0.1);
  }
}

Status validate(const SourceSettings& s) {
  auto gainOk = [](double db) { return db >= -120.0 && db <= 60.0; };
  if (!gainOk(s.gainDb)) return invalidArgument("source gain " + std::to_string(s.gainDb) + " dB is outside [-120, 60]");
  if (!gainOk(s.directGainDb))
    return invalidArgument("source direct gain " + std::to_string(s.directGainDb) + " dB is outside [-120, 60]");
  if (!gainOk(s.reflectionsGainDb))
    return invalidArgument("source reflections gain " + std::to_string(s.reflectionsGainDb) +
                           " dB is outside [-120, 60]");
  const int model = int(s.distance.model);
  if (model < 0 || model > int(DistanceModel::kTable)) return invalidArgument("unknown distance model");
  if (s.distance.model == DistanceModel::kTable) {
    const auto& t = s.distance.table;
    if (t.empty() || t.size() > size_t(kMaxDistanceTablePoints))
      return invalidArgument("distance table: 1 to " + std::to_string(kMaxDistanceTablePoints) + " points, got " +
                             std::to_string(t.size()));
    for (size_t i = 0; i < t.size(); ++i) {
      if (!(t[i].first >= 0 && t[i].first <= 1e6) || (i > 0 && !(t[i].first > t[i - 1].first)))
        return invalidArgument("distance table: point " + std::to_string(i) + "'s distance " +
                               std::to_string(t[i].first) + " m is not ascending in [0, 1e6]");
      if (!(t[i].second >= 0 && t[i].second <= 10))
        return invalidArgument("distance table: point " + std::to_string(i) + "'s gain " + std::to_string(t[i].second) +
                               " is outside [0, 10]");
    }
  }
  if (!(s.distance.minDistance > 0 && s.distance.minDistance <= 1e6))
    return invalidArgument("distance curve min distance " + std::to_string(s.distance.minDistance) +
                           " m is outside (0, 1e6]");
  if (!(s.distance.maxDistance >= s.distance.minDistance && s.distance.maxDistance <= 1e6))
    return invalidArgument("distance curve max distance " + std::to_string(s.distance.maxDistance) +
                           " m is not in [min distance, 1e6]");
  if (!(s.distance.rolloff >= 0 && s.distance.rolloff <= 100))
    return invalidArgument("distance curve rolloff " + std::to_string(s.distance.rolloff) + " is outside [0, 100]");
  EARSHOT_RETURN_IF_ERROR(validate(directivityOf(s)));
  const int occ = int(s.occlusion);
  if (occ < 0 || occ > int(OcclusionMode::kVolumetric)) return invalidArgument("unknown occlusion mode");
  if (!(s.radiusMeters > 0 && s.radiusMeters <= 100))
    return invalidArgument("source radius " + std::to_string(s.radiusMeters) + " m is outside (0, 100]");
  return Status::ok();
}

namespace {

Controls controlsOf(const SourceSettings& s) {
  Controls c;
  c.gain = dbToGain(s.gainDb);
  c.gainDb = s.gainDb;
  c.directGain = dbToGain(s.directGainDb);
  c.reflectionsGain = dbToGain(s.reflectionsGainDb);
  c.directGainDb = s.directGainDb;
  c.reflectionsGainDb = s.reflectionsGainDb;
  c.distanceModel = int(s.distance.model);
  c.distanceMin = s.distance.minDistance;
  c.distanceMax = s.distance.maxDistance;
  c.rolloff = s.distance.rolloff;
  if (s.distance.model == DistanceModel::kTable) {  // (validated: 1 to kMaxDistanceTablePoints points)
    c.tableCount = int(std::min(s.distance.table.size(), size_t(kMaxDistanceTablePoints)));
    for (int i = 0; i < c.tableCount; ++i) c.table[i] = s.distance.table[size_t(i)];
  }
  c.occlusion = int(s.occlusion);
  c.radius = s.radiusMeters;
  c.transmissionOn = s.transmission;
  c.priority = s.priority;
  const Directivity d = directivityOf(s);
  const BandArrayD ms = d.meanSquares();
  for (int b = 0; b < kNumBands; ++b) {
    c.directivityMeanSquare[b] = ms[size_t(b)];
    c.directivityBandAlpha[b] = d.alphaOf(b);
  }
  c.directivityAlpha = s.directivityAlpha;
  c.directivitySharpness = s.directivitySharpness;
  c.directivityPerBand = s.directivityPerBand;
  return c;
}

/** The pattern of a source's controls, without its axis (the forward). */
Directivity directivityOf(const Controls& c) {
  Directivity d;
  d.alpha = c.directivityAlpha;
  d.sharpness = c.directivitySharpness;
  d.perBand = c.directivityPerBand;
  for (int b = 0; b < kNumBands; ++b) d.bandAlpha[size_t(b)] = c.directivityBandAlpha[b];
  return d;
}

}  // namespace

Status Engine::setSourceControls(uint32_t s, const SourceSettings& settings) {
  if (!validSource(s)) return invalidArgument("source " + std::to_string(s) + " does not exist");
  EARSHOT_RETURN_IF_ERROR(validate(settings));
  Slot& slot = *mSlots[s];
  slot.controls.store(controlsOf(settings));
  return Status::ok();
}

Result<SourceOcclusion> Engine::sourceOcclusion(uint32_t s) const {
  if (!validSource(s)) return invalidArgument("source " + std::to_string(s) + " does not exist");
  return mSlots[s]->occlusion.load();
}

Result<SourceSettings> Engine::sourceControls(uint32_t s) const {
  if (!validSource(s)) return invalidArgument("source " + std::to_string(s) + " does not exist");
  const Slot& slot = *mSlots[s];
  SourceSettings out;
  out.direct = DirectMode(slot.direct.load());
  const Controls c = slot.controls.load();
  out.gainDb = c.gainDb;
  out.directGainDb = c.directGainDb;
  out.reflectionsGainDb = c.reflectionsGainDb;
  out.distance.model = DistanceModel(c.distanceModel);
  out.distance.minDistance = c.distanceMin;
  out.distance.maxDistance = c.distanceMax;
  out.distance.rolloff = c.rolloff;
  out.distance.table.assign(c.table, c.table + std::clamp(c.tableCount, 0, kMaxDistanceTablePoints));
  out.occlusion = OcclusionMode(c.occlusion);
  out.radiusMeters = c.radius;
  out.transmission = c.transmissionOn;
  out.priority = c.priority;
  const Directivity d = directivityOf(c);
  out.directivityAlpha = d.alpha;
  out.directivitySharpness = d.sharpness;
  out.directivityPerBand = d.perBand;
  out.directivityBandAlpha = d.bandAlpha;
  return out;
}

Status Engine::setSourceOrientation(uint32_t s, const Vec3d& forward) {
  if (!validSource(s)) return invalidArgument("source " + std::to_string(s) + " does not exist");
  EARSHOT_RETURN_IF_ERROR(validForward(forward));
  const Vec3d f = normalize(forward);
  mSlots[s]->forward.store({f.x, f.y, f.z});
  return Status::ok();
}

namespace {

/** kVolumetric: the energy average, per band, of the transmission along 16
 *  rays from the listener to points spread over a sphere of `radius` around
 *  the source (a Fibonacci sphere: deterministic). A ray that crosses a
 *  surface counts its transmission, or 0 without transmission. */
BandArrayD volumetricTransmission(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& source,
                                  const Vec3d& listener, double radius, bool transmissionOn) {
  constexpr int kRays = 16;
  DirectPathSettings ds;
  ds.air.enabled = false;
  BandArrayD energy = filledBands(0.0);
  const double golden = 3.14159265358979323846 * (3.0 - std::sqrt(5.0));
  for (int k = 0; k < kRays; ++k) {
    const double z = 1.0 - 2.0 * (k + 0.5) / kRays, rho = std::sqrt(std::max(0.0, 1.0 - z * z));
    const Vec3d p{source.x + radius * rho * std::cos(golden * k), source.y + radius * rho * std::sin(golden * k),
                  source.z + radius * z};
    const DirectPath path = computeDirectPath(&tracer, materials, p, listener, ds);
    for (int b = 0; b < kNumBands; ++b) {
      const double g = path.surfacesCrossed > 0 && !transmissionOn ? 0.0 : path.transmissionGain[b];
      energy[b] += g * g / kRays;
    }
  }
  for (auto& e : energy) e = std::sqrt(e);
  return energy;
}

}  // namespace

Engine::~Engine() = default;

size_t Engine::latencyFrames() const { return mLatency; }

std::shared_ptr<const AmbisonicDecoder> Engine::ambisonicDecoder() const {
  std::lock_guard<std::mutex> lock(mAddMutex);
  return mDecoder;
}

Result<std::unique_ptr<Engine>> Engine::create(const EngineSettings& s, std::shared_ptr<const BinauralModel> model) {
  if (!model) return invalidArgument("engine: no HRTF model");
  std::promise<Result<std::shared_ptr<const BinauralModel>>> ready;
  ready.set_value(std::move(model));
  return create(s, ready.get_future().share());
}

namespace {
// A loaded model (or its load's error) for an engine at `rateHz`.
Status checkModel(const Result<std::shared_ptr<const BinauralModel>>& m, double rateHz) {
  if (!m.isOk()) return m.status();
  if (!*m) return invalidArgument("engine: no HRTF model");
  if (std::fabs((*m)->sampleRateHz() - rateHz) > 1e-6)
    return invalidArgument("engine: sample rate " + std::to_string(rateHz) + " Hz differs from the HRTF set's " +
                           std::to_string((*m)->sampleRateHz()) + " Hz");
  return Status::ok();
}
}  // namespace

Result<std::shared_ptr<const BinauralModel>> Engine::model() const {
  if (!mModel.valid()) return invalidArgument("engine: no HRTF model");
  const Result<std::shared_ptr<const BinauralModel>>& m = mModel.get();
  EARSHOT_RETURN_IF_ERROR(checkModel(m, mSettings.sampleRateHz));
  return *m;
}

Result<std::unique_ptr<Engine>> Engine::create(const EngineSettings& settings, BinauralModelFuture model) {
  if (!model.valid()) return invalidArgument("engine: no HRTF model");
  EngineSettings s = settings;
  if (!(s.sharedTailSeconds >= 0))
    return invalidArgument("engine: sharedTailSeconds " + std::to_string(s.sharedTailSeconds) + " is negative or NaN");
  // A shared tail that would start at or after the cut shares nothing.
  if (s.sharedTailSeconds >= s.maxIrSeconds) s.sharedTailSeconds = 0;
  // A model already loaded is checked now (the sample rate), a loading one
  // when it is first needed.
  if (model.wait_for(std::chrono::seconds(0)) == std::future_status::ready)
    EARSHOT_RETURN_IF_ERROR(checkModel(model.get(), s.sampleRateHz));
  if (s.maxSources < 1 || s.maxSources > 4096)
    return invalidArgument("engine: maxSources " + std::to_string(s.maxSources) + " is outside [1, 4096]");
  if (s.simulationGroupSources < 1 || s.simulationGroupSources > 4096)
    return invalidArgument("engine: simulationGroupSources " + std::to_string(s.simulationGroupSources) +
                           " is outside [1, 4096]");
  if (!(s.maxIrSeconds > 0 && s.maxIrSeconds <= 60))
    return invalidArgument("engine: maxIrSeconds " + std::to_string(s.maxIrSeconds) + " is outside (0, 60]");
  if (!(s.simulation.maxLengthSeconds >= 0 && s.simulation.maxLengthSeconds <= 600))
    return invalidArgument("engine: simulation.maxLengthSeconds " + std::to_string(s.simulation.maxLengthSeconds) +
                           " is outside [0, 600]");
  if (!(s.maxDistanceMeters > 0 && s.maxDistanceMeters <= 20000))
    return invalidArgument("engine: maxDistanceMeters " + std::to_string(s.maxDistanceMeters) + " is outside (0, 20000]");
  std::unique_ptr<Engine> e(new Engine());
  e->mSettings = s;
  e->mSettings.simulation = simulationSettingsOf(s);
  e->mModel = std::move(model);

  if (s.ambisonicOrder < 0 || s.ambisonicOrder > kMaxAmbisonicOrder)
    return invalidArgument("engine: ambisonicOrder " + std::to_string(s.ambisonicOrder) + " is outside [0, " +
                           std::to_string(kMaxAmbisonicOrder) + "]");
  const bool sharedTail = hasSharedTail(s);
  const ConvolverSettings cs = convolverSettingsOf(s);
  auto mixer = ConvolutionMixer::create(cs, s.maxSources);
  if (!mixer.isOk()) return Status(mixer.status().code(), "engine: " + mixer.status().message());
  e->mMixer = std::move(mixer.value());
  e->mLatency = latencyOf(s, e->mMixer->latencyFrames());
  if (s.output == OutputFormat::kAmbisonic && s.ambisonicOrder < 1)
    return invalidArgument("engine: ambisonic output needs ambisonic reflections (ambisonicOrder 1-3)");
  e->mOutputChannels = s.output == OutputFormat::kAmbisonic ? size_t(ambisonicChannels(s.ambisonicOrder)) : 2;
  if (s.ambisonicOrder > 0) {
    e->mRotation = std::make_unique<ShRotation>();
    const size_t channels = size_t(ambisonicChannels(s.ambisonicOrder));
    e->mBus.assign(channels * kProcessChunk, 0.0f);
    e->mRotated.assign(channels * kProcessChunk, 0.0f);
    e->mLastRotation.assign(size_t(kMaxAmbisonicChannels * kMaxAmbisonicChannels), 0.0f);
    if (sharedTail) {
      ConvolverSettings ts = cs;
      ts.maxIrFrames = size_t(std::ceil(s.maxIrSeconds * s.sampleRateHz));
      auto tail = ConvolutionMixer::create(ts, 1);
      if (!tail.isOk()) return Status(tail.status().code(), "engine: " + tail.status().message());
      e->mTailMixer = std::move(tail.value());
      EARSHOT_RETURN_IF_ERROR(e->mTailMixer->reserveSource(0));
      e->mTailInput.assign(kProcessChunk, 0.0f);
      e->mTailBus.assign(channels * kProcessChunk, 0.0f);
    }
  }

  e->mRamp.assign(kProcessChunk, 0.0f);
  for (size_t i = 0; i < s.maxSources; ++i) e->mSlots.push_back(std::make_unique<Slot>());
  const ListenerOrientation o;
  const double listener[9] = {0, 0, 0, o.forward.x, o.forward.y, o.forward.z, o.up.x, o.up.y, o.up.z};
  e->mListener.store({listener[0], listener[1], listener[2], listener[3], listener[4], listener[5], listener[6],
                      listener[7], listener[8]});
  for (int i = 0; i < 9; ++i) e->mHeardListener[size_t(i)] = listener[i];
  auto empty = RayTracer::create(TriangleMesh{});
  if (!empty.isOk()) return empty.status();
  e->mEmptyTracer = std::move(empty.value());
  e->mTracer = e->mEmptyTracer;
  e->mMaterials = std::make_shared<const MaterialTable>();
  const unsigned threads = s.threads > 0 ? s.threads : std::max(2u, std::thread::hardware_concurrency()) - 1;
  e->mSettings.threads = threads;
  {
    // A simulation's traces within the memory limit (traceMemoryBytes):
    // one on every worker, or one per worker side by side (one per source,
    // at most). Refused here rather than by every simulate(); invalid
    // settings are left to it.
    const ReflectionSettings traced = reflectionSettingsOf(e->mSettings.simulation);
    if (validate(traced).isOk())
      EARSHOT_RETURN_IF_ERROR(checkMemoryEstimate(
          std::max(traceMemoryBytes(traced, 1, threads),
                   double(std::min<size_t>(threads, s.maxSources)) * traceMemoryBytes(traced, 1, 1)),
          "engine: simulation.rays " + std::to_string(traced.rays) + " with its histogram on " +
              std::to_string(threads) + " threads"));
  }
  e->mPool = std::make_unique<ThreadPool>(threads, s.workerNice);
  for (unsigned w = 0; w < e->mPool->threadCount(); ++w) e->mWorkerPools.push_back(std::make_unique<ThreadPool>(1));
  e->mInputs.assign(s.maxSources, nullptr);
  return e;
}

void Engine::setScene(std::shared_ptr<const RayTracer> tracer, std::shared_ptr<const MaterialTable> materials) {
  std::lock_guard<std::mutex> lock(mSceneMutex);
  mTracer = tracer ? std::move(tracer) : mEmptyTracer;
  mMaterials = materials ? std::move(materials) : std::make_shared<const MaterialTable>();
}

bool Engine::validSource(uint32_t s) const { return s < mSlots.size() && mSlots[s]->active.load(); }

Status Engine::createDecoder(const BinauralModel& model) {
  AmbisonicDecoderSettings ds;
  ds.order = mSettings.ambisonicOrder;
  ds.delayFrames = ambisonicDecoderDelayFrames(mSettings.sampleRateHz);
  ds.taps = 512;
  while (ds.taps / 2 <= ds.delayFrames) ds.taps *= 2;
  auto decoder = AmbisonicDecoder::create(model, ds);
  if (!decoder.isOk()) return Status(decoder.status().code(), "engine: " + decoder.status().message());
  ConvolverSettings cs;
  cs.latencyFrames = mSettings.blockFrames;
  cs.maxIrFrames = (*decoder)->taps();
  cs.channels = 2;
  cs.fadeFrames = 0;
  auto mixer = ConvolutionMixer::create(cs, size_t((*decoder)->channels()));
  if (!mixer.isOk()) return Status(mixer.status().code(), "engine: " + mixer.status().message());
  for (int c = 0; c < (*decoder)->channels(); ++c) {
    auto prepared = PreparedIr::create((*decoder)->channelIr(c), (*mixer)->layout());
    if (!prepared.isOk()) return prepared.status();
    EARSHOT_RETURN_IF_ERROR((*mixer)->setIr(size_t(c), *prepared));
  }
  mDecoder = *decoder;
  mDecoderMixer = std::move(mixer.value());
  mDecoderMixerLive.store(mDecoderMixer.get(), std::memory_order_release);
  return Status::ok();
}

size_t Engine::sourceSlotBytes() const { return slotBytesOf(mSettings, *mMixer, mLatency); }

Result<size_t> Engine::sourceSlotBytes(const EngineSettings& settings) {
  // The mixer's layout depends on the slot count; a mixer without sources
  // holds only its shared buffers.
  auto mixer = ConvolutionMixer::create(convolverSettingsOf(settings), settings.maxSources);
  if (!mixer.isOk()) return Status(mixer.status().code(), "engine: " + mixer.status().message());
  return slotBytesOf(settings, **mixer, latencyOf(settings, (*mixer)->latencyFrames()));
}

size_t Engine::ringOutFrames() const {
  // The IR's length after the output's latency, and a margin for the
  // ambisonic decoder's own convolution and delay.
  return mLatency + size_t(std::ceil((mSettings.maxIrSeconds + 0.1) * mSettings.sampleRateHz));
}

Result<uint32_t> Engine::addSource(const SourceSettings& settings) {
  return addSourceAt(settings, {0, 0, 0}, {0, 0, -1}, false);
}

Result<uint32_t> Engine::addSource(const SourceSettings& settings, const Vec3d& position, const Vec3d& forward) {
  return addSourceAt(settings, position, forward, true);
}

Result<uint32_t> Engine::addSourceAt(const SourceSettings& settings, const Vec3d& position, const Vec3d& forward,
                                     bool placed) {
  EARSHOT_RETURN_IF_ERROR(validate(settings));
  EARSHOT_RETURN_IF_ERROR(validPosition(position));
  EARSHOT_RETURN_IF_ERROR(validForward(forward));
  std::lock_guard<std::mutex> lock(mAddMutex);
  // Which slot. A removed source's reverberation rings out in its slot (what
  // it played is still in the slot's convolution history, heard through its
  // IR), and a new source in that slot would carry the rest of it through
  // its own IR once simulated: the old sound's reflections from the new
  // source's place; and its direct sound still in flight would be cut. So
  // a new source takes, in this order: a free slot that has rung out (or
  // never played); a slot never used (allocating its state, within the
  // memory limit); the free slot whose ring-out ends first.
  const uint64_t now = mFramesProcessed.load(std::memory_order_relaxed);
  const uint64_t ringOut = ringOutFrames();
  int rungOut = -1, fresh = -1, ringing = -1;
  uint64_t ringingEnds = 0;
  for (uint32_t i = 0; i < mSlots.size(); ++i) {
    const Slot& slot = *mSlots[i];
    if (slot.active.load()) continue;
    if (!slot.voiceOwner) {
      if (fresh < 0) fresh = int(i);
      continue;
    }
    const uint64_t fed = slot.fedUntilFrame.load(std::memory_order_relaxed);
    const uint64_t ends = std::max(fed == 0 ? 0 : fed + ringOut, slot.voiceUntilFrame.load(std::memory_order_relaxed));
    if (now >= ends) {
      if (rungOut < 0) rungOut = int(i);
    } else if (ringing < 0 || ends < ringingEnds) {
      ringing = int(i);
      ringingEnds = ends;
    }
  }
  int chosen = rungOut;
  if (chosen < 0 && fresh >= 0) {
    const Status allocated = allocateSlot(uint32_t(fresh));
    if (allocated.isOk())
      chosen = fresh;
    else if (ringing < 0 || allocated.code() != StatusCode::kOutOfRange)
      return allocated;  // (a slot past the memory limit falls back on a ringing one)
  }
  if (chosen < 0) chosen = ringing;
  if (chosen < 0)
    return Status(StatusCode::kOutOfRange, "all " + std::to_string(mSlots.size()) + " source slots are in use");
  Slot& slot = *mSlots[size_t(chosen)];
  // The source's late level until its first simulation: the other
  // simulated sources' (their power mean; once the game puts the source
  // somewhere, the nearest one's). What it plays before its first IR goes
  // into the shared tail at this level (in a room whose late field is
  // diffuse every source's is the same), and into its own convolution's
  // history, so that its first IR brings the reflections of what it
  // played while it waited (a one-shot is not heard dry).
  double lateEnergy = 0;
  int lateCount = 0;
  for (const auto& other : mSlots) {
    if (!other->active.load() || !other->tailGainSimulated.load()) continue;
    const double t = other->tailGain.load();
    lateEnergy += t * t;
    ++lateCount;
  }
  slot.direct.store(int(settings.direct));
  const Controls controls = controlsOf(settings);  // (the pattern's quadrature, before the lock)
  const Vec3d f = normalize(forward);
  {
    // A slot used before still holds its last source's IR: silence takes
    // its place (the audio thread drops it at once where the slot has rung
    // out, or lets it fade out), in the order of the IRs the simulation
    // posts, which posts none for a source no longer in its slot.
    std::shared_ptr<const PreparedIr> replaced;  // freed after the lock, as the simulation's
    {
      std::lock_guard<std::mutex> irLock(mIrMutex);
      if (chosen != fresh) EARSHOT_RETURN_IF_ERROR(mMixer->postIr(size_t(chosen), nullptr, &replaced));
      slot.owedFirstIr.store(-1);
      slot.generation.fetch_add(1);
      // Where it is, before the slot turns active: the audio thread's first
      // block of it plays from there (not from the slot's last source's
      // place, or the origin while the game has yet to move it), and so
      // does its first simulation. After the new generation: the last
      // source's sound in flight keeps its own place.
      slot.position.store({position.x, position.y, position.z});
      slot.forward.store({f.x, f.y, f.z});
      // So are its controls: the last source's sound in flight keeps its
      // own distance curve, direct gain and pattern until the audio thread
      // sees the new source (which ends it).
      slot.controls.store(controls);
      // What a simulation writes into its source's slot, under this lock
      // once it has checked the generation: a job of the slot's last
      // source that ends now finds the generation changed, and one that
      // ended before is overwritten here.
      slot.tailGainSimulated.store(false);
      slot.tailGainEstimate.store(lateCount > 0 ? std::sqrt(lateEnergy / lateCount) : 0.0);
      if (placed) estimateLateLevel(slot, position);
      slot.occlusion.store(SourceOcclusion{});
    }
    replaced.reset();
    // (Also when no simulation runs: the audio thread takes no IR while
    // the retired ones wait in a full queue.)
    if (chosen != fresh) mMixer->collectGarbage();
  }
  slot.active.store(true);
  return uint32_t(chosen);
}

Status Engine::allocateSlot(uint32_t i) {
  // The slot's first source: its state, published to the audio thread
  // before the slot turns active; refused before it is allocated when the
  // slots would pass the memory limit with their IRs.
  Slot& slot = *mSlots[i];
  auto model = this->model();
  if (!model.isOk()) return model.status();
  const size_t slots = mMixer->reservedSources() + 1;
  EARSHOT_RETURN_IF_ERROR(checkMemoryEstimate(
      double(slots) * double(sourceSlotBytes()),
      "engine: " + std::to_string(slots) + " source slots with IRs of up to " + seconds(mSettings.maxIrSeconds)));
  const DirectVoiceSettings ds = voiceSettingsOf(mSettings, mLatency);
  if (mSettings.ambisonicOrder > 0 && mSettings.output == OutputFormat::kBinaural && !mDecoder)
    EARSHOT_RETURN_IF_ERROR(createDecoder(**model));
  auto voice = DirectVoice::create(ds, (*model)->hrtfPtr());
  if (!voice.isOk()) return Status(voice.status().code(), "engine: " + voice.status().message());
  EARSHOT_RETURN_IF_ERROR(mMixer->reserveSource(i));
  try {
    slot.scaled.assign(kProcessChunk, 0.0f);
    slot.input.assign(kProcessChunk, 0.0f);
  } catch (const std::bad_alloc&) {
    return outOfRange("engine: out of memory for a source slot");
  }
  slot.voiceOwner = std::move(voice.value());
  slot.voice.store(slot.voiceOwner.get(), std::memory_order_release);
  return Status::ok();
}

Status Engine::removeSource(uint32_t s) {
  if (!validSource(s)) return invalidArgument("source " + std::to_string(s) + " does not exist");
  Slot& slot = *mSlots[s];
  std::lock_guard<std::mutex> lock(mIrMutex);
  slot.active.store(false);
  // Played before its first IR landed: that IR is still owed (its sound
  // so far is in the slot's convolution, waiting for it).
  const uint32_t generation = slot.generation.load();
  if (slot.simulatedGeneration.load() != generation && slot.fedGeneration.load() == generation)
    slot.owedFirstIr.store(generation);
  slot.generation.fetch_add(1);
  return Status::ok();
}

Status Engine::setSourcePosition(uint32_t s, const Vec3d& p) {
  if (!validSource(s)) return invalidArgument("source " + std::to_string(s) + " does not exist");
  EARSHOT_RETURN_IF_ERROR(validPosition(p));
  Slot& slot = *mSlots[s];
  slot.position.store({p.x, p.y, p.z});
  estimateLateLevel(slot, p);
  return Status::ok();
}

void Engine::estimateLateLevel(Slot& slot, const Vec3d& p) {
  if (!mTailMixer || slot.tailGainSimulated.load()) return;
  // Not simulated yet: the late level of the simulated source nearest to
  // it (more likely in the same room than the mean of all).
  double nearest = std::numeric_limits<double>::infinity();
  const Slot* from = nullptr;
  for (const auto& other : mSlots) {
    if (other.get() == &slot || !other->active.load() || !other->tailGainSimulated.load()) continue;
    const Vec3d q = vecOf(other->position.load());
    if (length(q - p) < nearest) {
      nearest = length(q - p);
      from = other.get();
    }
  }
  if (from) slot.tailGainEstimate.store(from->tailGain.load());
}

Status Engine::setSourceGainDb(uint32_t s, double gainDb) {
  if (!validSource(s)) return invalidArgument("source " + std::to_string(s) + " does not exist");
  if (!(gainDb >= -120.0 && gainDb <= 60.0))
    return invalidArgument("source gain " + std::to_string(gainDb) + " dB is outside [-120, 60]");
  mSlots[s]->controls.update([gainDb](Controls& c) {
    c.gain = dbToGain(gainDb);
    c.gainDb = gainDb;
  });
  return Status::ok();
}

Status Engine::setListener(const Vec3d& position, const ListenerOrientation& o) {
  if (!isFinite(position)) return invalidArgument("listener position is not finite");
  if (!withinCoordinateRange(position)) return outOfRange("listener position is farther than 1e6 m from the origin");
  EARSHOT_RETURN_IF_ERROR(validate(o));
  const double v[9] = {position.x, position.y, position.z, o.forward.x, o.forward.y, o.forward.z, o.up.x, o.up.y, o.up.z};
  mListener.store({v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]});
  return Status::ok();
}

SimulationStats Engine::lastSimulation() const { return mStats; }

SourceIr Engine::sourceIrInfo(uint32_t source) const {
  SourceIr out;
  if (!validSource(source)) return out;
  std::lock_guard<std::mutex> lock(mIrMutex);
  const Slot& slot = *mSlots[source];
  if (slot.generation.load() != slot.simulatedGeneration.load()) return out;  // not simulated since (re)added
  out.includesDirect = slot.lastIrIncludesDirect;
  out.simulations = slot.irCount;
  out.posed = slot.lastIrPosed;
  return out;
}

SourceIr Engine::sourceIr(uint32_t source) const {
  SourceIr out;
  if (!validSource(source)) return out;
  Slot& slot = *mSlots[source];
  std::shared_ptr<const Slot::WholeIr> inputs;
  {
    std::lock_guard<std::mutex> lock(mIrMutex);
    if (slot.generation.load() != slot.simulatedGeneration.load()) return out;  // not simulated since (re)added
    out.ir = slot.lastIr;
    out.includesDirect = slot.lastIrIncludesDirect;
    out.simulations = slot.irCount;
    out.posed = slot.lastIrPosed;
    if (out.ir || !slot.lastIrInputs) return out;
    inputs = slot.lastIrInputs;
    if (mMadeIrFrom.lock() == inputs) {
      out.ir = mMadeIr;
      return out;
    }
  }
  // Synthesised in part (a shared tail): made whole now, outside the lock,
  // in the denormal mode of its simulation (the same bits), and kept as the
  // engine's last made if no later IR replaced it meanwhile.
  const BinauralReceiver* binaural = nullptr;
  auto ir = [&] {
    ScopedDenormalMode mode(inputs->denormalMode);
    return synthesizeIrOf(inputs->result, inputs->settings, inputs->source, inputs->listener, binaural,
                          &inputs->ambisonic);
  }();
  if (!ir.isOk()) return out;  // (the same inputs gave an IR in part; not expected)
  cutIr(*ir, inputs->maxFrames, mSettings.sampleRateHz);
  out.ir = std::make_shared<const AudioBuffer>(std::move(ir.value()));
  std::shared_ptr<const AudioBuffer> oldMadeIr;  // freed after the lock
  std::lock_guard<std::mutex> lock(mIrMutex);
  if (slot.lastIrInputs == inputs) {
    oldMadeIr = std::move(mMadeIr);
    mMadeIr = out.ir;
    mMadeIrFrom = inputs;
  }
  return out;
}

Status Engine::simulate(uint32_t count) {
  std::lock_guard<std::mutex> simLock(mSimulationMutex);
  std::vector<uint32_t> order;
  const uint32_t n = uint32_t(mSlots.size());
  for (uint32_t k = 0; k < n; ++k) {
    const uint32_t i = (mNextRoundRobin + k) % n;
    // (A source released before its first IR is owed that IR.)
    if (mSlots[i]->active.load() || mSlots[i]->owedFirstIr.load() >= 0) order.push_back(i);
  }
  // Higher priority first; then never simulated; then waiting for over
  // twice a round (what moved most would otherwise starve a source that
  // stands still: its reflections would never follow a door that opened or
  // its own turn); then most changed since the last IR; round-robin order
  // among equals (stable sort).
  const Vec3d listenerNow = vecOf(mListener.load());
  const uint64_t taken = count > 0 && count < order.size() ? count : std::max<size_t>(order.size(), 1);
  const uint64_t patience = 2 * ((order.size() + taken - 1) / taken);
  std::vector<double> changed(n, 0.0);
  std::vector<char> fresh(n, 0), waiting(n, 0);
  std::vector<int> priority(n, 0);
  for (uint32_t i : order) {
    const Slot& slot = *mSlots[i];
    priority[i] = slot.controls.load().priority;
    fresh[i] = slot.simulatedGeneration.load() != slot.generation.load() || slot.owedFirstIr.load() >= 0;
    waiting[i] = mSimulations - slot.simulatedStep >= patience;
    const Vec3d p = vecOf(slot.position.load());
    changed[i] = length(p - slot.simulatedSource) + length(listenerNow - slot.simulatedListener);
  }
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    const int pa = priority[a], pb = priority[b];
    if (pa != pb) return pa > pb;
    if (fresh[a] != fresh[b]) return fresh[a] > fresh[b];
    if (waiting[a] != waiting[b]) return waiting[a] > waiting[b];
    return changed[a] > changed[b];
  });
  if (count > 0 && count < order.size()) order.resize(count);
  if (!order.empty()) {
    // Continue the round robin after the last source taken in its order.
    uint32_t last = order.front();
    auto rank = [&](uint32_t i) { return (i + n - mNextRoundRobin) % n; };
    for (uint32_t i : order)
      if (rank(i) > rank(last)) last = i;
    mNextRoundRobin = (last + 1) % n;
  }
  return simulateLocked(order, /*takeNewcomers=*/true);
}

Status Engine::simulate(const std::vector<uint32_t>& sources) {
  for (uint32_t s : sources)
    if (!validSource(s)) return invalidArgument("source " + std::to_string(s) + " does not exist");
  std::lock_guard<std::mutex> simLock(mSimulationMutex);
  return simulateLocked(sources, /*takeNewcomers=*/false);
}

size_t Engine::simulationGroupSize() const {
  const EngineSettings& s = mSettings;
  // A source's IR in the making, from above: its synthesised IR (as long
  // as its histogram, and 50 ms more), only W whole with a shared tail, and
  // its completed histogram.
  const double irSeconds = simulatedSeconds(s.simulation) + 0.05;
  const double frames = std::ceil(irSeconds * s.sampleRateHz);
  const double channels = double(mMixer->settings().channels);
  const double perSource = frames * (mTailMixer ? 1.0 : channels) * sizeof(float) +
                           histogramBytes(irSeconds, s.simulation.binSeconds);
  // What the limit leaves beside the slots in use and two whole IRs (in
  // every channel): the last source's, and the one sourceIr() made last.
  const double left = double(defaultInputLimits().maxMemoryBytes) -
                      double(mMixer->reservedSources()) * double(sourceSlotBytes()) -
                      2 * frames * channels * sizeof(float);
  return size_t(std::clamp(std::floor(left / perSource), 1.0, 4096.0));
}

Status Engine::simulateLocked(const std::vector<uint32_t>& requested, bool takeNewcomers) {
  std::vector<uint32_t> order = requested;
  const auto t0 = std::chrono::steady_clock::now();
  ++mSimulations;  // (each source taken below records this step)
  std::shared_ptr<const RayTracer> tracer;
  std::shared_ptr<const MaterialTable> materials;
  {
    std::lock_guard<std::mutex> lock(mSceneMutex);
    tracer = mTracer;
    materials = mMaterials;
  }
  const std::array<double, 9> pose = mListener.load();
  const Vec3d listener = vecOf(pose);
  auto model = this->model();
  if (!model.isOk()) return model.status();
  BinauralReceiver receiver;
  receiver.model = *model;
  receiver.orientation.forward = vecOf(pose, 3);
  receiver.orientation.up = vecOf(pose, 6);
  // Ambisonic reflections are in the world frame: the head's orientation is
  // applied per block on the audio thread, not here.
  AmbisonicReceiver ambisonic;
  ambisonic.order = std::max(1, mSettings.ambisonicOrder);
  ambisonic.frame = worldAmbisonicFrame();
  const bool isAmbisonic = mSettings.ambisonicOrder > 0;
  const BinauralReceiver* binauralReceiver = isAmbisonic ? nullptr : &receiver;
  const AmbisonicReceiver* ambisonicReceiver = isAmbisonic ? &ambisonic : nullptr;

  SimulationStats stats;
  const size_t maxFrames = size_t(std::ceil(mSettings.maxIrSeconds * mSettings.sampleRateHz));
  struct Job {
    uint32_t slot, generation;
    OmniIrSettings settings;
    Vec3d source;
    Controls controls;  // the source's, read whole with its pose
    std::optional<Result<OmniIrResult>> result;
    uint32_t denormalMode = 0;  // the synthesis's (pool workers flush denormals)
  };
  // Shared tail: each source's own IR up to sharedTailSeconds, crossfaded
  // (complementary linear ramps) into its tail, whose W energy is the
  // source's late level; the last source simulated with a tail gives the
  // shared one, at unit energy. Every source but the last is synthesised
  // up to the crossfade's end only (W whole, for its level).
  const size_t tailSplit = size_t(std::llround(mSettings.sharedTailSeconds * mSettings.sampleRateHz));
  const size_t tailFade = size_t(std::llround(kTailFadeSeconds * mSettings.sampleRateHz));
  auto tailWeight = [&](size_t i) {
    return i < tailSplit ? 0.0f : i >= tailSplit + tailFade ? 1.0f : float(i - tailSplit) / float(tailFade);
  };
  auto tailEnergy = [&](const AudioBuffer& ir) {
    double energy = 0;
    for (size_t i = 0; i < ir.frameCount(); ++i) {
      const float v = ir.channels[0][i] * tailWeight(i);
      energy += double(v) * v;
    }
    return energy;
  };
  auto normalisedTail = [&](const AudioBuffer& ir, double energy) {
    const float norm = float(1.0 / std::sqrt(energy));
    AudioBuffer tail(ir.channelCount(), ir.frameCount(), ir.sampleRateHz);
    for (size_t c = 0; c < ir.channelCount(); ++c)
      for (size_t i = 0; i < ir.frameCount(); ++i) tail.channels[c][i] = ir.channels[c][i] * tailWeight(i) * norm;
    return tail;
  };
  std::optional<AudioBuffer> sharedTail;
  // The last source synthesised in part that has a tail: the shared tail's
  // if the last source has none.
  std::shared_ptr<const Slot::WholeIr> tailFallback;
  // The sources in groups of at most simulationGroupSources whose IRs in
  // the making fit what the memory limit leaves beside the slots
  // (simulationGroupSize): a group's results are all held until its IRs
  // are posted, each group's as soon as it is done. The IRs are the same bits
  // however the sources are grouped (the trace mode is the whole
  // simulation's; kept paths give what a trace gives).
  const TraceMode traceMode = effectiveTraceMode(mSettings.traceMode, order.size());
  const size_t group = std::min(simulationGroupSize(), mSettings.simulationGroupSources);
  // The slots' sources when the simulation began: one added since joins
  // its next group (a one-shot waits for a group, not for a whole round),
  // at most as many as there are slots in one step (a game that adds and
  // releases sources without end does not keep a step from ending).
  std::vector<uint32_t> startGeneration(mSlots.size());
  for (size_t i = 0; i < mSlots.size(); ++i) startGeneration[i] = mSlots[i]->generation.load();
  size_t newcomersLeft = mSlots.size();
  for (size_t g0 = 0; g0 < order.size(); g0 += group) {
    if (takeNewcomers && g0 > 0) {
      std::vector<uint32_t> newcomers;
      for (uint32_t i = 0; i < uint32_t(mSlots.size()) && newcomers.size() < newcomersLeft; ++i) {
        const Slot& slot = *mSlots[i];
        const uint32_t generation = slot.generation.load();
        const bool unsimulated = slot.active.load() ? slot.simulatedGeneration.load() != generation
                                                    : slot.owedFirstIr.load() >= 0;  // released, owed its first IR
        if (generation == startGeneration[i] || !unsimulated ||
            std::find(order.begin() + std::ptrdiff_t(g0), order.end(), i) != order.end())
          continue;
        startGeneration[i] = generation;
        newcomers.push_back(i);
      }
      newcomersLeft -= newcomers.size();
      order.insert(order.begin() + std::ptrdiff_t(g0), newcomers.begin(), newcomers.end());
    }
    const size_t g1 = std::min(order.size(), g0 + group);
    const auto tGroup = g0 == 0 ? t0 : std::chrono::steady_clock::now();
    ++stats.groups;
    std::vector<Job> jobs;
    for (size_t g = g0; g < g1; ++g) {
      const uint32_t i = order[g];
      Slot& slot = *mSlots[i];
      // A released source owed its first IR is simulated as the source it was.
      const int64_t owed = slot.owedFirstIr.load();
      const uint32_t generation = !slot.active.load() && owed >= 0 ? uint32_t(owed) : slot.generation.load();
      Job j{i, generation, mSettings.simulation,
            vecOf(slot.position.load()), {}, std::nullopt};
      slot.simulatedSource = j.source;
      slot.simulatedListener = listener;
      slot.simulatedStep = mSimulations;
      j.settings.includeDirect = DirectMode(slot.direct.load()) == DirectMode::kInImpulseResponse;
      j.controls = slot.controls.load();
      j.settings.directivity = directivityOf(j.controls);
      j.settings.directivity.forward = vecOf(slot.forward.load());
      jobs.push_back(std::move(j));
    }
    if (mTailMixer)
      for (size_t k = 0; k < jobs.size(); ++k)
        if (g0 + k + 1 < order.size()) jobs[k].settings.ambisonicPartialFrames = tailSplit + tailFade;
    uint32_t flushedMode;
    {
      ScopedFlushDenormals ftz;
      flushedMode = currentDenormalMode();
    }
    for (Job& j : jobs) j.denormalMode = flushedMode;
    // Several sources: one per worker, each traced single-threaded (synthesis
    // is single-threaded anyway); one source: all workers trace it. Either way
    // each IR is bit-identical (the tracer's result does not depend on threads).
    if (traceMode == TraceMode::kShared && !jobs.empty()) {
      // One trace from the listener for every source of this group (its
      // paths kept for the next group).
      std::vector<IrRequest> requests;
      for (const Job& j : jobs) {
        IrRequest q;
        q.source = j.source;
        q.directivity = j.settings.directivity;
        q.includeDirect = j.settings.includeDirect;
        q.ambisonicPartialFrames = j.settings.ambisonicPartialFrames;
        q.name = "source " + std::to_string(j.slot);
        requests.push_back(std::move(q));
      }
      if (!mListenerCache) mListenerCache = std::make_unique<ListenerCache>();
      auto r = computeIrs(*tracer, *materials, listener, requests, mSettings.simulation, TraceMode::kShared, *mPool,
                          binauralReceiver, ambisonicReceiver, mListenerCache.get());
      if (!r.isOk()) return r.status();
      stats.pathsReused = (g0 == 0 || stats.pathsReused) && !r->empty() && r->front().traceStats.pathsReused;
      for (size_t k = 0; k < jobs.size(); ++k) jobs[k].result = std::move((*r)[k]);
    } else if (jobs.size() >= 2 && mPool->threadCount() >= 2) {
      mPool->parallelFor(jobs.size(), [&](size_t k, unsigned worker) {
        Job& j = jobs[k];
        j.result = computeIr(*tracer, *materials, j.source, listener, j.settings, *mWorkerPools[worker],
                             binauralReceiver, ambisonicReceiver);
      });
    } else {
      for (Job& j : jobs) j.denormalMode = currentDenormalMode();
      for (Job& j : jobs)
        j.result = computeIr(*tracer, *materials, j.source, listener, j.settings, *mPool, binauralReceiver,
                             ambisonicReceiver);
    }
    for (Job& j : jobs) {
      Slot& slot = *mSlots[j.slot];
      auto& r = *j.result;
      if (!r.isOk()) return Status(r.status().code(), "source " + std::to_string(j.slot) + ": " + r.status().message());
      stats.traceMs += r->timings.traceMs + r->timings.imageSourcesMs;
      stats.synthesisMs += r->timings.synthesisMs;
      const auto tPrepare = std::chrono::steady_clock::now();
      AudioBuffer& ir = r->ir;
      cutIr(ir, maxFrames, mSettings.sampleRateHz);
      const bool partial = j.settings.ambisonicPartialFrames > 0;
      const DirectPath direct = r->direct;
      double lateLevel = 0;  // with a shared tail: the source's level in it
      AudioBuffer own;
      const AudioBuffer* convolved = &ir;
      bool hasTail = false;
      if (mTailMixer) {
        const size_t ownFrames = std::min(ir.frameCount(), tailSplit + tailFade);
        own = AudioBuffer(ir.channelCount(), ownFrames, ir.sampleRateHz);
        for (size_t c = 0; c < ir.channelCount(); ++c)
          for (size_t i = 0; i < ownFrames; ++i) own.channels[c][i] = ir.channels[c][i] * (1.0f - tailWeight(i));
        const double energy = tailEnergy(ir);  // W whole also when in part
        lateLevel = std::sqrt(energy);
        hasTail = energy > 0;
        if (!partial && hasTail) sharedTail = normalisedTail(ir, energy);
        convolved = &own;
      }
      auto prepared = PreparedIr::create(*convolved, mMixer->layout(), mPool.get());
      if (!prepared.isOk()) return prepared.status();
      {
        // Not into a slot another source took meanwhile (addSource() posts
        // silence there, under the same lock); a source released meanwhile
        // rings out through it, and one released before its first IR
        // still gets that IR (what it played waits in its convolution).
        // Nothing is freed under the lock (the game thread's addSource()
        // and removeSource() wait for it): the IR this one replaced, and
        // those the audio thread retired, after it.
        std::shared_ptr<const PreparedIr> replaced;
        {
          std::lock_guard<std::mutex> lock(mIrMutex);
          const bool owed = slot.owedFirstIr.load() == int64_t(j.generation);
          if (slot.generation.load() == j.generation || owed)
            EARSHOT_RETURN_IF_ERROR(mMixer->postIr(j.slot, *prepared, &replaced));
          if (owed) slot.owedFirstIr.store(-1);
          if (mTailMixer && slot.generation.load() == j.generation) {
            slot.tailGain.store(lateLevel);
            slot.tailGainSimulated.store(true, std::memory_order_release);
          }
        }
        replaced.reset();
        mMixer->collectGarbage();
      }
      {
        // Kept for sourceIr(), unless the slot was released or reused
        // meanwhile: the IR, or with a shared tail what sourceIr() makes it
        // from (a slot holds no whole IR then, whichever source was last
        // in its simulation: the last source's whole IR is the engine's one
        // made, until sourceIr() makes another).
        std::shared_ptr<const AudioBuffer> kept;
        std::shared_ptr<const Slot::WholeIr> inputs;
        if (mTailMixer) {
          auto w = std::make_shared<Slot::WholeIr>();
          if (!partial) kept = std::make_shared<const AudioBuffer>(std::move(ir));
          r->ir = AudioBuffer();
          w->result = std::move(*r);
          w->settings = j.settings;
          w->settings.ambisonicPartialFrames = 0;
          w->source = j.source;
          w->listener = listener;
          w->ambisonic = ambisonic;
          w->maxFrames = maxFrames;
          w->denormalMode = j.denormalMode;
          inputs = std::move(w);
          if (partial && hasTail) tailFallback = inputs;
        } else {
          kept = std::make_shared<const AudioBuffer>(std::move(ir));
        }
        if (!mSettings.keepSourceIrs) {
          kept.reset();
          inputs.reset();
        }
        // What these replace is freed after the lock (declared before it).
        std::shared_ptr<const AudioBuffer> oldIr, oldMadeIr;
        std::shared_ptr<const Slot::WholeIr> oldInputs;
        std::lock_guard<std::mutex> lock(mIrMutex);
        if (slot.generation.load() == j.generation) {
          slot.lastIrPosed = tGroup;  // the poses were read just after tGroup
          if (inputs && kept) {
            oldMadeIr = std::move(mMadeIr);
            mMadeIr = std::move(kept);
            mMadeIrFrom = inputs;
          }
          oldIr = std::move(slot.lastIr);
          oldInputs = std::move(slot.lastIrInputs);
          slot.lastIr = std::move(kept);
          slot.lastIrInputs = std::move(inputs);
          slot.lastIrIncludesDirect = j.settings.includeDirect;
          ++slot.irCount;
        }
      }
      // Transmission through occluders: the direct path's band gains without
      // air, by the source's occlusion mode (kOff is applied per block).
      const DirectPath& d = direct;
      const bool transmissionOn = j.controls.transmissionOn;
      BandArrayD transmission = filledBands(1.0);
      if (OcclusionMode(j.controls.occlusion) == OcclusionMode::kVolumetric) {
        transmission = volumetricTransmission(*tracer, *materials, j.source, listener, j.controls.radius,
                                              transmissionOn);
      } else if (transmissionOn || d.surfacesCrossed == 0) {
        transmission = d.transmissionGain;
      } else {
        transmission = filledBands(0.0);
      }
      // (Not into a source that took the slot meanwhile: it is unoccluded
      // until its own first simulation. Checked under the lock addSource()
      // resets the slot under.)
      std::lock_guard<std::mutex> lock(mIrMutex);
      if (slot.generation.load() == j.generation) {
        SourceOcclusion found;
        found.transmission = transmission;
        found.audible = false;
        for (double t : transmission) found.audible = found.audible || t > 0;
        found.simulated = true;
        slot.occlusion.store(found);
      }
      slot.simulatedGeneration.store(j.generation);
      stats.prepareMs += msSince(tPrepare);
      ++stats.sourcesSimulated;
    }
  }
  if (mTailMixer && !sharedTail && tailFallback) {
    // The last source has no tail: the last one that has gives it, made
    // whole again (the same bits as when it was synthesised whole).
    const Slot::WholeIr& w = *tailFallback;
    auto whole = [&] {
      ScopedDenormalMode mode(w.denormalMode);
      return synthesizeIrOf(w.result, w.settings, w.source, w.listener, nullptr, &w.ambisonic);
    }();
    if (!whole.isOk()) return whole.status();
    cutIr(*whole, w.maxFrames, mSettings.sampleRateHz);
    const double energy = tailEnergy(*whole);
    if (energy > 0) sharedTail = normalisedTail(*whole, energy);
  }
  if (sharedTail) {
    auto prepared = PreparedIr::create(*sharedTail, mTailMixer->layout(), mPool.get());
    if (!prepared.isOk()) return prepared.status();
    EARSHOT_RETURN_IF_ERROR(mTailMixer->setIr(0, *prepared));
  }
  stats.totalMs = msSince(t0);
  mStats = stats;
  return Status::ok();
}

void Engine::process(const float* const* inputs, float* left, float* right, size_t frames) {
  float* outputs[2] = {left, right};
  process(inputs, outputs, frames);
}

void Engine::process(const float* const* inputs, float* const* outputs, size_t frames) {
  ScopedFlushDenormals ftz;
  const uint64_t firstFrame = mFramesProcessed.load(std::memory_order_relaxed);
  const bool ambisonicOut = mSettings.output == OutputFormat::kAmbisonic;
  const size_t outChannels = mOutputChannels;
  const size_t n = mSlots.size();
  DirectTarget target;
  mHeardListener = mListener.take();
  const Vec3d listenerSet = vecOf(mHeardListener);
  target.orientation.forward = vecOf(mHeardListener, 3);
  target.orientation.up = vecOf(mHeardListener, 6);
  for (size_t i = 0; i < n; ++i) {
    Slot& slot = *mSlots[i];
    const uint32_t generation = slot.generation.load(std::memory_order_acquire);
    // A per-block source's direct sound plays from its first block (issue
    // 19: unoccluded until its first simulation says otherwise); its
    // reflections join when its first IR lands (the convolution starts from
    // silence then, as a sound starting in the room). A source whose IR holds
    // the direct sound waits for that IR.
    const bool active = inputs && inputs[i] && slot.active.load(std::memory_order_acquire);
    const bool simulated = slot.simulatedGeneration.load(std::memory_order_acquire) == generation;
    const bool perBlock = DirectMode(slot.direct.load(std::memory_order_relaxed)) == DirectMode::kPerBlock;
    const bool live = active && (simulated || perBlock);
    // What the slot did in the last call (the glides restart with it).
    const bool wasLive = slot.live, voiceRan = slot.voicePlayed || slot.drainLeft > 0;
    slot.live = live;
    slot.reflectionsLive = active && simulated;
    // The source's controls, whole (Controls): a live source's own (taken
    // after its slot turned active, and addSource() stores them before);
    // a voice running out its sound in flight keeps its source's if a new
    // source takes the slot meanwhile (addSource() stores the new ones
    // after the new generation, checked here after the take).
    const Controls& controls = slot.controls.take();
    if (live || slot.generation.load(std::memory_order_acquire) == slot.voiceGeneration)
      slot.heardControls = controls;
    // Sound in flight: a direct voice whose source stops playing (its input
    // NULL, or the source released) runs on silence until what it played
    // has arrived (DirectVoice::ringOutFrames), unless a new source takes
    // the slot (its generation changes, the slot active again).
    const bool plays = live && perBlock;
    if (plays) {
      slot.drainLeft = 0;
    } else if (slot.voicePlayed &&
               (generation == slot.voiceGeneration || !slot.active.load(std::memory_order_acquire))) {
      slot.drainLeft = slot.voice.load(std::memory_order_relaxed)->ringOutFrames();
      slot.drainGeneration = generation;
    } else if (slot.drainGeneration != generation && slot.active.load(std::memory_order_acquire)) {
      slot.drainLeft = 0;  // a new source in the slot (a release alone lets it run out)
    }
    slot.voicePlayed = plays;
    // A voice that starts again (or anew) starts where its source is set
    // now, and a source's gain where it is set now.
    if ((plays || slot.drainLeft > 0) && !voiceRan) slot.resetVoiceGlides();
    if (live && !wasLive) slot.resetInputGlides();
    if (live && slot.voiceGeneration != generation) {
      slot.voice.load(std::memory_order_relaxed)->reset();
      slot.resetVoiceGlides();
      slot.resetInputGlides();
      slot.voiceGeneration = generation;
      slot.appliedGain = slot.heardControls.gain;
      slot.appliedReflectionsGain = slot.heardControls.reflectionsGain;
      slot.appliedTailGain = slot.lateLevel();
      slot.startsAnew = true;
    }
    // Before its first IR, a per-block source's input goes into its
    // convolution's history (and into the shared tail at its estimated late
    // level, Slot::lateLevel), so that its first IR, fading in, brings the
    // reflections of what it played while it waited: a one-shot is not heard
    // dry. First the slot's convolution starts anew, at once where the last
    // source's sound has rung out (nothing of it would be heard), else once
    // its IR has faded out (addSource() posted silence), so that nothing of
    // the last source's sound goes through this source's IR, nor this
    // source's through the last one's.
    const bool early = active && perBlock && !simulated;
    if (early && slot.startsAnew) {
      const uint64_t fed = slot.fedUntilFrame.load(std::memory_order_relaxed);
      const bool rungOut = fed == 0 || firstFrame >= fed + ringOutFrames();
      if (rungOut || !mMixer->holdsIr(i)) {
        mMixer->resetSource(i);
        slot.startsAnew = false;
      }
    }
    slot.feedsEarly = early && !slot.startsAnew;
  }
  // The glides (PoseGlide): over at most kMaxGlideSeconds, never faster
  // than half the speed of sound (the direct voice's jump).
  const uint64_t maxGlide = uint64_t(kMaxGlideSeconds * mSettings.sampleRateHz);
  const double maxGlideSpeed = 0.5 * mSettings.simulation.speedOfSound / mSettings.sampleRateHz;
  constexpr double kAnySpeed = std::numeric_limits<double>::infinity();  // gains and facing: no teleport
  // Chunks bound the gain scratch buffers whatever the host block size.
  for (size_t off = 0; off < frames; off += kProcessChunk) {
    const size_t m = std::min(kProcessChunk, frames - off);
    // The positions the direct sound follows: where the game set them,
    // its changes spread over the interval it makes them at.
    target.listener = mSettings.glideGameUpdates ? mListenerGlide.next(listenerSet, m, maxGlide, maxGlideSpeed) : listenerSet;
    bool tailUsed = false;
    if (mTailMixer) std::fill(mTailInput.begin(), mTailInput.begin() + std::ptrdiff_t(m), 0.0f);
    // The gains' ramp across the chunk, once for every source (a division
    // per sample and source was a tenth of this function).
    float* ramp = mRamp.data();
    for (size_t k = 0; k < m; ++k) ramp[k] = float(k + 1) / float(m);
    for (size_t i = 0; i < n; ++i) {
      Slot& slot = *mSlots[i];
      mInputs[i] = nullptr;
      if (!slot.live) continue;
      // The source gain, ramped per chunk, on the reflections' input (the
      // direct voice applies it itself).
      double gainSet = slot.heardControls.gain;
      double reflectionsSet = slot.heardControls.reflectionsGain;
      if (mSettings.glideGameUpdates) {
        gainSet = slot.gainGlide.next(gainSet, m, maxGlide, kAnySpeed);
        reflectionsSet = slot.reflectionsGlide.next(reflectionsSet, m, maxGlide, kAnySpeed);
      }
      const float from = float(slot.appliedGain), to = float(gainSet);
      const float* in = inputs[i] + off;
      float* g = slot.scaled.data();
      // Containment: a NaN, Inf or absurd sample mutes this source for the
      // chunk before it reaches any state (no poisoned convolution).
      bool bad = false;
      for (size_t k = 0; k < m; ++k) bad |= !(std::fabs(in[k]) <= kMaxInputSample);
      slot.mutedChunk = bad;
      if (bad) {
        std::fill(g, g + m, 0.0f);
        mMutedSourceChunks.fetch_add(1, std::memory_order_relaxed);
      } else {
        // The source gain and the reflections' gain, both ramped.
        const float rFrom = from * float(slot.appliedReflectionsGain);
        const float rTo = to * float(reflectionsSet);
        const float rStep = rTo - rFrom;
        for (size_t k = 0; k < m; ++k) g[k] = in[k] * (rFrom + rStep * ramp[k]);
        // For the direct voice (per block only: an IR's own direct sound
        // needs none).
        if (DirectMode(slot.direct.load(std::memory_order_relaxed)) == DirectMode::kPerBlock)
          std::copy(in, in + m, slot.input.data());
      }
      slot.appliedReflectionsGain = reflectionsSet;
      slot.appliedGain = to;
      const bool feeds = slot.reflectionsLive || slot.feedsEarly;
      mInputs[i] = feeds ? g : nullptr;
      if (feeds) {
        slot.fedUntilFrame.store(firstFrame + off + m, std::memory_order_relaxed);
        slot.fedGeneration.store(slot.voiceGeneration, std::memory_order_relaxed);
      }
      if (mTailMixer && feeds) {
        // The shared tail's input: this source at its late level, ramped.
        const float t0 = float(slot.appliedTailGain), t1 = float(slot.lateLevel());
        float* tail = mTailInput.data();
        const float tStep = t1 - t0;
        for (size_t k = 0; k < m; ++k) tail[k] += g[k] * (t0 + tStep * ramp[k]);
        slot.appliedTailGain = t1;
        tailUsed = true;
      }
    }
    float* outs[kMaxAmbisonicChannels];
    for (size_t c = 0; c < outChannels; ++c) outs[c] = outputs[c] + off;
    if (mSettings.ambisonicOrder > 0) {
      processAmbisonicBus(target.orientation, outs, m, tailUsed);
    } else {
      mMixer->process(mInputs.data(), outs, m);
    }
    for (size_t i = 0; i < n; ++i) {
      Slot& slot = *mSlots[i];
      const bool draining = !slot.live && slot.drainLeft > 0;
      if (!draining &&
          (!slot.live || DirectMode(slot.direct.load(std::memory_order_relaxed)) != DirectMode::kPerBlock))
        continue;
      // A released source's sound in flight stays where it was: a new
      // source's pose in its slot (addSource() sets it after the new
      // generation, so a pose taken before the generation is checked is
      // the new source's only if the check sees the new generation).
      const std::array<double, 3>& read = slot.position.take();
      const std::array<double, 3>& facing = slot.forward.take();
      const SourceOcclusion& occlusion = slot.occlusion.take();
      if (slot.live || slot.generation.load(std::memory_order_acquire) == slot.voiceGeneration) {
        slot.heardPosition = vecOf(read);
        slot.heardForward = vecOf(facing);
        slot.heardOcclusion = occlusion;
      }
      target.source = slot.heardPosition;
      if (mSettings.glideGameUpdates) target.source = slot.glide.next(target.source, m, maxGlide, maxGlideSpeed);
      // The direct gain and the distance curve, relative to the voice's own
      // physical 1/r (ramped by the voice across the chunk).
      const Controls& controls = slot.heardControls;
      DistanceCurve curve;
      curve.model = DistanceModel(controls.distanceModel);
      double shape = 1.0;
      if (curve.model != DistanceModel::kPhysical) {
        curve.minDistance = controls.distanceMin;
        curve.maxDistance = controls.distanceMax;
        curve.rolloff = controls.rolloff;
        const double r = length(target.source - target.listener);
        // (kTable: the controls' own points, no allocation.)
        const double g = curve.model == DistanceModel::kTable
                             ? tableGain(controls.table, size_t(std::clamp(controls.tableCount, 0, kMaxDistanceTablePoints)), r)
                             : distanceGain(curve, r);
        shape = g * std::max(r, DirectVoiceSettings{}.minDistanceMeters);
      }
      double directSet = controls.directGain;
      if (mSettings.glideGameUpdates) directSet = slot.directGlide.next(directSet, m, maxGlide, kAnySpeed);
      target.gain = slot.appliedGain * directSet * shape;
      if (OcclusionMode(controls.occlusion) == OcclusionMode::kOff) {
        target.transmission = filledBands(1.0);
        target.audible = true;
      } else {
        target.transmission = slot.heardOcclusion.transmission;
        target.audible = slot.heardOcclusion.audible;
      }
      // The way the source faces, glided along the chord and brought back
      // to unit length (a half turn within one update, whose chord passes
      // the centre, flips halfway); followed whether or not it is
      // directional, so a pattern switched on starts where it faces.
      Vec3d f = slot.heardForward;
      if (mSettings.glideGameUpdates) {
        const Vec3d glided = slot.facingGlide.next(f, m, maxGlide, kAnySpeed);
        if (length(glided) > 1e-6) f = normalize(glided);
      }
      // Directivity toward the listener, per band: sqrt(D_b) = g_b / sqrt(<g_b^2>),
      // through the voice's band shelves (as occlusion).
      const bool perBand = controls.directivityPerBand;
      if (perBand || controls.directivityAlpha > 0.0) {
        const Vec3d toListener = target.listener - target.source;
        const double r = length(toListener);
        const double c = r > 1e-9 ? std::clamp(dot(f, toListener) / r, -1.0, 1.0) : 1.0;
        const double k = controls.directivitySharpness;
        // One pattern for every band unless the table differs per band.
        const int patterns = perBand ? kNumBands : 1;
        double g[kNumBands];
        for (int b = 0; b < patterns; ++b) {
          const double a = controls.directivityBandAlpha[b];
          g[b] = a == 0.0 ? 1.0 : std::pow(std::fabs((1.0 - a) + a * c), k) / std::sqrt(controls.directivityMeanSquare[b]);
        }
        for (int b = 0; b < kNumBands; ++b) target.transmission[b] *= g[perBand ? b : 0];
        target.audible = target.audible && [&] {
          for (double t : target.transmission)
            if (t > 0) return true;
          return false;
        }();
      }
      // A muted chunk feeds the voice the zeros the mixer got; one running
      // out, silence.
      const float* voiceIn = draining ? nullptr : slot.mutedChunk ? slot.scaled.data() : slot.input.data();
      if (draining) slot.drainLeft -= std::min(slot.drainLeft, m);
      DirectVoice* voice = slot.voice.load(std::memory_order_relaxed);
      if (ambisonicOut)
        voice->processAmbisonic(voiceIn, outs, mSettings.ambisonicOrder, m, target);
      else
        voice->process(voiceIn, outs[0], outs[1], m, target);
      slot.voiceUntilFrame.store(firstFrame + off + m + voice->ringOutFrames(), std::memory_order_relaxed);
    }
    // Containment of an overflow anywhere in the state: never a non-finite
    // sample out, and no state that stays poisoned.
    bool finite = true;
    for (size_t c = 0; c < outChannels; ++c)
      for (size_t k = 0; k < m; ++k) finite &= std::isfinite(outs[c][k]);
    if (!finite) {
      for (size_t c = 0; c < outChannels; ++c) std::fill(outs[c], outs[c] + m, 0.0f);
      mMixer->clearState();
      if (ConvolutionMixer* d = mDecoderMixerLive.load(std::memory_order_acquire)) d->clearState();
      if (mTailMixer) mTailMixer->clearState();
      for (auto& slot : mSlots)
        if (DirectVoice* v = slot->voice.load(std::memory_order_acquire)) v->reset();
      mClearedOutputChunks.fetch_add(1, std::memory_order_relaxed);
    }
  }
  // (One writer: a plain store, no read-modify-write.)
  mFramesProcessed.store(firstFrame + frames, std::memory_order_relaxed);
}

void Engine::processAmbisonicBus(const ListenerOrientation& head, float* const* ears, size_t m, bool tailUsed) {
  constexpr size_t C = kMaxAmbisonicChannels;
  const int order = mSettings.ambisonicOrder;
  const size_t channels = size_t(ambisonicChannels(order));
  float* bus[C] = {};
  const float* rotatedIn[C] = {};
  float* rotated[C] = {};
  for (size_t c = 0; c < channels; ++c) {
    bus[c] = mBus.data() + c * kProcessChunk;
    rotated[c] = mRotated.data() + c * kProcessChunk;
    rotatedIn[c] = rotated[c];
  }
  mMixer->process(mInputs.data(), bus, m);
  if (mTailMixer) {
    // The shared tail, convolved once for every source (it runs on silence
    // too, so that its state stays in step).
    float* tailOut[C] = {};
    for (size_t c = 0; c < channels; ++c) tailOut[c] = mTailBus.data() + c * kProcessChunk;
    const float* tailIn[1] = {tailUsed ? mTailInput.data() : nullptr};
    mTailMixer->process(tailIn, tailOut, m);
    for (size_t c = 0; c < channels; ++c)
      for (size_t k = 0; k < m; ++k) bus[c][k] += tailOut[c][k];
  }
  // The world-frame bus into the head's frame: R = head * world^T, its SH
  // rotation interpolated linearly across the chunk from the last one.
  const Rotation3 r =
      relativeRotation(worldToAmbisonicFrame(head.forward, head.up), worldAmbisonicFrame().worldToFrame);
  float now[C * C];
  mRotation->compute(r, order, now);
  if (!mHaveRotation) std::copy(now, now + C * C, mLastRotation.begin());
  mHaveRotation = true;
  const float* before = mLastRotation.data();
  for (int n = 0; n <= order; ++n) {
    const size_t lo = size_t(n * n), hi = size_t((n + 1) * (n + 1));
    for (size_t i = lo; i < hi; ++i) {
      float* out = rotated[i];
      std::fill(out, out + m, 0.0f);
      for (size_t j = lo; j < hi; ++j) {
        const float a = before[i * C + j], b = now[i * C + j];
        const float* x = bus[j];
        if (a == 0.0f && b == 0.0f) continue;
        const float step = (b - a) / float(m);
        for (size_t k = 0; k < m; ++k) out[k] += (a + step * float(k + 1)) * x[k];
      }
    }
  }
  std::copy(now, now + C * C, mLastRotation.begin());
  if (mSettings.output == OutputFormat::kAmbisonic) {
    for (size_t c = 0; c < channels; ++c) std::copy(rotated[c], rotated[c] + m, ears[c]);
    return;
  }
  if (ConvolutionMixer* decoder = mDecoderMixerLive.load(std::memory_order_acquire)) {
    decoder->process(rotatedIn, ears, m);
  } else {
    std::fill(ears[0], ears[0] + m, 0.0f);
    std::fill(ears[1], ears[1] + m, 0.0f);
  }
}

ContainmentStats Engine::containment() const {
  ContainmentStats s;
  s.mutedSourceChunks = mMutedSourceChunks.load(std::memory_order_relaxed);
  s.clearedOutputChunks = mClearedOutputChunks.load(std::memory_order_relaxed);
  return s;
}

}  // namespace earshot::runtime
