// Real spherical harmonics (AmbiX: ACN, SN3D) and their rotation; see the header.
#include "earshot/ir/spherical_harmonics.h"

#include <Eigen/Dense>
#include <cmath>

#include "earshot/core/math.h"

namespace earshot {

namespace {

template <class T>
void harmonics(T x, T y, T z, int order, T* out) {
  out[0] = T(1);
  if (order < 1) return;
  out[1] = y;
  out[2] = z;
  out[3] = x;
  if (order < 2) return;
  const T s3 = T(1.7320508075688772);  // sqrt(3)
  out[4] = s3 * x * y;
  out[5] = s3 * y * z;
  out[6] = T(0.5) * (T(3) * z * z - T(1));
  out[7] = s3 * x * z;
  out[8] = T(0.5) * s3 * (x * x - y * y);
  if (order < 3) return;
  const T s58 = T(0.7905694150420949);  // sqrt(5/8)
  const T s15 = T(3.872983346207417);   // sqrt(15)
  const T s38 = T(0.6123724356957945);  // sqrt(3/8)
  out[9] = s58 * y * (T(3) * x * x - y * y);
  out[10] = s15 * x * y * z;
  out[11] = s38 * y * (T(5) * z * z - T(1));
  out[12] = T(0.5) * z * (T(5) * z * z - T(3));
  out[13] = s38 * x * (T(5) * z * z - T(1));
  out[14] = T(0.5) * s15 * z * (x * x - y * y);
  out[15] = s58 * x * (x * x - T(3) * y * y);
}

constexpr int kRotationDirections = 64;

}  // namespace

int ambisonicOrderOf(int acn) {
  int n = 0;
  while ((n + 1) * (n + 1) <= acn) ++n;
  return n;
}

void realSphericalHarmonics(const Vec3d& d, int order, double* out) { harmonics(d.x, d.y, d.z, order, out); }
void realSphericalHarmonics(const Vec3f& d, int order, float* out) { harmonics(d.x, d.y, d.z, order, out); }

Rotation3 worldToAmbisonicFrame(const Vec3d& forward, const Vec3d& up) {
  const Vec3d f = normalize(forward);
  const Vec3d l = normalize(cross(up, f));
  const Vec3d u = cross(f, l);
  return {f.x, f.y, f.z, l.x, l.y, l.z, u.x, u.y, u.z};
}

Vec3d rotate(const Rotation3& r, const Vec3d& d) {
  return {r[0] * d.x + r[1] * d.y + r[2] * d.z, r[3] * d.x + r[4] * d.y + r[5] * d.z,
          r[6] * d.x + r[7] * d.y + r[8] * d.z};
}

Rotation3 relativeRotation(const Rotation3& to, const Rotation3& from) {
  Rotation3 r{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) r[size_t(i * 3 + j)] += to[size_t(i * 3 + k)] * from[size_t(j * 3 + k)];
  return r;
}

ShRotation::ShRotation() {
  constexpr int K = kRotationDirections, C = kMaxAmbisonicChannels;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  Eigen::MatrixXd y(C, K);
  for (int k = 0; k < K; ++k) {
    const double z = 1.0 - 2.0 * (k + 0.5) / K, r = std::sqrt(std::max(0.0, 1.0 - z * z));
    mDirections.push_back({r * std::cos(golden * k), r * std::sin(golden * k), z});
    double h[C];
    harmonics(mDirections.back().x, mDirections.back().y, mDirections.back().z, kMaxAmbisonicOrder, h);
    for (int c = 0; c < C; ++c) y(c, k) = h[c];
  }
  // pinv(Y) = Y^T (Y Y^T)^-1 (Y has full row rank on these directions).
  const Eigen::MatrixXd p = y.transpose() * (y * y.transpose()).inverse();
  mPinv.resize(size_t(K) * C);
  for (int k = 0; k < K; ++k)
    for (int c = 0; c < C; ++c) mPinv[size_t(k) * C + size_t(c)] = p(k, c);
}

void ShRotation::compute(const Rotation3& r, int order, float* m) const {
  constexpr int C = kMaxAmbisonicChannels;
  for (int i = 0; i < C * C; ++i) m[i] = 0.0f;
  const int channels = ambisonicChannels(order);
  double acc[C * C] = {};
  double h[C];
  for (size_t k = 0; k < mDirections.size(); ++k) {
    const Vec3d& d = mDirections[k];
    const Vec3d rd = rotate(r, d);
    harmonics(rd.x, rd.y, rd.z, order, h);
    const double* p = &mPinv[k * C];
    // Only the blocks of equal order are non-zero.
    for (int n = 0; n <= order; ++n)
      for (int i = n * n; i < (n + 1) * (n + 1); ++i)
        for (int j = n * n; j < (n + 1) * (n + 1); ++j) acc[i * C + j] += h[i] * p[j];
  }
  for (int i = 0; i < channels; ++i)
    for (int j = 0; j < channels; ++j) m[i * C + j] = float(acc[i * C + j]);
}

}  // namespace earshot
