#include "earshot/dsp/partition_layout.h"

#include <gtest/gtest.h>

namespace earshot {
namespace {

// The layout covers the IR, starts with latency-sized partitions, doubles
// grows the partition size by powers of two level by level, and every level >= 1 starts late
// enough (offset >= 2P - 2N) for its work to be spread over P/N steps.
TEST(PartitionLayout, CoversIrAndMeetsDeadlines) {
  for (size_t n : {16u, 64u, 256u, 1000u, 1024u}) {
    for (size_t len : {1u, 500u, 48000u, 192000u}) {
      ConvolverSettings s;
      s.latencyFrames = n;
      s.maxIrFrames = len;
      auto l = PartitionLayout::create(s);
      ASSERT_TRUE(l.isOk()) << l.status().message();
      const auto& lv = l->levels();
      ASSERT_FALSE(lv.empty());
      EXPECT_EQ(lv[0].partitionFrames, n);
      EXPECT_EQ(lv[0].offsetFrames, 0u);
      EXPECT_GE(l->capacityFrames(), len);
      size_t offset = 0;
      for (size_t i = 0; i < lv.size(); ++i) {
        EXPECT_EQ(lv[i].offsetFrames, offset);
        if (i > 0) {
          EXPECT_GT(lv[i].partitionFrames, lv[i - 1].partitionFrames);
          EXPECT_EQ(lv[i].partitionFrames % lv[i - 1].partitionFrames, 0u);
          EXPECT_EQ(lv[i].offsetFrames, lv[i].inputDelayFrames + 2 * lv[i].partitionFrames - 2 * n);
        }
        EXPECT_EQ(lv[i].stepsPerBlock * n, lv[i].partitionFrames);
        EXPECT_GE(l->historyFrames(), 2 * lv[i].partitionFrames + lv[i].inputDelayFrames);
        offset += lv[i].partitionCount * lv[i].partitionFrames;
      }
      EXPECT_EQ(offset, l->capacityFrames());
    }
  }
}

TEST(PartitionLayout, LongIrUsesLargePartitions) {
  ConvolverSettings s;
  s.latencyFrames = 64;
  s.maxIrFrames = 96000;
  auto l = PartitionLayout::create(s);
  ASSERT_TRUE(l.isOk());
  EXPECT_GE(l->levels().back().partitionFrames, 2048u);
  size_t total = 0;
  for (const auto& lv : l->levels()) total += lv.partitionCount;
  EXPECT_LT(total, 96000u / 64u / 8u);  // far fewer than a uniform layout
}

}  // namespace
}  // namespace earshot
