// The process's memory limit and a thread's share of it (input_file.h).
#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "earshot/io/input_file.h"

namespace earshot {
namespace {

class MemoryLimit : public ::testing::Test {
 protected:
  void SetUp() override { setDefaultMaxMemoryBytes(1000); }
  void TearDown() override { setDefaultMaxMemoryBytes(0); }
};

TEST_F(MemoryLimit, AnEstimateOverTheLimitOrNaNIsRefused) {
  EXPECT_TRUE(checkMemoryEstimate(1000, "x").isOk());
  const Status over = checkMemoryEstimate(1001, "a trace");
  EXPECT_EQ(over.code(), StatusCode::kOutOfRange);
  EXPECT_NE(over.message().find("a trace needs about 1001 bytes, over the memory limit of 1000 bytes"),
            std::string::npos)
      << over.message();
  const Status nan = checkMemoryEstimate(std::nan(""), "x");
  EXPECT_FALSE(nan.isOk());
  // The message counted no bytes: uint64_t(NaN) was undefined (the ASan
  // build's float-cast-overflow check found it).
  EXPECT_NE(nan.message().find("x needs an amount that is not a number, over the memory limit"), std::string::npos)
      << nan.message();
}

TEST_F(MemoryLimit, AShareRefusesWhatPassesItsShareAndRemembersIt) {
  MemoryLimitShare share(400);
  EXPECT_TRUE(checkMemoryEstimate(400, "x").isOk());
  EXPECT_FALSE(share.refusedWithinTheLimit());
  // Over the limit: refused as before, and not the share's refusal (alone
  // it would be refused too).
  EXPECT_NE(checkMemoryEstimate(1001, "x").message().find("over the memory limit of 1000 bytes"), std::string::npos);
  EXPECT_FALSE(share.refusedWithinTheLimit());
  const Status st = checkMemoryEstimate(401, "an IR");
  EXPECT_EQ(st.code(), StatusCode::kOutOfRange);
  EXPECT_NE(st.message().find("over this thread's share (400 bytes) of the memory limit of 1000 bytes"),
            std::string::npos)
      << st.message();
  EXPECT_TRUE(share.refusedWithinTheLimit());
}

TEST_F(MemoryLimit, ASharesOnItsThreadAndWhileItLives) {
  {
    MemoryLimitShare share(100);
    // Another thread has no share.
    bool otherOk = false;
    std::thread([&] { otherOk = checkMemoryEstimate(900, "x").isOk(); }).join();
    EXPECT_TRUE(otherOk);
    EXPECT_FALSE(checkMemoryEstimate(900, "x").isOk());
    {
      // The innermost share counts; its refusal is its outer share's too.
      MemoryLimitShare inner(950);
      EXPECT_TRUE(checkMemoryEstimate(900, "x").isOk());
      EXPECT_FALSE(checkMemoryEstimate(960, "x").isOk());
      EXPECT_TRUE(inner.refusedWithinTheLimit());
    }
    EXPECT_TRUE(share.refusedWithinTheLimit());
    EXPECT_FALSE(checkMemoryEstimate(900, "x").isOk());
  }
  EXPECT_TRUE(checkMemoryEstimate(900, "x").isOk());
  // A share above the limit changes nothing.
  MemoryLimitShare wide(5000);
  EXPECT_FALSE(checkMemoryEstimate(1001, "x").isOk());
  EXPECT_FALSE(wide.refusedWithinTheLimit());
}

}  // namespace
}  // namespace earshot
