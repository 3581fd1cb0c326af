#include <gtest/gtest.h>

#include <set>

#include "earshot/core/random.h"

namespace earshot {

TEST(Pcg32, SameSeedAndStreamGiveTheSameSequence) {
  Pcg32 a(42, 7), b(42, 7);
  for (int i = 0; i < 1000; ++i) ASSERT_EQ(a.next(), b.next());
}

TEST(Pcg32, DifferentStreamsDiffer) {
  Pcg32 a(42, 7), b(42, 8);
  int same = 0;
  for (int i = 0; i < 1000; ++i) same += a.next() == b.next();
  EXPECT_LT(same, 3);
}

TEST(Pcg32, UniformMeanAndRangeAreRight) {
  Pcg32 r(1, 1);
  double sum = 0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    float u = r.uniform();
    ASSERT_GE(u, 0.0f);
    ASSERT_LT(u, 1.0f);
    sum += u;
  }
  // Mean of U(0,1) is 1/2 with standard error 1/sqrt(12 n) ~ 6.5e-4.
  EXPECT_NEAR(sum / n, 0.5, 5 * 6.5e-4);
}

}  // namespace earshot
