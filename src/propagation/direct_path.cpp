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
  const BandArrayD dirEnergy = settings.directivity.energyFactors(-d.directionFromListener);
  for (int b = 0; b < kNumBands; ++b) d.directivityGain[size_t(b)] = std::sqrt(dirEnergy[size_t(b)]);

  const BandArrayD airDb = airAttenuationDbPerMeter(settings.air);
  BandArrayD energy{};
  for (int b = 0; b < kNumBands; ++b) energy[b] = std::pow(10.0, -airDb[b] * d.distanceMeters / 10.0);
  BandArrayD through = filledBands(1.0);  // the occluders' alone

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
      for (int b = 0; b < kNumBands; ++b) {
        energy[b] *= m.transmission[b];
        through[b] *= m.transmission[b];
      }
      if (*std::max_element(through.begin(), through.end()) <= 0.0) break;
      ray.tNear = hit.t + eps;
      if (ray.tNear >= ray.tFar) break;
    }
  }
  d.audible = false;
  for (int b = 0; b < kNumBands; ++b) {
    d.bandGain[b] = std::sqrt(energy[b]);
    d.transmissionGain[b] = std::sqrt(through[b]);
    d.audible |= d.bandGain[b] > 0.0;
  }
  return d;
}

namespace {

double patternMeanSquare(double alpha, double sharpness) {
  if (alpha == 0.0) return 1.0;
  // <g^2> over the sphere: g depends on cos(theta) only, uniform in [-1, 1].
  constexpr int kSteps = 4096;
  double sum = 0;
  for (int i = 0; i < kSteps; ++i) {
    const double c = -1.0 + (i + 0.5) * 2.0 / kSteps;
    const double g = std::pow(std::fabs((1.0 - alpha) + alpha * c), sharpness);
    sum += g * g;
  }
  return sum / kSteps;
}

}  // namespace

bool Directivity::isOmni() const {
  for (int b = 0; b < kNumBands; ++b)
    if (alphaOf(b) != 0.0) return false;
  return true;
}

BandArrayD Directivity::meanSquares() const {
  BandArrayD out = filledBands(1.0);
  if (!perBand) {
    out = filledBands(patternMeanSquare(alpha, sharpness));
  } else {
    for (int b = 0; b < kNumBands; ++b) out[size_t(b)] = patternMeanSquare(bandAlpha[size_t(b)], sharpness);
  }
  return out;
}

BandArrayD Directivity::energyFactors(const Vec3d& u, const BandArrayD& ms) const {
  BandArrayD out = filledBands(1.0);
  if (isOmni()) return out;
  const double len = length(forward);
  const double c = std::clamp(len > 0 ? dot(u, forward) / len : 1.0, -1.0, 1.0);
  auto factor = [&](double a, double m) {
    const double g = std::pow(std::fabs((1.0 - a) + a * c), sharpness);
    return g * g / m;
  };
  if (!perBand) return filledBands(factor(alpha, ms[0]));
  for (int b = 0; b < kNumBands; ++b) out[size_t(b)] = factor(bandAlpha[size_t(b)], ms[size_t(b)]);
  return out;
}

Status validate(const Directivity& d) {
  for (int b = 0; b < kNumBands; ++b)
    if (!(d.alphaOf(b) >= 0.0 && d.alphaOf(b) <= 1.0))
      return invalidArgument("directivity alpha " + std::to_string(d.alphaOf(b)) + " is outside [0, 1]");
  if (!(d.sharpness >= 1.0 && d.sharpness <= 16.0))
    return invalidArgument("directivity sharpness " + std::to_string(d.sharpness) + " is outside [1, 16]");
  if (!isFinite(d.forward) || !(length(d.forward) > 0)) return invalidArgument("directivity forward is zero or not finite");
  return Status::ok();
}

}  // namespace earshot
