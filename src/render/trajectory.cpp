// Keyframed poses. Orientation: each keyframe's frame (right, up, back =
// -forward) is a rotation matrix, turned into a unit quaternion (Shepperd's
// method: S. W. Shepperd, "Quaternion from rotation matrix", J. Guidance and
// Control 1(3), 1978) and interpolated by slerp along the shorter arc
// (K. Shoemake, "Animating rotation with quaternion curves", SIGGRAPH 1985).
// The result is re-orthonormalised (Gram-Schmidt) against rounding.
#include "earshot/render/trajectory.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

namespace earshot {

namespace {

// Smallest sine of the angle between forward and up we accept: below it the
// two do not define a plane well (about 0.06 degrees).
constexpr double kMinSinForwardUp = 1e-3;

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

struct Quat {
  double w, x, y, z;
};

Quat fromFrame(const Vec3d& forward, const Vec3d& up) {
  // Columns of R: right, up, back.
  const Vec3d r = cross(forward, up), b = -forward;
  const double m00 = r.x, m01 = up.x, m02 = b.x;
  const double m10 = r.y, m11 = up.y, m12 = b.y;
  const double m20 = r.z, m21 = up.z, m22 = b.z;
  const double tr = m00 + m11 + m22;
  Quat q;
  if (tr > 0) {
    double s = 2.0 * std::sqrt(1.0 + tr);
    q = {0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s};
  } else if (m00 > m11 && m00 > m22) {
    double s = 2.0 * std::sqrt(std::max(0.0, 1.0 + m00 - m11 - m22));
    q = {(m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s};
  } else if (m11 > m22) {
    double s = 2.0 * std::sqrt(std::max(0.0, 1.0 + m11 - m00 - m22));
    q = {(m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s};
  } else {
    double s = 2.0 * std::sqrt(std::max(0.0, 1.0 + m22 - m00 - m11));
    q = {(m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s};
  }
  double n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  return {q.w / n, q.x / n, q.y / n, q.z / n};
}

Vec3d rotate(const Quat& q, const Vec3d& v) {
  // v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z).
  const Vec3d u{q.x, q.y, q.z};
  const Vec3d t = cross(u, v) * 2.0;
  return v + t * q.w + cross(u, t);
}

Quat slerp(Quat a, Quat b, double s) {
  double d = a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z;
  if (d < 0) {  // shorter arc
    b = {-b.w, -b.x, -b.y, -b.z};
    d = -d;
  }
  double ka, kb;
  if (d > 0.9995) {  // nearly equal: nlerp (normalised below) avoids 0/0
    ka = 1.0 - s;
    kb = s;
  } else {
    const double theta = std::acos(std::min(1.0, d));
    const double st = std::sin(theta);
    ka = std::sin((1.0 - s) * theta) / st;
    kb = std::sin(s * theta) / st;
  }
  Quat q{ka * a.w + kb * b.w, ka * a.x + kb * b.x, ka * a.y + kb * b.y, ka * a.z + kb * b.z};
  double n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  return {q.w / n, q.x / n, q.y / n, q.z / n};
}

// Gram-Schmidt: unit forward, unit up orthogonal to it. Inputs already checked.
void orthonormalise(Vec3d& forward, Vec3d& up) {
  forward = normalize(forward);
  up = normalize(up - forward * dot(up, forward));
}

std::string vecText(const Vec3d& v) { return "[" + fmt(v.x) + ", " + fmt(v.y) + ", " + fmt(v.z) + "]"; }

Status checkPose(const Vec3d& position, Vec3d& forward, Vec3d& up, const std::string& name) {
  if (!isFinite(position)) return invalidArgument(name + ".position: not finite");
  for (int i = 0; i < 3; ++i)
    if (std::abs(position[i]) > kMaxCoordinateMeters)
      return outOfRange(name + ".position: " + vecText(position) + " is farther than " + fmt(kMaxCoordinateMeters) +
                        " m from the origin on an axis");
  if (!isFinite(forward)) return invalidArgument(name + ".forward: not finite");
  if (!isFinite(up)) return invalidArgument(name + ".up: not finite");
  const double lf = length(forward), lu = length(up);
  if (!(lf > 0) || !std::isfinite(lf)) return invalidArgument(name + ".forward: zero length (expected a direction)");
  if (!(lu > 0) || !std::isfinite(lu)) return invalidArgument(name + ".up: zero length (expected a direction)");
  const double sinAngle = length(cross(forward / lf, up / lu));
  if (!(sinAngle >= kMinSinForwardUp))
    return invalidArgument(name + ".up: " + vecText(up) + " is parallel to forward " + vecText(forward) +
                           " (the two must span a plane)");
  // Scale to unit length first: the part of a tiny up (1e-160) orthogonal to
  // forward could underflow to zero when squared.
  forward = forward / lf;
  up = up / lu;
  orthonormalise(forward, up);
  return Status::ok();
}

}  // namespace

Trajectory::Trajectory() : mKeys(1) {}

Result<Trajectory> Trajectory::fromPose(const Vec3d& position, const Vec3d& forward, const Vec3d& up,
                                        const std::string& name) {
  Keyframe k{0.0, position, forward, up};
  EARSHOT_RETURN_IF_ERROR(checkPose(k.position, k.forward, k.up, name));
  Trajectory tr;
  tr.mKeys = {k};
  return tr;
}

Result<Trajectory> Trajectory::fromKeyframes(std::vector<Keyframe> keyframes, const std::string& name) {
  if (keyframes.empty()) return invalidArgument(name + ": expected at least one keyframe");
  for (size_t i = 0; i < keyframes.size(); ++i) {
    Keyframe& k = keyframes[i];
    const std::string ki = name + "[" + std::to_string(i) + "]";
    if (!std::isfinite(k.t)) return invalidArgument(ki + ".t: not finite");
    if (k.t < 0) return invalidArgument(ki + ".t: " + fmt(k.t) + " is negative (times are seconds from the start)");
    if (k.t > kMaxSceneSeconds)
      return outOfRange(ki + ".t: " + fmt(k.t) + " s is later than the limit of " + fmt(kMaxSceneSeconds) + " s");
    if (i > 0 && !(k.t > keyframes[i - 1].t))
      return invalidArgument(ki + ".t: " + fmt(k.t) + " is not after " + name + "[" + std::to_string(i - 1) +
                             "].t = " + fmt(keyframes[i - 1].t) + " (keyframe times must increase strictly)");
    if (i > 0 && !(k.t - keyframes[i - 1].t >= kMinKeyframeSpacingSeconds))
      return invalidArgument(ki + ".t: " + fmt(k.t) + " is less than 1 us after " + name + "[" + std::to_string(i - 1) +
                             "].t = " + fmt(keyframes[i - 1].t) + " (a jump takes two keyframes at least 1 us apart)");
    EARSHOT_RETURN_IF_ERROR(checkPose(k.position, k.forward, k.up, ki));
  }
  Trajectory tr;
  tr.mKeys = std::move(keyframes);
  return tr;
}

Pose Trajectory::at(double t) const {
  const auto pose = [](const Keyframe& k) {
    Pose p;
    p.position = k.position;
    p.forward = k.forward;
    p.up = k.up;
    return p;
  };
  if (!(t > mKeys.front().t)) return pose(mKeys.front());  // also NaN
  if (t >= mKeys.back().t) return pose(mKeys.back());
  // First keyframe later than t; t lies in [k0.t, k1.t).
  auto it = std::upper_bound(mKeys.begin(), mKeys.end(), t, [](double v, const Keyframe& k) { return v < k.t; });
  const Keyframe& k1 = *it;
  const Keyframe& k0 = *(it - 1);
  const double span = k1.t - k0.t;
  const double s = (t - k0.t) / span;
  Pose p;
  p.position = k0.position + (k1.position - k0.position) * s;
  p.velocity = (k1.position - k0.position) / span;
  const Quat q = slerp(fromFrame(k0.forward, k0.up), fromFrame(k1.forward, k1.up), s);
  Vec3d forward = -rotate(q, Vec3d{0, 0, 1}), up = rotate(q, Vec3d{0, 1, 0});
  orthonormalise(forward, up);
  p.forward = forward;
  p.up = up;
  return p;
}

}  // namespace earshot
