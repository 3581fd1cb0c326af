// Image sources with ray-traced visibility: see image_sources.h.
#include "earshot/propagation/image_sources.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "earshot/core/random.h"
#include "earshot/core/thread_pool.h"
#include "earshot/propagation/reflection_tracer.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot {

namespace {

constexpr uint32_t kUnused = 0xFFFFFFFFu;

struct Validator {
  const RayTracer& tracer;
  const MaterialTable& materials;
  const Vec3d source, listener;
  const ImageSourceSettings& settings;
  BandArrayD airDbPerM;

  // Leg from `from` toward `to`: the first surface hit must be plane `plane`
  // at the point where the segment crosses it. Returns the crossing and its
  // triangle, or false.
  // `fromSurface`: the leg starts on a wall (skip it with tNear = eps).
  bool legHitsPlane(const Vec3d& from, bool fromSurface, const Vec3d& to, uint32_t plane, Vec3d& point,
                    uint32_t& triangle) const {
    const Plane& p = tracer.planes().planes[plane];
    const double d0 = p.distance(from), d1 = p.distance(to);
    const float eps = tracer.surfaceEpsilon();
    if (fromSurface && std::fabs(d0) <= 8.0 * eps && std::fabs(d1) > 8.0 * eps) {
      // The previous reflection point lies on this plane too: an edge where
      // two walls meet reflects in both at once (a corner reflector); the leg
      // between the two reflections has zero length.
      for (uint32_t t : tracer.planes().trianglesOfPlane[plane])
        if (pointOnTriangle(tracer.mesh(), t, from, 8.0 * eps)) {
          point = from;
          triangle = t;
          return true;
        }
      return false;
    }
    if (d0 * d1 >= 0) return false;  // the segment must cross the plane
    const double s = d0 / (d0 - d1);
    point = from + (to - from) * s;
    const Vec3d delta = point - from;
    const double dist = length(delta);
    if (!(dist > 0)) return false;
    // A crossing well beyond the bounds of the plane's triangles is on none
    // of them, and the ray below would find that out: no ray (in the
    // runtime's 32 sources, half the legs traced were such). The margin is
    // far above the 8 eps the tests below allow.
    if (!nearPlaneBounds(plane, point, 64.0 * eps)) return false;
    Ray ray{from, fromSurface ? 4 * eps : 0.0f, Vec3f(delta / dist), float(dist) + 8 * eps};
    Hit hit;
    if (!tracer.intersect(ray, hit)) return false;
    if (std::fabs(double(hit.t) - dist) > 8.0 * eps) return false;  // blocked before, or missed the wall
    if (tracer.planeOf(hit.triangle) == plane) {
      triangle = hit.triangle;
      return true;
    }
    // The hit is another plane's triangle at the same distance: the path
    // strikes an edge where the two meet. It is valid when the crossing lies
    // on a triangle of the expected plane (edges included).
    for (uint32_t t : tracer.planes().trianglesOfPlane[plane])
      if (pointOnTriangle(tracer.mesh(), t, point, 8.0 * eps)) {
        triangle = t;
        return true;
      }
    return false;
  }

  // True when p lies within `margin` of the plane's bounds (or the tracer's
  // planes have none).
  bool nearPlaneBounds(uint32_t plane, const Vec3d& p, double margin) const {
    const auto& bounds = tracer.planes().bounds;
    if (plane >= bounds.size()) return true;
    const Vec3f& lo = bounds[plane][0];
    const Vec3f& hi = bounds[plane][1];
    return p.x >= double(lo.x) - margin && p.x <= double(hi.x) + margin && p.y >= double(lo.y) - margin &&
           p.y <= double(hi.y) + margin && p.z >= double(lo.z) - margin && p.z <= double(hi.z) + margin;
  }

  bool unobstructed(const Vec3d& from, const Vec3d& to) const {
    const Vec3d delta = to - from;
    const double dist = length(delta);
    if (!(dist > 0)) return true;
    const float eps = tracer.surfaceEpsilon();
    Ray ray{from, float(eps), Vec3f(delta / dist), float(dist) - 2 * eps};
    return ray.tFar <= ray.tNear || !tracer.occluded(ray);
  }

