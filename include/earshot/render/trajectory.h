#pragma once
/** @file Where a listener or source is, and which way it faces, over time:
 *  a static pose or keyframes interpolated linearly in position and by
 *  spherical linear interpolation (slerp) of the orientation frame. */
#include <string>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/core/math.h"
#include "earshot/core/vec3.h"

namespace earshot {

/** Default orientation (docs/design.md: glTF convention): forward -Z, up +Y. */
constexpr Vec3d kDefaultForward{0.0, 0.0, -1.0};
constexpr Vec3d kDefaultUp{0.0, 1.0, 0.0};

/** Latest keyframe time (and any other scene time) accepted, seconds. */
constexpr double kMaxSceneSeconds = 86400.0;

/** Least time between two keyframes, seconds: under a sample period at
 *  every rate (2.6 us at 384 kHz), and enough for any jump within
 *  kMaxCoordinateMeters to have a finite velocity. */
constexpr double kMinKeyframeSpacingSeconds = 1e-6;

/** A pose at one instant. forward and up are unit length and orthogonal. */
struct Pose {
  Vec3d position;             ///< metres
  Vec3d forward = kDefaultForward;
  Vec3d up = kDefaultUp;
  Vec3d velocity;             ///< m/s: the slope of the position's segment; 0 when static or clamped
};

/** One keyframe as given: forward and up need not be unit length or exactly
 *  orthogonal (Trajectory orthonormalises them), only non-zero and not parallel. */
struct Keyframe {
  double t = 0.0;             ///< seconds from the start of the scene, >= 0
  Vec3d position;             ///< metres
  Vec3d forward = kDefaultForward;
  Vec3d up = kDefaultUp;
};

/** A static pose or keyframes with strictly increasing times.
 *
 *  at(t): before the first keyframe and after the last, the pose is that
 *  keyframe's (clamped, velocity 0). Between keyframes k and k+1 the position
 *  is linear in t (velocity constant over the segment) and the orientation
 *  frame (right, up, -forward) is slerped as a rotation along the shortest
 *  arc (constant angular speed), then re-orthonormalised; a 180-degree turn
 *  is well defined (its axis follows from the two frames) and never NaN.
 *  Plain data: copy freely; const methods are safe from any thread. */
class Trajectory {
 public:
  /** At the origin, default orientation. */
  Trajectory();

  /** A static pose. `name` (e.g. "listener") prefixes errors:
   *  "listener.up: parallel to forward". Checks finite, |coordinate| <=
   *  kMaxCoordinateMeters, forward non-zero, up not parallel to forward. */
  static Result<Trajectory> fromPose(const Vec3d& position, const Vec3d& forward = kDefaultForward,
                                     const Vec3d& up = kDefaultUp, const std::string& name = "pose");

  /** Keyframes (at least one). `name` (e.g. "sources[0].path") prefixes
   *  errors with the keyframe's index: "sources[0].path[3].t: 2 is not after
   *  path[2].t = 2 (times must increase strictly)". Checks as fromPose, and
   *  every t finite, in [0, kMaxSceneSeconds], strictly increasing, each
   *  at least kMinKeyframeSpacingSeconds after the one before. */
  static Result<Trajectory> fromKeyframes(std::vector<Keyframe> keyframes, const std::string& name = "path");

  /** The pose at time t (seconds; any finite value). O(log keyframes). */
  Pose at(double t) const;

  bool isStatic() const { return mKeys.size() == 1; }
  /** The position never changes (the orientation may). */
  bool isStationary() const {
    for (const Keyframe& k : mKeys)
      if (!(k.position == mKeys.front().position)) return false;
    return true;
  }
  /** Keyframes with orthonormal forward/up (a static pose is one keyframe at t = 0). */
  const std::vector<Keyframe>& keyframes() const { return mKeys; }
  /** Time of the last keyframe (0 when static), seconds. */
  double endSeconds() const { return mKeys.back().t; }

 private:
  std::vector<Keyframe> mKeys;  // orthonormal frames, strictly increasing t
};

}  // namespace earshot
