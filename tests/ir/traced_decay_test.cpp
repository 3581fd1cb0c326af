// Issue 20, consistent reporting: the decay earshot reports per band
// (tracedDecay, `earshot ir --json` "decay") is the IR's: its octave bands'
// T20 and T30 (ISO 3382 analysis of the synthesised IR) agree within 5 %.
//
// Measured (seeds 11-13, alpha 0.08 and 0.3): 250 Hz - 4 kHz within 4 %
// for every single IR. At 125 Hz one IR scatters by up to 12 % (an octave 88
// Hz wide has few degrees of freedom), so there the mean over 6 seeds is
// compared. At 8 kHz the ISO filter reads 9 - 16 % more than the band's own
// decay at alpha 0.08: air absorption makes the 8 kHz band decay faster
// than the 4 kHz band, and the filter's skirt passes some of the slower 4 kHz
// reverberation (as it would in a measurement): asserted as a reading
// between the two bands' reported decays. The rays-in-flight t60
// (TailInfo::t60Seconds, formerly reported as the tail's "t60_s") differs
// from the IR's T20 by up to 12 %: it is not the IR's decay, and is now
// reported as "population_t60_s".
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "../propagation/shoebox_fixture.h"
#include "earshot/analysis/room_acoustics.h"
#include "earshot/core/thread_pool.h"
#include "earshot/ir/ir_pipeline.h"

namespace earshot {
namespace {

TEST(TracedDecay, IrOctaveBandsDecayAsReported) {
  ThreadPool pool(2);
  constexpr int kSeeds = 6;
  double worst = 0;
  for (float absorption : {0.08f, 0.3f}) {
    testing::Shoebox room(absorption, 0.5f);
    BandArrayD irT20{}, irT30{}, repT20{}, repT30{};
    for (int seed = 1; seed <= kSeeds; ++seed) {
      OmniIrSettings s;  // balanced
      s.seed = uint64_t(seed) + 10;
      auto r = computeIr(*room.tracer, room.materials, {2.1, 3.1, 1.3}, {6.7, 4.2, 1.7}, s, pool, nullptr);
      ASSERT_TRUE(r.isOk()) << r.status().message();
      const TracedDecay d = tracedDecay(*r);
      auto m = analysis::analyzeIr(r->ir.channels[0], r->ir.sampleRateHz);
      ASSERT_TRUE(m.isOk());
      for (int b = 0; b < kNumBands; ++b) {
        const size_t i = size_t(b);
        const double t20 = (*m)[i].t20S, t30 = (*m)[i].t30S;
        ASSERT_TRUE(std::isfinite(t20) && std::isfinite(t30) && std::isfinite(d.t20Seconds[i]) &&
                    std::isfinite(d.t30Seconds[i]));
        irT20[i] += t20 / kSeeds;
        irT30[i] += t30 / kSeeds;
        repT20[i] += d.t20Seconds[i] / kSeeds;
        repT30[i] += d.t30Seconds[i] / kSeeds;
        if (b == 0 || b == kNumBands - 1) continue;
        const double e20 = t20 / d.t20Seconds[i] - 1.0, e30 = t30 / d.t30Seconds[i] - 1.0;
        EXPECT_LE(std::fabs(e20), 0.05) << "alpha " << absorption << ", seed " << s.seed << ", "
                                        << kBandCentersHz[i] << " Hz: IR T20 " << t20 << " s, reported "
                                        << d.t20Seconds[i];
        EXPECT_LE(std::fabs(e30), 0.05) << "alpha " << absorption << ", seed " << s.seed << ", "
                                        << kBandCentersHz[i] << " Hz: IR T30 " << t30 << " s, reported "
                                        << d.t30Seconds[i];
        worst = std::max({worst, std::fabs(e20), std::fabs(e30)});
      }
    }
    EXPECT_LE(std::fabs(irT20[0] / repT20[0] - 1.0), 0.05) << "alpha " << absorption << ", 125 Hz T20 (6-seed mean)";
    EXPECT_LE(std::fabs(irT30[0] / repT30[0] - 1.0), 0.05) << "alpha " << absorption << ", 125 Hz T30 (6-seed mean)";
    const size_t top = kNumBands - 1;
    EXPECT_GE(irT20[top], 0.97 * repT20[top]) << "alpha " << absorption << ", 8 kHz";
    EXPECT_LE(irT20[top], repT20[top - 1]) << "alpha " << absorption << ", 8 kHz reads more than the 4 kHz band";
    std::printf("alpha %.2f: 125 Hz T20/T30 (6-seed means) %+.1f / %+.1f %%, 8 kHz %+.1f / %+.1f %% (4 kHz band's own "
                "decay %+.1f %%)\n",
                absorption, 100 * (irT20[0] / repT20[0] - 1), 100 * (irT30[0] / repT30[0] - 1),
                100 * (irT20[top] / repT20[top] - 1), 100 * (irT30[top] / repT30[top] - 1),
                100 * (repT20[top - 1] / repT20[top] - 1));
  }
  std::printf("reported decay vs each IR's T20/T30, 250 Hz - 4 kHz: worst %.1f %%\n", 100 * worst);
}

}  // namespace
}  // namespace earshot