  // Validates one sequence (planes[0] first from the source); fills path.
  bool validate(const PlaneSequence& planes, uint32_t order, SpecularPath& path) const {
    // Image sources: images[k] = source mirrored in planes[0..k-1].
    Vec3d images[kMaxImageSourceOrder + 1];
    images[0] = source;
    for (uint32_t k = 0; k < order; ++k) {
      const Plane& p = tracer.planes().planes[planes[k]];
      if (std::fabs(p.distance(images[k])) < 1e-9) return false;
      images[k + 1] = p.mirror(images[k]);
    }
    // Walk back from the listener toward each image.
    Vec3d from = listener;
    Vec3d points[kMaxImageSourceOrder];
    uint32_t triangles[kMaxImageSourceOrder];
    for (uint32_t k = order; k-- > 0;) {
      if (!legHitsPlane(from, k + 1 < order, images[k + 1], planes[k], points[k], triangles[k])) return false;
      from = points[k];
    }
    if (!unobstructed(from, source)) return false;
    // Build the path.
    double len = length(listener - images[order]);
    path.order = order;
    path.planes = planes;
    path.lengthMeters = len;
    path.delaySeconds = len / settings.speedOfSound;
    path.spreadingGain = 1.0 / std::max(len, 1e-3);
    path.imageSource = images[order];
    const Vec3d last = order > 0 ? points[order - 1] : source;
    path.directionFromListener = normalize(last - listener);
    for (int b = 0; b < kNumBands; ++b) {
      double g = std::pow(10.0, -airDbPerM[b] * len / 20.0);
      for (uint32_t k = 0; k < order; ++k) {
        const Material& m = materials[tracer.materialOf(triangles[k])];
        double e = std::clamp(1.0 - double(m.absorption[b]), 0.0, 1.0);
        if (settings.specularPartOnly) e *= std::clamp(1.0 - double(m.scattering[b]), 0.0, 1.0);
        g *= std::sqrt(e);
      }
      path.bandGain[b] = g;
    }
    return true;
  }
};

}  // namespace

Status validate(const ImageSourceSettings& s) {
  if (s.maxOrder > kMaxImageSourceOrder)
    return invalidArgument("image-source order " + std::to_string(s.maxOrder) + " is outside [0, " +
                           std::to_string(kMaxImageSourceOrder) + "]");
  if (!(s.speedOfSound >= 1.0 && s.speedOfSound <= 1e5))
    return invalidArgument("speed of sound " + std::to_string(s.speedOfSound) + " m/s is outside [1, 1e5]");
  return validate(s.air);
}

std::vector<PlaneSequence> imageSourceCandidates(const RayTracer& tracer, const Vec3d& from,
                                                 const ImageSourceSettings& settings, bool fromListener,
                                                 ThreadPool* pool) {
  const uint32_t maxOrder = std::min(settings.maxOrder, kMaxImageSourceOrder);
  if (maxOrder == 0 || tracer.empty() || !isFinite(from) || settings.candidateRays == 0) return {};
  const float eps = tracer.surfaceEpsilon();
  Pcg32 rng(settings.seed, 0xC0FFEEULL);
  const double rotation = rng.uniformDouble();  // spin the Fibonacci sphere per seed
  const double c = std::cos(rotation * 6.283185307179586), s = std::sin(rotation * 6.283185307179586);
  // The rays in a fixed number of chunks, each into its own set: the union
  // is the same whatever the threads.
  constexpr uint32_t kChunks = 16;
  const uint32_t perChunk = (settings.candidateRays + kChunks - 1) / kChunks;
  std::vector<PlaneSequenceSet> found(kChunks);
  auto chunk = [&](size_t task, unsigned) {
    PlaneSequenceSet& candidates = found[task];
    const uint32_t first = uint32_t(task) * perChunk;
    const uint32_t last = std::min(settings.candidateRays, first + perChunk);
    for (uint32_t i = first; i < last; ++i) {
      Vec3d d = fibonacciDirection(i, settings.candidateRays);
      d = {c * d.x - s * d.y, s * d.x + c * d.y, d.z};
      Ray ray{from, 0.0f, Vec3f(d), 1e30f};
      PlaneSequence seq;
      seq.fill(kUnused);
      for (uint32_t k = 0; k < maxOrder; ++k) {
        Hit hit;
        if (!tracer.intersect(ray, hit)) break;
        seq[k] = tracer.planeOf(hit.triangle);
        if (k > 0 && seq[k] == seq[k - 1]) break;
        if (fromListener) {
          // The path from the source runs through these planes backwards.
          PlaneSequence reversed;
          reversed.fill(kUnused);
          for (uint32_t j = 0; j <= k; ++j) reversed[j] = seq[k - j];
          candidates.insert(reversed);
        } else {
          candidates.insert(seq);
        }
        Vec3f n = hit.normal;
        if (dot(n, ray.direction) > 0) n = -n;
        ray.origin = ray.origin + Vec3d(ray.direction) * double(hit.t) + Vec3d(n * eps);
        ray.direction = normalize(ray.direction - n * (2.0f * dot(ray.direction, n)));
      }
    }
  };
  if (pool && pool->threadCount() > 1) {
    pool->parallelFor(kChunks, chunk);
  } else {
    for (size_t t = 0; t < kChunks; ++t) chunk(t, 0);
  }
  for (size_t t = 1; t < kChunks; ++t) found[0].insert(found[t].begin(), found[t].end());
  // Deterministic order: sorted.
  std::vector<PlaneSequence> sorted(found[0].begin(), found[0].end());
  std::sort(sorted.begin(), sorted.end());
  return sorted;
}

