// Issue 20: the late noise of an IR depends on the source/listener pair, so
// that averaging metrics over positions (as every room-acoustics
// measurement does) averages the synthesis noise out, while the same inputs
// still give the same bits.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "../propagation/shoebox_fixture.h"
#include "earshot/analysis/compare.h"
#include "earshot/analysis/room_acoustics.h"
#include "earshot/core/thread_pool.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/ir/ir_synthesis.h"

namespace earshot {
namespace {

using analysis::Metric;

TEST(NoiseKey, DependsOnBothPositionsAndIsSymmetric) {
  const Vec3d a{2, 3, 1.5}, b{7, 4, 1.6}, c{7, 4, 1.6000001};
  EXPECT_EQ(noiseKeyOf(a, b), noiseKeyOf(b, a));
  EXPECT_NE(noiseKeyOf(a, b), noiseKeyOf(a, c));
  EXPECT_NE(noiseKeyOf(a, b), 0u);
  EXPECT_EQ(noiseKeyOf({0.0, 1, 2}, b), noiseKeyOf({-0.0, 1, 2}, b));
}

// Two pairs, one seed: the late parts are uncorrelated (they were the same
// noise before); the same pair twice gives the same bits.
TEST(NoiseKey, DifferentPairsGetUncorrelatedTailsAndTheSamePairTheSameBits) {
  testing::Shoebox room(0.1f, 1.0f);
  ThreadPool pool(2);
  OmniIrSettings s;
  s.rays = 4096;
  s.bounces = 8;
  s.imageSourceOrder = 0;
  s.lengthSeconds = 1.0;
  s.seed = 7;
  auto a = computeIr(*room.tracer, room.materials, {2, 3, 1.5}, {7, 4, 1.6}, s, pool, nullptr);
  auto a2 = computeIr(*room.tracer, room.materials, {2, 3, 1.5}, {7, 4, 1.6}, s, pool, nullptr);
  // The same geometry of the pair, moved 1 mm: the energies barely change.
  auto b = computeIr(*room.tracer, room.materials, {2, 3, 1.501}, {7, 4, 1.6}, s, pool, nullptr);
  ASSERT_TRUE(a.isOk() && a2.isOk() && b.isOk());
  EXPECT_EQ(a->ir.channels[0], a2->ir.channels[0]);
  const auto& x = a->ir.channels[0];
  const auto& y = b->ir.channels[0];
  ASSERT_EQ(x.size(), y.size());
  // From 0.1 s (well past the direct sound and first reflections) on.
  double xy = 0, xx = 0, yy = 0;
  for (size_t i = size_t(0.1 * s.sampleRateHz); i < x.size(); ++i) {
    xy += double(x[i]) * y[i];
    xx += double(x[i]) * x[i];
    yy += double(y[i]) * y[i];
  }
  const double rho = xy / std::sqrt(xx * yy);
  EXPECT_LT(std::fabs(rho), 0.1) << "tails of two positions correlate: " << rho;
  EXPECT_NEAR(xx / yy, 1.0, 0.1);  // same energy
}

// Standard deviation across seeds, in JND of `metric` about the seeds' mean.
double spreadInJnd(Metric metric, const std::vector<double>& perSeed) {
  double mean = 0;
  for (double v : perSeed) mean += v / double(perSeed.size());
  double ss = 0;
  for (double v : perSeed) {
    const double d = analysis::differenceInJnd(metric, v, mean);
    ss += d * d;
  }
  return std::sqrt(ss / double(perSeed.size() - 1));
}

// Must show (issue 20): metrics averaged over 10 source/listener pairs
// converge: the average's spread from seed to seed (standard deviation over
// 6 seeds) is at most 0.5 JND, and about the single pair's spread /
// sqrt(10), as for independent noise. Measured: 0.03 - 0.21 JND from 250 Hz
// to 8 kHz; with one noise for every pair (as before) the range over 5 seeds
// was 0.4 - 4.5 JND (0.05 - 0.54 now). At 125 Hz one IR's EDT and D50
// spread by ~2 JND (an octave band 88 Hz wide has ~12 degrees of freedom in
// the EDT's first 0.14 s here), so 10 pairs give ~1.0 JND: 0.5 would take
// ~40 pairs. There only the 1/sqrt(N) convergence is asserted.
TEST(NoiseKey, PositionAveragedMetricsConvergeAcrossSeeds) {
  testing::Shoebox room(0.15f, 0.6f);
  ThreadPool pool(2);
  const std::array<std::pair<Vec3d, Vec3d>, 10> pairs = {{
      {{2.0, 3.0, 1.5}, {7.0, 4.0, 1.6}}, {{1.5, 1.5, 1.2}, {8.0, 5.5, 1.4}}, {{3.0, 5.0, 1.7}, {6.5, 2.0, 1.2}},
      {{5.0, 3.5, 1.5}, {8.5, 1.5, 1.6}}, {{1.2, 6.0, 2.0}, {4.0, 2.0, 1.2}}, {{8.8, 6.0, 1.3}, {2.5, 1.0, 1.8}},
      {{4.5, 1.2, 2.2}, {5.5, 6.0, 1.1}}, {{7.5, 3.0, 0.8}, {2.0, 5.0, 2.3}}, {{3.5, 2.5, 1.0}, {9.0, 3.5, 1.9}},
      {{6.0, 5.5, 2.1}, {1.0, 2.5, 1.5}},
  }};
  const std::array<Metric, 4> metrics = {Metric::kEdt, Metric::kT20, Metric::kC80, Metric::kD50};
  constexpr int kSeeds = 6;
  // value[band][metric][pair][seed]
  std::vector<std::vector<std::vector<std::vector<double>>>> value(
      kNumBands, std::vector<std::vector<std::vector<double>>>(
                     metrics.size(), std::vector<std::vector<double>>(pairs.size(), std::vector<double>(kSeeds))));
  for (int seed = 0; seed < kSeeds; ++seed) {
    OmniIrSettings s;  // the balanced preset's budget
    s.seed = uint64_t(seed) + 1;
    for (size_t p = 0; p < pairs.size(); ++p) {
      auto ir = computeIr(*room.tracer, room.materials, pairs[p].first, pairs[p].second, s, pool, nullptr);
      ASSERT_TRUE(ir.isOk()) << ir.status().message();
      auto m = analysis::analyzeIr(ir->ir.channels[0], ir->ir.sampleRateHz);
      ASSERT_TRUE(m.isOk()) << m.status().message();
      for (int b = 0; b < kNumBands; ++b)
        for (size_t k = 0; k < metrics.size(); ++k) {
          const double v = (*m)[size_t(b)].value(metrics[k]);
          ASSERT_TRUE(std::isfinite(v)) << analysis::metricName(metrics[k]) << " band " << b;
          value[size_t(b)][k][p][size_t(seed)] = v;
        }
    }
  }
  double worst = 0;
  for (int b = 0; b < kNumBands; ++b)
    for (size_t k = 0; k < metrics.size(); ++k) {
      std::vector<double> average(kSeeds, 0.0);
      double single = 0;  // RMS over pairs of one pair's spread
      for (size_t p = 0; p < pairs.size(); ++p) {
        const double sp = spreadInJnd(metrics[k], value[size_t(b)][k][p]);
        single += sp * sp / double(pairs.size());
        for (int seed = 0; seed < kSeeds; ++seed)
          average[size_t(seed)] += value[size_t(b)][k][p][size_t(seed)] / double(pairs.size());
      }
      single = std::sqrt(single);
      const double spread = spreadInJnd(metrics[k], average);
      const std::string what = std::string(analysis::metricName(metrics[k])) + " at " +
                               std::to_string(int(kBandCentersHz[size_t(b)])) + " Hz";
      if (std::getenv("EARSHOT_SPREAD")) std::printf("%s: one pair %.2f JND, 10-pair average %.2f JND\n", what.c_str(), single, spread);
      // 1/sqrt(10) with room for a 6-seed estimate of a spread (+-30 %).
      EXPECT_LE(spread, 1.6 * single / std::sqrt(double(pairs.size()))) << what << ": one pair spreads " << single;
      if (b > 0) {
        EXPECT_LE(spread, 0.5) << what;
        worst = std::max(worst, spread);
      }
    }
  std::printf("worst seed-to-seed spread of a 10-pair average, 250 Hz - 8 kHz: %.2f JND\n", worst);
}

}  // namespace
}  // namespace earshot
