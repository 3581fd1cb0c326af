// Real spherical harmonics (AmbiX) and their rotation (issue 15).
#include "earshot/ir/spherical_harmonics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "earshot/core/math.h"

namespace earshot {
namespace {

Vec3d fibonacci(int i, int n) {
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  const double z = 1.0 - 2.0 * (i + 0.5) / n, r = std::sqrt(1.0 - z * z);
  return {r * std::cos(golden * i), r * std::sin(golden * i), z};
}

Rotation3 randomRotation(std::mt19937_64& rng) {
  // A uniformly random unit quaternion (Shoemake).
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double u1 = u(rng), u2 = u(rng), u3 = u(rng);
  const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
  const double w = a * std::sin(2 * kPi * u2), x = a * std::cos(2 * kPi * u2), y = b * std::sin(2 * kPi * u3),
               z = b * std::cos(2 * kPi * u3);
  return {1 - 2 * (y * y + z * z), 2 * (x * y - z * w),     2 * (x * z + y * w),
          2 * (x * y + z * w),     1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
          2 * (x * z - y * w),     2 * (y * z + x * w),     1 - 2 * (x * x + y * y)};
}

TEST(SphericalHarmonics, Sn3dNormsAndOrthogonality) {
  // Mean over the sphere of Y_i Y_j: 1/(2n+1) on the diagonal, 0 elsewhere.
  constexpr int kN = 20000, C = kMaxAmbisonicChannels;
  std::vector<double> mean(C * C, 0.0);
  double y[C];
  for (int i = 0; i < kN; ++i) {
    realSphericalHarmonics(fibonacci(i, kN), 3, y);
    for (int a = 0; a < C; ++a)
      for (int b = 0; b < C; ++b) mean[a * C + b] += y[a] * y[b] / kN;
  }
  for (int a = 0; a < C; ++a)
    for (int b = 0; b < C; ++b) {
      const double want = a == b ? 1.0 / (2 * ambisonicOrderOf(a) + 1) : 0.0;
      EXPECT_NEAR(mean[a * C + b], want, 1e-3) << a << "," << b;
    }
}

TEST(SphericalHarmonics, KnownDirections) {
  double y[16];
  realSphericalHarmonics(Vec3d(0, 1, 0), 3, y);  // left
  EXPECT_DOUBLE_EQ(y[0], 1.0);
  EXPECT_DOUBLE_EQ(y[1], 1.0);   // Y
  EXPECT_DOUBLE_EQ(y[3], 0.0);   // X
  EXPECT_NEAR(y[9], -std::sqrt(5.0 / 8.0), 1e-15);  // Q = sqrt(5/8) y (3x^2 - y^2)
  realSphericalHarmonics(Vec3d(0, 0, 1), 3, y);  // up
  EXPECT_DOUBLE_EQ(y[2], 1.0);
  EXPECT_DOUBLE_EQ(y[6], 1.0);
  EXPECT_DOUBLE_EQ(y[12], 1.0);
}

TEST(SphericalHarmonics, WorldToAmbisonicFrame) {
  // glTF listener: forward -Z, up +Y; so world -Z is x, world -X is y (left), +Y is z.
  const Rotation3 r = worldToAmbisonicFrame({0, 0, -1}, {0, 1, 0});
  const Vec3d f = rotate(r, {0, 0, -1}), l = rotate(r, {-1, 0, 0}), u = rotate(r, {0, 1, 0});
  EXPECT_NEAR(f.x, 1, 1e-12);
  EXPECT_NEAR(l.y, 1, 1e-12);
  EXPECT_NEAR(u.z, 1, 1e-12);
}

TEST(SphericalHarmonics, RotationOfEncodingIsEncodingOfRotatedDirection) {
  // Encode at d, rotate by M(R): equals the encoding at R d, for random R and d, orders 1-3.
  std::mt19937_64 rng(15);
  ShRotation rotation;
  std::vector<float> m(kMaxAmbisonicChannels * kMaxAmbisonicChannels);
  for (int order = 1; order <= 3; ++order)
    for (int trial = 0; trial < 50; ++trial) {
      const Rotation3 r = randomRotation(rng);
      rotation.compute(r, order, m.data());
      std::normal_distribution<double> g;
      const Vec3d d = normalize(Vec3d(g(rng), g(rng), g(rng)));
      double y[16], yr[16];
      realSphericalHarmonics(d, order, y);
      realSphericalHarmonics(rotate(r, d), order, yr);
      const int c = ambisonicChannels(order);
      for (int i = 0; i < c; ++i) {
        double v = 0;
        for (int j = 0; j < c; ++j) v += double(m[i * kMaxAmbisonicChannels + j]) * y[j];
        ASSERT_NEAR(v, yr[i], 1e-5) << "order " << order << " channel " << i;
      }
      // Entries beyond the order are zero.
      for (int i = c; i < kMaxAmbisonicChannels; ++i) ASSERT_EQ(m[i * kMaxAmbisonicChannels + i], 0.0f);
    }
}

}  // namespace
}  // namespace earshot