Result<ImageSourceResult> findImageSources(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& source,
                                           const Vec3d& listener, const ImageSourceSettings& settings, ThreadPool* pool) {
  EARSHOT_RETURN_IF_ERROR(validate(settings));
  if (!isFinite(source) || !isFinite(listener)) return invalidArgument("source or listener position is not finite");
  const auto start = std::chrono::steady_clock::now();
  ImageSourceResult result;
  const size_t planeCount = tracer.planes().planes.size();
  if (settings.maxOrder == 0 || planeCount == 0) return result;

  Validator v{tracer, materials, source, listener, settings, airAttenuationDbPerMeter(settings.air)};
  auto consider = [&](const PlaneSequence& seq, uint32_t order) {
    ++result.candidates;
    SpecularPath path;
    if (v.validate(seq, order, path)) {
      result.found.insert(seq);
      result.paths.push_back(path);
    }
  };

  if (planeCount <= settings.maxPlanesExhaustive) {
    // Every sequence, depth first.
    PlaneSequence seq;
    seq.fill(kUnused);
    auto recurse = [&](auto&& self, uint32_t depth) -> void {
      for (uint32_t p = 0; p < planeCount; ++p) {
        if (depth > 0 && seq[depth - 1] == p) continue;
        seq[depth] = p;
        consider(seq, depth + 1);
        if (depth + 1 < settings.maxOrder) self(self, depth + 1);
      }
      seq[depth] = kUnused;
    };
    recurse(recurse, 0);
  } else {
    result.exhaustive = false;
    std::vector<PlaneSequence> own;
    if (!settings.candidates) own = imageSourceCandidates(tracer, source, settings, false, pool);
    const std::vector<PlaneSequence>& list = settings.candidates ? *settings.candidates : own;
    auto orderOf = [&](const PlaneSequence& seq) {
      uint32_t order = 0;
      while (order < kMaxImageSourceOrder && seq[order] != kUnused) ++order;
      return order == 0 || order > settings.maxOrder ? 0u : order;
    };
    for (const auto& seq : list) {
      const uint32_t order = orderOf(seq);
      if (order > 0) consider(seq, order);
    }
  }
  std::sort(result.paths.begin(), result.paths.end(), [](const SpecularPath& a, const SpecularPath& b) {
    return a.delaySeconds < b.delaySeconds || (a.delaySeconds == b.delaySeconds && a.planes < b.planes);
  });
  // Reflections in two walls that meet at an edge commute: (A, B) and (B, A)
  // give one image and one physical path through the edge. Keep one path
  // (both sequences stay in `found`, so the tracer excludes either).
  std::vector<SpecularPath> unique;
  for (const SpecularPath& p : result.paths) {
    bool seen = false;
    for (auto it = unique.rbegin(); it != unique.rend() && it->delaySeconds > p.delaySeconds - 1e-12; ++it)
      if (length(it->imageSource - p.imageSource) < 1e-9 * std::max(1.0, p.lengthMeters)) seen = true;
    if (!seen) unique.push_back(p);
  }
  result.paths = std::move(unique);
  result.milliseconds = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace earshot
