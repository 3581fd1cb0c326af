#include "earshot/hrtf/coordinates.h"

#include <algorithm>
#include <cmath>

#include "earshot/core/math.h"

namespace earshot::hrtf {

SofaAngles headDirectionToSofaAngles(const Vec3d& headDirection) {
  Vec3d s = headToSofa(headDirection);
  double len = length(s);
  if (!(len > 0.0) || !std::isfinite(len)) return {};
  s = s / len;
  SofaAngles a;
  a.azimuthDegrees = std::atan2(s.y, s.x) * 180.0 / kPi;
  if (a.azimuthDegrees <= -180.0) a.azimuthDegrees += 360.0;
  a.elevationDegrees = std::asin(std::clamp(s.z, -1.0, 1.0)) * 180.0 / kPi;
  return a;
}

Vec3d sofaAnglesToHeadDirection(double azimuthDegrees, double elevationDegrees) {
  double az = azimuthDegrees * kPi / 180.0, el = elevationDegrees * kPi / 180.0;
  Vec3d s{std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
  return sofaToHead(s);
}

}  // namespace earshot::hrtf
