#pragma once
/** @file Early specular reflections by the image-source method (Allen &
 *  Berkley 1979; Borish 1984 for arbitrary polyhedra), in any triangle
 *  geometry: candidate plane sequences are mirrored into image sources and
 *  every path is validated by ray casts (each reflection point must lie on a
 *  triangle of its plane and every leg must be unobstructed).
 *
 *  Candidates: with at most `maxPlanesExhaustive` planes, every sequence of
 *  planes up to the order (no plane twice in a row), which is exact; with more
 *  planes, the plane sequences of specular rays shot from the source (found
 *  paths are exact; a path no candidate ray follows is missed, and is then
 *  left to the stochastic tracer, which excludes only the paths found here). */
#include <array>
#include <cstdint>
#include <unordered_set>
#include <vector>

#include "earshot/core/bands.h"
#include "earshot/core/status.h"
#include "earshot/core/vec3.h"
#include "earshot/materials/material.h"
#include "earshot/propagation/air_absorption.h"

namespace earshot {

class RayTracer;
class ThreadPool;

constexpr uint32_t kMaxImageSourceOrder = 4;

/** Plane ids of a specular path, in order from the source; unused entries are ~0u. */
using PlaneSequence = std::array<uint32_t, kMaxImageSourceOrder>;

struct PlaneSequenceHash {
  size_t operator()(const PlaneSequence& s) const {
    uint64_t h = 1469598103934665603ULL;
    for (uint32_t v : s) h = (h ^ v) * 1099511628211ULL;
    return size_t(h);
  }
};
using PlaneSequenceSet = std::unordered_set<PlaneSequence, PlaneSequenceHash>;

struct SpecularPath {
  uint32_t order = 0;
  PlaneSequence planes{};
  double lengthMeters = 0;          ///< source -> reflections -> listener
  double delaySeconds = 0;          ///< length / c
  double spreadingGain = 0;         ///< 1 / length
  BandArrayD bandGain{};            ///< pressure: prod sqrt((1 - alpha)(1 - scattering)) x air
  Vec3d directionFromListener;      ///< unit, toward the last reflection point (world frame)
  Vec3d imageSource;                ///< position of the image source
};

struct ImageSourceSettings {
  uint32_t maxOrder = 3;                ///< [0, kMaxImageSourceOrder]
  double speedOfSound = 343.0;
  AirConditions air;
  size_t maxPlanesExhaustive = 64;      ///< above this, candidates come from rays
  uint32_t candidateRays = 16384;       ///< specular rays shot for candidates (many planes only)
  uint64_t seed = 1;
  /** true: reflection factor sqrt((1 - alpha)(1 - s)), the specular part
   *  (the stochastic tracer renders the scattered rest). false: sqrt(1 - alpha). */
  bool specularPartOnly = true;
  /** Candidates found beforehand (imageSourceCandidates; sorted, each in
   *  order from the source), used instead of rays from the source when the
   *  planes are too many for the exhaustive search: a trace shared by many
   *  sources finds them once, from the listener. Not owned; null: rays from
   *  the source. */
  const std::vector<PlaneSequence>* candidates = nullptr;
};

struct ImageSourceResult {
  std::vector<SpecularPath> paths;       ///< sorted by delay
  PlaneSequenceSet found;                ///< sequences of all valid paths
  uint64_t candidates = 0;               ///< sequences examined
  bool exhaustive = true;                ///< all sequences were examined
  double milliseconds = 0;
};

Status validate(const ImageSourceSettings& settings);

/** Candidate plane sequences up to settings.maxOrder: those of
 *  settings.candidateRays specular rays from `from` (a Fibonacci sphere spun
 *  by settings.seed), sorted. `fromListener`: `from` is the listener, and
 *  each sequence is reversed (in order from the source, as findImageSources
 *  takes them). Specular paths are reversible: a path source -> planes ->
 *  listener is a candidate when some ray from either end follows it.
 *  `pool` (optional; not from inside its own parallelFor) shares the rays
 *  between threads: the same candidates whatever the thread count. */
std::vector<PlaneSequence> imageSourceCandidates(const RayTracer& tracer, const Vec3d& from,
                                                 const ImageSourceSettings& settings, bool fromListener,
                                                 ThreadPool* pool = nullptr);

/** The image-source paths from `source` to `listener`. `pool` (optional;
 *  not from inside its own parallelFor): candidates from rays are found on
 *  its threads, with the same result whatever the thread count. */
Result<ImageSourceResult> findImageSources(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& source,
                                           const Vec3d& listener, const ImageSourceSettings& settings,
                                           ThreadPool* pool = nullptr);

}  // namespace earshot
