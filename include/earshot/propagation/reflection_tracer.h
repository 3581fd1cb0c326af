#pragma once
/** @file Stochastic ray tracing of reflections into an EnergyHistogram.
 *
 *  Rays leave the source along a Fibonacci sphere (evenly spread; rotated at
 *  random per seed), each carrying 4 pi / rays of energy per band (so that a
 *  direct sound at r has energy 1/r^2). At every hit the ray loses the
 *  absorbed fraction; it then continues specularly, diffusely (Lambert) or
 *  through the surface, chosen at random and reweighted so every band's
 *  expected energy is exact. Detection partitions all paths by their last
 *  event, so nothing is counted twice:
 *  - paths whose last reflection is diffuse: next-event estimation ("diffuse
 *    rain", Schroeder 1970 / Heinz 1993): each hit sends the scattered part of
 *    its reflected energy to the listener through a shadow ray, weighted by
 *    the Lambert radiance cos(theta) / (pi d^2). Unbiased, no receiver size.
 *  - paths whose last event is specular (or a transmission after a
 *    reflection): the segment's chord through a receiver sphere of radius R,
 *    energy x chord / (4/3 pi R^3) (unbiased for a field uniform over R).
 *  The first segment (source to first hit) is the direct sound's business
 *  and never detected here; purely specular paths whose plane sequence the
 *  image-source method rendered (`excludedSpecular`) are not detected either.
 *
 *  For tail completion the tracer also records, per bin and band, the energy
 *  of rays in flight ("alive") and of rays stopped by the bounce limit
 *  ("cut"), and over the later half of the bounces the energy-weighted loss
 *  per reflection and mean free path (tail_completion.h). Rays whose energy
 *  has fallen 60 dB survive Russian roulette with probability 1/10 and
 *  carry 10x their energy, which keeps every estimate unbiased.
 *
 *  Determinism: each ray draws from its own PCG32 stream (seed, ray index)
 *  and detections are summed in 2^-50 fixed point (integer addition is
 *  associative), so the histogram is bit-identical for any thread count. */
#include <cstdint>
#include <memory>
#include <vector>

#include "earshot/core/bands.h"
#include "earshot/core/status.h"
#include "earshot/core/vec3.h"
#include "earshot/materials/material.h"
#include "earshot/propagation/air_absorption.h"
#include "earshot/propagation/direct_path.h"
#include "earshot/propagation/energy_histogram.h"
#include "earshot/propagation/image_sources.h"

