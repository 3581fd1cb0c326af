#pragma once
/** @file Real spherical harmonics in the AmbiX convention (ACN channel order,
 *  SN3D normalisation) up to order 3, and their rotation.
 *
 *  Coordinates: x forward, y left, z up (right-handed), the ambisonic
 *  convention; for a unit direction (x, y, z) the channel ACN = n^2 + n + m
 *  of order n and degree m is, up to order 3 (Nachbar, Zotter, Deleflie &
 *  Sontacchi, "AmbiX - a suggested ambisonics format", Ambisonics Symposium
 *  2011, table of SN3D real harmonics):
 *    W 1;  Y y;  Z z;  X x;
 *    V sqrt3 xy;  T sqrt3 yz;  R (3z^2-1)/2;  S sqrt3 xz;  U sqrt3/2 (x^2-y^2);
 *    Q sqrt(5/8) y(3x^2-y^2);  O sqrt15 xyz;  M sqrt(3/8) y(5z^2-1);
 *    K z(5z^2-3)/2;  L sqrt(3/8) x(5z^2-1);  N sqrt15/2 z(x^2-y^2);
 *    P sqrt(5/8) x(x^2-3y^2).
 *  SN3D: a channel's mean square over the sphere is 1/(2n+1) (N3D's is 1);
 *  W of a plane wave equals its pressure.
 *
 *  Rotation: for a rotation R of directions (d -> R d), the harmonics of
 *  order n mix among themselves only: Y(R d) = M(R) Y(d) with M block
 *  diagonal. ShRotation computes M for any R without recursion: M =
 *  Y(R D) pinv(Y(D)) over a fixed set D of directions, exact (to rounding)
 *  because the harmonics up to the order are spanned by their values on D. */
#include <array>
#include <cstddef>
#include <vector>

#include "earshot/core/vec3.h"

namespace earshot {

constexpr int kMaxAmbisonicOrder = 3;
constexpr int kMaxAmbisonicChannels = (kMaxAmbisonicOrder + 1) * (kMaxAmbisonicOrder + 1);

/** Channels of an order: (order + 1)^2. */
constexpr int ambisonicChannels(int order) { return (order + 1) * (order + 1); }
/** The order n of ACN channel `acn`. */
int ambisonicOrderOf(int acn);

/** The (order + 1)^2 SN3D real harmonics (ACN order) of the unit direction
 *  `d` (x forward, y left, z up) into out[0 .. (order+1)^2). order in [0, 3].
 *  No allocation. */
void realSphericalHarmonics(const Vec3d& d, int order, double* out);
void realSphericalHarmonics(const Vec3f& d, int order, float* out);

/** A 3x3 rotation, row-major: d' = R d. */
using Rotation3 = std::array<double, 9>;

/** The rotation that takes world directions into a listener's ambisonic
 *  frame (x forward, y left, z up) given the listener's forward and up in
 *  the world (up made orthogonal to forward; both finite, non-zero, not
 *  parallel). Its rows are forward, left = up x forward, up. */
Rotation3 worldToAmbisonicFrame(const Vec3d& forward, const Vec3d& up);

/** R d. */
Vec3d rotate(const Rotation3& r, const Vec3d& d);
/** The rotation from frame `from` to frame `to`, both given as rotations from
 *  the world: to from^T. */
Rotation3 relativeRotation(const Rotation3& to, const Rotation3& from);

/** M(R) for SH up to kMaxAmbisonicOrder: prepared once (allocates), then
 *  compute() is allocation-free and cheap (~10 us), for the audio thread. */
class ShRotation {
 public:
  ShRotation();
  /** Fills m (kMaxAmbisonicChannels^2 floats, row-major: out = m * in) with
   *  the rotation of the harmonics up to `order` (the other entries zero).
   *  R must be a rotation (orthonormal, det +1). */
  void compute(const Rotation3& r, int order, float* m) const;

 private:
  std::vector<Vec3d> mDirections;   // D
  std::vector<double> mPinv;        // pinv(Y(D)): [direction][channel], one per order's block
};

}  // namespace earshot
