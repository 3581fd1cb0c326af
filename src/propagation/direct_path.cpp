#include "earshot/propagation/direct_path.h"

#include <algorithm>
#include <cmath>

#include "earshot/scene/ray_tracer.h"

namespace earshot {

DirectPath computeDirectPath(const RayTracer* tracer, const MaterialTable& materials, const Vec3d& source,
                             const Vec3d& listener, const DirectPathSettings& settings) {
  DirectPath d;
  const Vec3d delta = source - listener;
  d.distanceMeters = length(delta);
  d.delaySeconds = d.distanceMeters / settings.speedOfSound;
  d.spreadingGain = 1.0 / std::max(d.distanceMeters, settings.minDistanceMeters);
  d.directionFromListener = d.distanceMeters > 0 ? delta / d.distanceMeters : Vec3d{0, 0, -1};

  const BandArrayD airDb = airAttenuationDbPerMeter(settings.air);
  BandArrayD energy{};
  for (int b = 0; b < kNumBands; ++b) energy[b] = std::pow(10.0, -airDb[b] * d.distanceMeters / 10.0);

  if (tracer && !tracer->empty() && d.distanceMeters > 0 && !tracer->nothingBetween(listener, source)) {
    d.occlusionTested = true;
    // Walk every surface on the segment listener -> source, multiplying transmission.
    const Vec3f dir = Vec3f(d.directionFromListener);
    const float eps = tracer->surfaceEpsilon();
    Ray ray{listener, 0.0f, dir, float(d.distanceMeters)};
    Hit hit;
    // A segment through a mesh crosses each surface once; 1024 guards against
    // pathological stacks of coincident triangles.
    for (int guard = 0; guard < 1024 && tracer->intersect(ray, hit); ++guard) {
      const Material& m = materials[tracer->materialOf(hit.triangle)];
      ++d.surfacesCrossed;
      for (int b = 0; b < kNumBands; ++b) energy[b] *= m.transmission[b];
      if (*std::max_element(energy.begin(), energy.end()) <= 0.0) break;
      ray.tNear = hit.t + eps;
      if (ray.tNear >= ray.tFar) break;
    }
  }
  d.audible = false;
  for (int b = 0; b < kNumBands; ++b) {
    d.bandGain[b] = std::sqrt(energy[b]);
    d.audible |= d.bandGain[b] > 0.0;
  }
  return d;
}

}  // namespace earshot
