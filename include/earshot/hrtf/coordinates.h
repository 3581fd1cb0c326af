#pragma once
/** @file Conversions between earshot's listener head frame and SOFA's frame.
 *
 *  earshot head frame (glTF convention, docs/design.md): +x = right, +y = up,
 *  -z = forward. So forward is (0, 0, -1), left is (-1, 0, 0), up is (0, 1, 0).
 *
 *  SOFA frame (AES69, listener view +x, up +z): +x = forward, +y = left,
 *  +z = up. Spherical SOFA coordinates: azimuth in degrees counter-clockwise
 *  from the front seen from above (90 = left, -90 or 270 = right), elevation
 *  in degrees up from the horizontal plane (90 = above).
 *
 *  Mapping: sofa = (-head.z, -head.x, head.y); head = (-sofa.y, sofa.z, -sofa.x).
 *
 *  All functions are pure, allocation-free and callable from any thread,
 *  including the audio thread. */
#include "earshot/core/vec3.h"

namespace earshot::hrtf {

/** Azimuth/elevation in SOFA's spherical convention, degrees. */
struct SofaAngles {
  double azimuthDegrees = 0.0;    ///< (-180, 180], counter-clockwise from front, 90 = left
  double elevationDegrees = 0.0;  ///< [-90, 90], 90 = straight up
};

/** Head-frame vector (earshot convention) to SOFA cartesian (x fwd, y left, z up). */
template <class T>
constexpr Vec3<T> headToSofa(const Vec3<T>& head) { return {-head.z, -head.x, head.y}; }

/** SOFA cartesian (x fwd, y left, z up) to head-frame vector (x right, y up, -z fwd). */
template <class T>
constexpr Vec3<T> sofaToHead(const Vec3<T>& sofa) { return {-sofa.y, sofa.z, -sofa.x}; }

/** Direction in the head frame (any non-zero length) to SOFA azimuth/elevation.
 *  A zero vector gives (0, 0), i.e. forward. */
SofaAngles headDirectionToSofaAngles(const Vec3d& headDirection);

/** SOFA azimuth/elevation (degrees, any range) to a unit direction in the head frame. */
Vec3d sofaAnglesToHeadDirection(double azimuthDegrees, double elevationDegrees);

}  // namespace earshot::hrtf
