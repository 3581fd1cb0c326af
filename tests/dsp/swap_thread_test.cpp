// IR replacement from a control thread while the audio thread processes:
// written to run under ThreadSanitizer (ctest label "tsan"); in a normal
// build it checks the hand-off end to end (every IR is eventually released,
// output stays finite and bounded).
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <thread>

#include "earshot/dsp/convolver.h"
#include "test_signals.h"

namespace earshot {
namespace {

TEST(SwapThread, ControlThreadSwapsWhileAudioRuns) {
  ConvolverSettings s;
  s.latencyFrames = 64;
  s.maxIrFrames = 8000;
  s.channels = 2;
  auto conv = Convolver::create(s);
  ASSERT_TRUE(conv.isOk());
  Convolver& c = **conv;
  std::vector<std::weak_ptr<const PreparedIr>> made;
  std::atomic<bool> stop{false};
  std::atomic<int> posted{0};
  std::thread control([&] {
    uint64_t seed = 1;
    while (!stop.load()) {
      std::vector<std::vector<float>> ir = {test::decayingNoise(8000, seed), test::decayingNoise(8000, seed + 1)};
      seed += 2;
      auto p = PreparedIr::create(ir, c.layout());
      if (!p.isOk()) break;
      made.push_back(*p);
      if (!c.setIr(*p).isOk()) break;
      posted.fetch_add(1);
      std::this_thread::yield();
    }
  });
  std::vector<float> in(64), l(64), r(64);
  float* outs[2] = {l.data(), r.data()};
  double peak = 0;
  for (int block = 0; block < 3000 || posted.load() < 20; ++block) {
    for (size_t i = 0; i < 64; ++i) in[i] = static_cast<float>(std::sin(0.05 * (block * 64 + i)));
    c.process(in.data(), outs, 64);
    for (size_t i = 0; i < 64; ++i) {
      ASSERT_TRUE(std::isfinite(l[i]) && std::isfinite(r[i]));
      peak = std::max(peak, static_cast<double>(std::fabs(l[i])));
    }
  }
  stop = true;
  control.join();
  EXPECT_GE(posted.load(), 20);
  // |y| <= sum |h| * max |x|; decayingNoise has sum |h| < 8000 * 0.5 / ln-ish,
  // far below 1e4: a broken hand-off (freed IR) would show as garbage.
  EXPECT_LT(peak, 1e4);
  EXPECT_GT(peak, 0.1);
  c.collectGarbage();
  conv->reset();
  for (auto& w : made) EXPECT_TRUE(w.expired());
}

}  // namespace
}  // namespace earshot