namespace earshot {

class RayTracer;
class ThreadPool;

/** ReflectionSettings::tailProbes: every ray carries on. */
constexpr uint32_t kEveryRay = 0xFFFFFFFFu;

struct ReflectionSettings {
  Directivity directivity;            ///< the source's: each ray's energy times D(its emission direction)
  uint32_t rays = 16384;              ///< [1, 1e8]
  uint32_t bounces = 12;              ///< reflections per ray, [0, 100000]
  uint64_t seed = 1;
  double speedOfSound = 343.0;        ///< m/s
  AirConditions air;
  double binSeconds = 0.001;          ///< histogram resolution, [1e-5, 0.1] s
  double maxTimeSeconds = 4.0;        ///< histogram length; later arrivals are counted in stats only
  /** Sphere for specular detection; 0 = automatic, sized from the ray
   *  density (rays, bounces and the listener's surroundings; 0.5 - 2 m,
   *  under 90 % of the distance to the nearest surface). [0, 1000] m */
  double receiverRadiusMeters = 0.0;
  double minDistanceMeters = 0.1;     ///< clamp of 1/d^2 in next-event estimation
  /** Specular paths rendered elsewhere (image sources): not detected here. Not owned. */
  const PlaneSequenceSet* excludedSpecular = nullptr;
  uint32_t excludedMaxOrder = 0;      ///< orders 1..this are checked against excludedSpecular
  bool russianRoulette = true;        ///< stop rays 60 dB down (unbiased)
  /** Tail probes: about this many rays (every rays/tailProbes-th of each
   *  direction set) carry on past the bounce limit until they are 60 dB
   *  down (where roulette would start; not without roulette; from 20 dB
   *  down, every further 10 dB, half of them go on with twice the energy),
   *  escape, reach
   *  the histogram's end or make kMaxProbeBounces more reflections, detected
   *  by the receiver sphere alone (TailData::probeDetected; no next-event
   *  estimation, so no shadow rays); tail completion scales what they
   *  deposit to all cut rays (beyond their ends, the population's rate). A
   *  specular room decays as a mixture of rates that no one rate
   *  extrapolates. 0: none (the whole tail at the population's rate).
   *  kEveryRay (the default) or anything above `rays`: every ray. */
  uint32_t tailProbes = kEveryRay;
  /** > 0: stop tracing once the histogram has converged: the rays go in 16
   *  rounds, each spread over the whole sphere, and the trace stops after
   *  the round (the 4th at the earliest) where the estimated standard error
   *  of every 10 ms window within 20 dB of its band's peak is below this
   *  many dB. Energies are scaled to the rays traced. 0: trace every ray.
   *  [0, 20] */
  double convergenceDb = 0.0;
  /** Flutter cones: where a pair of parallel planes both reflect
   *  specularly (a round trip keeps >= 25 % in some band; each plane >= 2 %
   *  of the area, >= 0.5 m apart), 1/8 of the rays leave on nested
   *  Fibonacci caps (0.15 and 0.03 rad) around +-the normal of the pair that
   *  decays slowest per metre (and of a second one within 1.25x of its
   *  rate), the rest on the sphere, each ray carrying 1 / (the density of
   *  all the sets at its direction): unbiased, and the few long-lived rays
   *  of a flutter echo, which carry a specular room's late decay, are
   *  sampled densely. Not with convergenceDb or fewer than 1024 rays. */
  bool flutterCones = true;
  /** A shared trace's next-event estimation (traceReflectionsShared): a
   *  reflection sends a source its shadow ray with probability
   *  min(1, this x R^2 cos(theta) / d^2) (R: the source's detection sphere;
   *  d, theta: the distance and angle from the reflecting surface to it) and
   *  the detection counts 1/p times: unbiased (Russian roulette on shadow
   *  rays). With 1, a reflection farther from a source than its sphere's
   *  radius detects about as often, and with about the weight, as a ray
   *  through the sphere does. The default 2: in a furnished room with 32
   *  sources 11x fewer shadow rays (5.8 M -> 0.52 M), the trace 2.4x faster;
   *  the window energies' standard error at most 1.16x (SharedTrace.ShadowRoulette*). The decision for a source depends on it alone
   *  and on a random number per reflection: a source's result is the same
   *  with or without others in the trace. 0: every reflection sends every
   *  facing source a shadow ray. Not used by traceReflections, nor for a
   *  source in a room convex around it (no shadow rays). [0, 1e6] */
  double sharedShadowRoulette = 2.0;
};

/** Reflections a tail probe makes past the bounce limit, at most. */
constexpr uint32_t kMaxProbeBounces = 2000;

/** A ray stopped by the bounce limit: what it would have carried on with. */
struct CutRay {
  float pathMeters = 0;               ///< path length at the stop
  BandArray energy{};                 ///< energy after the last reflection (no air)
};

/** What tail completion needs from a trace's rays (energies in the
 *  histogram's units): the same for every detector of one trace. */
struct RayTail {
  std::vector<BandArrayD> alive;      ///< per bin: energy of rays in flight (air of the bin's centre: each has travelled c t)
  std::vector<CutRay> cutRays;        ///< in ray order
  /** Free paths of the later half of the bounces, in log-spaced length bins
   *  (freePathBinCenter): the energy e arriving at a reflection after a free
   *  path in that bin, and e times the fraction the reflection keeps. Escapes
   *  count in `pathEnergy` of the last bin and keep nothing. */
  std::vector<BandArrayD> pathEnergy, pathRetained;
  /** Tail probes (ReflectionSettings::tailProbes): their energy in flight
   *  after their cut, per bin (air applied), and the energy they were cut
   *  with (air applied). Empty / zero without probes. */
  std::vector<BandArrayD> probeAlive;
  BandArrayD probeCutEnergy{};
  /** Probes stopped 60 dB down, at the histogram's end or at
   *  kMaxProbeBounces: what they would have carried on with (energy without
   *  air, as CutRay). */
  std::vector<CutRay> probeEnds;
};

/** What tail completion needs from a trace, for one detector. */
struct TailData {
  /** The rays' part, shared by the detectors of one trace and by the kept
   *  paths (SharedTracePaths) that gave it: a shared trace's sources hold
   *  one, not a copy each. Read it through rays(); null: no rays. */
  std::shared_ptr<const RayTail> shared;
  /** What the tail probes past their cut deposit in the receiver sphere, per
   *  bin (every segment by the sphere: specular and diffuse paths alike).
   *  Empty when the sphere is under 0.5 m (a surface next to the listener):
   *  too few hits; tail completion then uses kappa x probeAlive, and at most
   *  4096 rays are probes (enough for that smooth shape). */
  std::vector<BandArrayD> probeDetected;
  /** `shared`, or an empty RayTail where it is null. */
  const RayTail& rays() const;
};

/** Free-path bins: log-spaced, 64 per octave from 1/1024 m up (~10 km at
 *  the last), read off a float's exponent and top mantissa bits. */
constexpr size_t kFreePathBins = 24 * 64;
size_t freePathBin(double lengthMeters);
double freePathBinCenter(size_t bin);

struct ReflectionStats {
  uint64_t raysTraced = 0;            ///< fewer than asked when the trace converged early
  uint64_t raysEscaped = 0;           ///< rays that left the geometry
  uint64_t segmentsTraced = 0;        ///< intersection queries
  uint64_t shadowRays = 0;            ///< occlusion queries
  uint64_t shadowRaysSkipped = 0;     ///< not needed: a convex room around the listener (RayTracer::convexAround)
  uint64_t shadowRaysRouletted = 0;   ///< not sent: a shared trace's roulette (ReflectionSettings::sharedShadowRoulette)
  /** Energy deposits in this receiver's sums: sphere crossings and visible
   *  next-event estimates, tail probes' included (what detection costs,
   *  beside the rays; a shared trace's sources each count their own). */
  uint64_t detections = 0;
  uint64_t probeDetections = 0;       ///< of detections: tail probes past their cut
  BandArrayD energyEscaped{};         ///< fraction of emitted energy that escaped, per band
  BandArrayD energyLate{};            ///< detected energy arriving after maxTimeSeconds
  std::vector<BandArrayD> detectedPerOrder;  ///< detected energy by reflection order (index 0 unused)
  uint64_t raysCut = 0;               ///< rays stopped by the bounce limit
  uint64_t raysRouletted = 0;         ///< rays ended by Russian roulette
  uint64_t specularExcluded = 0;      ///< detections left to the image sources
  uint64_t tailProbeSegments = 0;     ///< of segmentsTraced: tail probes past the bounce limit
  /** With ReflectionSettings::convergenceDb: the histogram's estimated
   *  standard error when the trace stopped (dB; see there). 0 otherwise. */
  double estimatedErrorDb = 0.0;
  uint32_t flutterAxes = 0;           ///< ReflectionSettings::flutterCones: axes found
  uint32_t coneRays = 0;              ///< rays that left on the flutter cones
  double receiverRadiusMeters = 0.0;
  double traceMs = 0.0;               ///< wall time of the tracing
  /** A shared trace given SharedTracePaths that held the listener's paths:
   *  no ray was traced, the sources detected the kept paths (the counts
   *  above are the kept trace's). */
  bool pathsReused = false;
};

struct ReflectionResult {
  EnergyHistogram histogram;
  ReflectionStats stats;
  TailData tail;
};

/** Validates settings (message names the field). */
Status validate(const ReflectionSettings& settings);

/** About what a trace with these settings holds while it runs, in bytes
 *  (an estimate from above): per ray, its slots for where it was cut and
 *  where a tail probe ended, and those ends in each detector's TailData;
 *  per histogram bin (maxTimeSeconds / binSeconds), each thread's and the
 *  merged sums of every detector and the energy in flight, and each
 *  result's histogram and tail curves. A trace from a source has one
 *  detector; a shared trace one per source. Kept paths (SharedTracePaths)
 *  come on top, within their budget and what the limit leaves. traceReflections and traceReflectionsShared
 *  refuse (kOutOfRange, before allocating) a trace over
 *  defaultInputLimits().maxMemoryBytes (earshot/io/input_file.h: 1 GiB
 *  unless the CLI's --max-memory or setDefaultInputLimits says otherwise):
 *  a file's or an argument's ray count or histogram length cannot make
 *  the engine exhaust the host. */
double traceMemoryBytes(const ReflectionSettings& settings, size_t detectors, unsigned threads);

/** Traces reflections from `source` to `listener`. `pool` supplies the
 *  threads (the result does not depend on how many). */
Result<ReflectionResult> traceReflections(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& source,
                                          const Vec3d& listener, const ReflectionSettings& settings, ThreadPool& pool);

/** A source of traceReflectionsShared. */
struct SharedTraceSource {
  Vec3d position;
  Directivity directivity;            ///< weighs what reaches the source's sphere, by the direction the sound left it in
  /** Its image-source paths (sequences from the source, as
   *  findImageSources gives them): not detected. Not owned. */
  const PlaneSequenceSet* excludedSpecular = nullptr;
  uint32_t excludedMaxOrder = 0;
  double receiverRadiusMeters = 0.0;  ///< its detection sphere; 0: automatic, sized around the source
};

/** Sources in one shared trace, at most. */
constexpr size_t kMaxSharedTraceSources = 4096;

/** What SharedTracePaths keeps by default, at most (the balanced preset's
 *  16384 rays, every one a tail probe, need 66 MB in the furnished room of
 *  24k triangles and 60 MB in the shoebox: `earshot bench trace
 *  --shared-sources`, its kept_mb). */
constexpr size_t kSharedTracePathsBudgetBytes = size_t(256) << 20;

/** The paths of a shared trace's rays from the listener, kept for the next
 *  shared trace from the same place. The rays' paths depend on the scene
 *  (the tracer, RayTracer::id(), and the materials' factors), the
 *  listener's position and the settings that shape them (rays, bounces,
 *  seed, speed of sound, histogram bins and length, air, tail probes,
 *  roulettes, flutter cones), not on the sources: a trace that finds all
 *  of these the same detects its sources in the kept paths instead of
 *  tracing (each source's result the same bits as a trace's), and a trace
 *  that does not replaces them. A listener that stays in place (a seated
 *  player turning the head, an offline render's fixed listener) then costs
 *  each simulation only its sources' detections and shadow rays. At most
 *  `budgetBytes` (default kSharedTracePathsBudgetBytes), and at most what
 *  the memory limit leaves beside the trace's state (traceMemoryBytes), are
 *  kept; a trace whose paths need more keeps none. Not thread-safe: one trace at a time. */
class SharedTracePaths {
 public:
  explicit SharedTracePaths(size_t budgetBytes);
  SharedTracePaths();
  ~SharedTracePaths();
  SharedTracePaths(const SharedTracePaths&) = delete;
  SharedTracePaths& operator=(const SharedTracePaths&) = delete;
  /** Bytes held (0: none kept). */
  size_t bytes() const;
  /** Changes whenever the kept paths are replaced or forgotten: what was
   *  made from one set of them (ListenerCache's tail rates) is known to be
   *  of it. */
  uint64_t generation() const;
  /** Forgets the paths. */
  void clear();

