// Known answers for keyframed poses: linear position, slerped orientation,
// clamping outside the keyframes, orthonormal frames, and the errors.
#include "earshot/render/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>

#include "earshot/core/math.h"

namespace earshot {
namespace {

void expectVecNear(const Vec3d& a, const Vec3d& b, double tol, const std::string& what = "") {
  EXPECT_NEAR(a.x, b.x, tol) << what;
  EXPECT_NEAR(a.y, b.y, tol) << what;
  EXPECT_NEAR(a.z, b.z, tol) << what;
}

void expectOrthonormal(const Pose& p, const std::string& what) {
  ASSERT_TRUE(isFinite(p.forward) && isFinite(p.up)) << what;
  EXPECT_NEAR(length(p.forward), 1.0, 1e-12) << what;
  EXPECT_NEAR(length(p.up), 1.0, 1e-12) << what;
  EXPECT_NEAR(dot(p.forward, p.up), 0.0, 1e-12) << what;
}

Trajectory keyframes(std::vector<Keyframe> k) {
  auto t = Trajectory::fromKeyframes(std::move(k));
  EXPECT_TRUE(t.isOk()) << t.status().message();
  return t.isOk() ? *t : Trajectory();
}

TEST(Trajectory, MidpointIsLinearInPositionWithTheSegmentsVelocity) {
  Trajectory tr = keyframes({{0.0, {0, 0, 0}}, {2.0, {2, 4, 6}}, {3.0, {2, 4, 7}}});
  Pose p = tr.at(1.0);
  expectVecNear(p.position, {1, 2, 3}, 1e-12);
  expectVecNear(p.velocity, {1, 2, 3}, 1e-12);
  expectVecNear(tr.at(2.5).position, {2, 4, 6.5}, 1e-12);
  expectVecNear(tr.at(2.5).velocity, {0, 0, 1}, 1e-12);
  // Exactly at a keyframe: that keyframe.
  expectVecNear(tr.at(2.0).position, {2, 4, 6}, 1e-12);
  EXPECT_DOUBLE_EQ(tr.endSeconds(), 3.0);
}

TEST(Trajectory, ClampsBeforeTheFirstAndAfterTheLastKeyframe) {
  Trajectory tr = keyframes({{1.0, {1, 0, 0}, {1, 0, 0}, {0, 0, 1}}, {2.0, {3, 0, 0}, {0, 1, 0}, {0, 0, 1}}});
  for (double t : {-5.0, 0.0, 1.0}) {
    Pose p = tr.at(t);
    expectVecNear(p.position, {1, 0, 0}, 0.0);
    expectVecNear(p.forward, {1, 0, 0}, 1e-15);
    expectVecNear(p.velocity, {0, 0, 0}, 0.0);
  }
  for (double t : {2.0, 2.5, 1e9}) {
    Pose p = tr.at(t);
    expectVecNear(p.position, {3, 0, 0}, 0.0);
    expectVecNear(p.forward, {0, 1, 0}, 1e-15);
    expectVecNear(p.velocity, {0, 0, 0}, 0.0);
  }
  Pose nan = tr.at(std::nan(""));
  EXPECT_TRUE(isFinite(nan.position));
}

TEST(Trajectory, StaticPoseIsTheSameAtEveryTime) {
  auto tr = Trajectory::fromPose({1, 2, 3}, {0, 1, 0}, {0, 0, 1});
  ASSERT_TRUE(tr.isOk());
  EXPECT_TRUE(tr->isStatic());
  for (double t : {-1.0, 0.0, 7.5}) {
    Pose p = tr->at(t);
    expectVecNear(p.position, {1, 2, 3}, 0.0);
    expectVecNear(p.forward, {0, 1, 0}, 0.0);
    expectVecNear(p.up, {0, 0, 1}, 0.0);
  }
  Pose d = Trajectory().at(0.0);
  expectVecNear(d.forward, kDefaultForward, 0.0);
  expectVecNear(d.up, kDefaultUp, 0.0);
}

TEST(Trajectory, FramesAreOrthonormalisedAndStayOrthonormal) {
  // Neither unit length nor orthogonal as given.
  Trajectory tr = keyframes({{0.0, {0, 0, 0}, {2, 0, 0}, {1, 1, 0}}, {1.0, {0, 0, 0}, {0, 0, 3}, {0, 5, 1}},
                             {2.0, {0, 0, 0}, {-1, 1, 0}, {0, 0, 0.1}}});
  expectVecNear(tr.keyframes()[0].forward, {1, 0, 0}, 1e-15);
  expectVecNear(tr.keyframes()[0].up, {0, 1, 0}, 1e-15);
  for (int i = 0; i <= 200; ++i) expectOrthonormal(tr.at(i * 0.01), "t = " + std::to_string(i * 0.01));
}

TEST(Trajectory, NinetyDegreeTurnIsSlerpedAtConstantAngularSpeed) {
  // Yaw from -z to +x about +y in one second.
  Trajectory tr = keyframes({{0.0, {0, 0, 0}, {0, 0, -1}, {0, 1, 0}}, {1.0, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}}});
  const double h = std::sqrt(0.5);
  expectVecNear(tr.at(0.5).forward, {h, 0, -h}, 1e-12);
  expectVecNear(tr.at(0.5).up, {0, 1, 0}, 1e-12);
  // A third of the way: 30 degrees.
  expectVecNear(tr.at(1.0 / 3).forward, {std::sin(kPi / 6), 0, -std::cos(kPi / 6)}, 1e-12);
}

TEST(Trajectory, HalfTurnIsWellDefinedAndNeverNaN) {
  // Yaw by 180 degrees: the only rotation taking (-z, +y) to (+z, +y) is
  // about +y, so the midpoint faces +x or -x with up unchanged.
  Trajectory yaw = keyframes({{0.0, {0, 0, 0}, {0, 0, -1}, {0, 1, 0}}, {2.0, {0, 0, 0}, {0, 0, 1}, {0, 1, 0}}});
  for (int i = 0; i <= 100; ++i) expectOrthonormal(yaw.at(i * 0.02), "yaw t = " + std::to_string(i * 0.02));
  Pose mid = yaw.at(1.0);
  EXPECT_NEAR(std::abs(mid.forward.x), 1.0, 1e-12);
  expectVecNear(mid.up, {0, 1, 0}, 1e-12);
  // Quarter of the way: 45 degrees from the start.
  EXPECT_NEAR(dot(yaw.at(0.5).forward, Vec3d{0, 0, -1}), std::sqrt(0.5), 1e-12);

  // Roll by 180 degrees (up flips, forward stays): the midpoint's up is sideways.
  Trajectory roll = keyframes({{0.0, {0, 0, 0}, {0, 0, -1}, {0, 1, 0}}, {1.0, {0, 0, 0}, {0, 0, -1}, {0, -1, 0}}});
  for (int i = 0; i <= 50; ++i) expectOrthonormal(roll.at(i * 0.02), "roll t = " + std::to_string(i * 0.02));
  expectVecNear(roll.at(0.5).forward, {0, 0, -1}, 1e-12);
  EXPECT_NEAR(std::abs(roll.at(0.5).up.x), 1.0, 1e-12);

  // Forward and up both reversed (a 180-degree turn about the right axis).
  Trajectory pitch = keyframes({{0.0, {0, 0, 0}, {0, 0, -1}, {0, 1, 0}}, {1.0, {0, 0, 0}, {0, 0, 1}, {0, -1, 0}}});
  for (int i = 0; i <= 50; ++i) expectOrthonormal(pitch.at(i * 0.02), "pitch t = " + std::to_string(i * 0.02));
  expectVecNear(pitch.at(0.5).forward, {0, std::copysign(1.0, pitch.at(0.5).forward.y), 0}, 1e-12);
}

TEST(Trajectory, BadKeyframesAreNamedErrors) {
  auto err = [](std::vector<Keyframe> k) {
    auto t = Trajectory::fromKeyframes(std::move(k), "sources[0].path");
    EXPECT_FALSE(t.isOk());
    return t.isOk() ? std::string() : t.status().message();
  };
  EXPECT_EQ(err({}), "sources[0].path: expected at least one keyframe");
  EXPECT_EQ(err({{0.0, {0, 0, 0}}, {2.0, {1, 0, 0}}, {1.0, {2, 0, 0}}}),
            "sources[0].path[2].t: 1 is not after sources[0].path[1].t = 2 (keyframe times must increase strictly)");
  EXPECT_NE(err({{1.0, {0, 0, 0}}, {1.0, {1, 0, 0}}}).find("sources[0].path[1].t: 1 is not after"), std::string::npos);
  EXPECT_NE(err({{-0.5, {0, 0, 0}}}).find("sources[0].path[0].t: -0.5 is negative"), std::string::npos);
  EXPECT_NE(err({{std::nan(""), {0, 0, 0}}}).find("sources[0].path[0].t: not finite"), std::string::npos);
  EXPECT_NE(err({{0.0, {0, 0, 0}, {0, 0, 0}}}).find("sources[0].path[0].forward: zero length"), std::string::npos);
  EXPECT_NE(err({{0.0, {0, 0, 0}, {0, 0, 2}, {0, 0, -1}}}).find("sources[0].path[0].up: [0, 0, -1] is parallel"),
            std::string::npos);
  EXPECT_NE(err({{0.0, {0, 0, INFINITY}}}).find("sources[0].path[0].position: not finite"), std::string::npos);
  EXPECT_NE(err({{0.0, {2e6, 0, 0}}}).find("sources[0].path[0].position: [2e+06, 0, 0] is farther"),
            std::string::npos);
  // Keyframes closer than 1 us: a jump of 5 m in 9e-315 s (found by
  // fuzz_scene_json) had an infinite velocity.
  EXPECT_NE(err({{0.0, {5, 0, 0}}, {9e-315, {0, 0, 0}}}).find("sources[0].path[1].t: 9e-315 is less than 1 us after"),
            std::string::npos);
  EXPECT_NE(err({{2.0, {0, 0, 0}}, {2.0 + 0.9e-6, {1, 0, 0}}}).find("less than 1 us after"), std::string::npos);
  auto jump = Trajectory::fromKeyframes({{2.0, {-1e6, -1e6, -1e6}}, {2.0 + 1e-6, {1e6, 1e6, 1e6}}});
  ASSERT_TRUE(jump.isOk()) << jump.status().message();
  const Pose mid = jump->at(2.0 + 0.5e-6);
  EXPECT_TRUE(isFinite(mid.position) && isFinite(mid.velocity));
  EXPECT_GT(mid.velocity.x, 1e12);
  auto pose = Trajectory::fromPose({0, 0, 0}, {0, 0, 1}, {0, 0, 1}, "listener");
  ASSERT_FALSE(pose.isOk());
  EXPECT_EQ(pose.status().message().rfind("listener.up: ", 0), 0u) << pose.status().message();
}

}  // namespace
}  // namespace earshot
