#pragma once
/** @file Constants and small numeric helpers. */
#include <cmath>

namespace earshot {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDefaultSpeedOfSound = 343.0;  ///< m/s (docs/design.md)
/** Largest coordinate magnitude accepted anywhere (geometry, sources,
 *  listener), metres: beyond it float geometry loses centimetres, and from
 *  ~1.8e18 Embree's BVH builder asserts and aborts the process. */
constexpr double kMaxCoordinateMeters = 1e6;
/** |x|, |y| and |z| all within kMaxCoordinateMeters (false for NaN). */
template <class V>
constexpr bool withinCoordinateRange(const V& p) {
  return std::fabs(p.x) <= kMaxCoordinateMeters && std::fabs(p.y) <= kMaxCoordinateMeters &&
         std::fabs(p.z) <= kMaxCoordinateMeters;
}

inline double dbToGain(double db) { return std::pow(10.0, db / 20.0); }
inline double gainToDb(double g) { return 20.0 * std::log10(g); }
inline double energyToDb(double e) { return 10.0 * std::log10(e); }

}  // namespace earshot
