// The reflection tracer's fixed-point conversion (src/propagation/fixed_point.h):
// the batch conversion, with AVX or without, gives the scalar one's bits for
// every value, the rounding ties, the limits of its exact path, NaN and the
// infinities included.
#include "fixed_point.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace earshot::detail {
namespace {

// Values the batch must convert as toFixed() does.
std::vector<double> hardValues() {
  const double inv = 1.0 / kFixedScale;
  std::vector<double> v = {0.0, -0.0, 1.0, -1.0, 0.5 * inv, -0.5 * inv, 1.5 * inv, -1.5 * inv, 2.5 * inv,
                           -2.5 * inv,
                           0.49999999999999994 * inv,  // + 0.5 rounds to 1.0: 1, in either path std::numeric_limits<double>::denorm_min(),
                           std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                           -std::numeric_limits<double>::infinity(), 8192.0, -8192.0, 1e4, -1e4, 1e300};
  // Around the exact path's limit, 2^51 - 2 on the fixed scale, and 2^52
  // (where doubles stop having halves).
  for (double s : {2251799813685246.0, 4503599627370496.0})
    for (double d = -3; d <= 3; d += 0.5) {
      v.push_back((s + d) * inv);
      v.push_back(-(s + d) * inv);
    }
  // Ties k + 1/2 at every scale the exact path covers.
  for (int e = 0; e < 51; ++e) {
    const double k = std::ldexp(1.0, e);
    v.push_back((k + 0.5) * inv);
    v.push_back(-(k + 0.5) * inv);
  }
  return v;
}

void expectBatchEqualsScalar(const std::vector<double>& values, bool avx) {
  // In batches, each value at every position of a batch once.
  for (size_t start = 0; start < values.size(); ++start) {
    double v[kFixedBatch];
    for (size_t k = 0; k < kFixedBatch; ++k) v[k] = values[(start + k) % values.size()];
    int64_t q[kFixedBatch];
    toFixedBatch(v, q, avx);
    for (size_t k = 0; k < kFixedBatch; ++k) ASSERT_EQ(q[k], toFixed(v[k])) << "value " << v[k] << " avx " << avx;
  }
}

// At run time: with a NaN known at compile time GCC folds the clamp's
// minsd as a plain min (NaN order undefined) and gets INT64_MIN (checked,
// GCC 12 -O2); the tracer converts only computed values.
int64_t fixedOf(double v) {
  volatile double x = v;
  return toFixed(x);
}

TEST(FixedPoint, ScalarRoundsHalfAwayFromZeroAndClampsNaNAndInfinities) {
  const double inv = 1.0 / kFixedScale;
  EXPECT_EQ(fixedOf(1.0), int64_t(1) << 50);
  EXPECT_EQ(fixedOf(0.5 * inv), 1);
  EXPECT_EQ(fixedOf(-0.5 * inv), -1);
  EXPECT_EQ(fixedOf(2.5 * inv), 3);
  EXPECT_EQ(fixedOf(0.25 * inv), 0);
  EXPECT_EQ(fixedOf(-0.0), 0);
  const int64_t top = int64_t(kFixedMax + 0.5);
  EXPECT_EQ(fixedOf(std::numeric_limits<double>::quiet_NaN()), top);
  EXPECT_EQ(fixedOf(std::numeric_limits<double>::infinity()), top);
  EXPECT_EQ(fixedOf(-std::numeric_limits<double>::infinity()), -top);
}

TEST(FixedPoint, AddSaturatesInsteadOfOverflowing) {
  int64_t a = INT64_MAX - 1;
  addSat(a, 5);
  EXPECT_EQ(a, INT64_MAX);
  int64_t b = INT64_MIN + 1;
  addSat(b, -5);
  EXPECT_EQ(b, INT64_MIN);
  int64_t c = 7;
  addSat(c, -9);
  EXPECT_EQ(c, -2);
}

TEST(FixedPoint, BatchGivesTheScalarBitsWithAndWithoutAvx) {
  std::vector<double> values = hardValues();
  // Random values over the detections' range of scales, both signs.
  std::mt19937_64 rng(20261127);
  std::uniform_real_distribution<double> mantissa(1.0, 2.0);
  std::uniform_int_distribution<int> exponent(-70, 16);
  for (int i = 0; i < 20000; ++i) {
    const double x = std::ldexp(mantissa(rng), exponent(rng));
    values.push_back(i % 2 ? x : -x);
  }
  expectBatchEqualsScalar(values, false);
#if defined(EARSHOT_FIXED_AVX)
  if (!__builtin_cpu_supports("avx")) GTEST_SKIP() << "no AVX on this CPU: the scalar path only";
  expectBatchEqualsScalar(values, true);
#endif
}

}  // namespace
}  // namespace earshot::detail