  struct Impl;  // reflection_tracer.cpp
  Impl& impl() { return *mImpl; }  ///< the tracer's

 private:
  std::unique_ptr<Impl> mImpl;
};


/** One trace for many sources (issue 16): rays leave the listener, and each
 *  source detects them as traceReflections' listener does (next-event
 *  estimation to it, a sphere around it), by reciprocity: for omni sources
 *  the energy a path carries from listener to source is what it carries
 *  from source to listener. Each detection arrives at the listener from its
 *  ray's first direction (exact, whatever the scattering). Sources cost a
 *  sphere test per segment and a shadow ray per reflection each, instead of
 *  a trace each. Per source, the result is traceReflections(source,
 *  listener)'s in expectation, with these differences: the tail data (energy
 *  in flight, cut rays, free paths) are the listener's omni emission's,
 *  shared (a directional source's late level is its pattern's at the late
 *  field's departure directions, through its detections); convergenceDb
 *  is not used (every ray is traced); every tail probe is kept
 *  (traceReflections keeps 4096 when its sphere is under 0.5 m), so that a
 *  source's result does not depend on the others; settings.directivity and
 *  settings.excludedSpecular are ignored (per source here). Results in
 *  `sources` order, bit-identical for any thread count. `paths` (optional):
 *  the listener's paths, reused when they were kept for this scene,
 *  listener and settings, else traced and kept (SharedTracePaths). */
Result<std::vector<ReflectionResult>> traceReflectionsShared(const RayTracer& tracer, const MaterialTable& materials,
                                                             const Vec3d& listener,
                                                             const std::vector<SharedTraceSource>& sources,
                                                             const ReflectionSettings& settings, ThreadPool& pool,
                                                             SharedTracePaths* paths = nullptr);

/** Direction i of n on a Fibonacci sphere (unit vector). */
Vec3d fibonacciDirection(uint32_t i, uint32_t n);

}  // namespace earshot
