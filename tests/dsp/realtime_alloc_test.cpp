// Fails on any heap allocation or release inside process() and the audio
// side of the IR hand-off (tests/support/alloc_hook.cpp counts them).
#include <gtest/gtest.h>

#include <cstdlib>

#include "earshot/dsp/convolver.h"
#include "../support/alloc_hook.h"
#include "test_signals.h"

namespace earshot {
namespace {

int* volatile gSink = nullptr;
void* volatile gSinkRaw = nullptr;

using Armed = test::AllocationCounter;

// The hook itself works: an allocation while armed is seen (so the tests
// below could fail).
TEST(RealtimeAlloc, HookSeesAllocations) {
  long allocs, frees;
  {
    Armed a;
    gSink = new int(3);  // through a volatile global: new/delete pairs may be elided
    void* q = std::malloc(16);
    gSinkRaw = q;
    std::free(gSinkRaw);
    delete gSink;
    allocs = a.allocations();
    frees = a.releases();
  }
  if (test::mallocIsHooked()) {
    EXPECT_GE(allocs, 2);  // new and malloc
    EXPECT_GE(frees, 2);
  } else {
    EXPECT_GE(allocs, 1);  // sanitizer builds own malloc: only new/delete are seen
    EXPECT_GE(frees, 1);
  }
}

// process() with varying block sizes, IR pick-up, crossfades and retiring
// the replaced IR allocate and free nothing; the replaced IR is destroyed
// only by collectGarbage() on the control side.
TEST(RealtimeAlloc, ProcessAndIrHandOffDoNotAllocate) {
  ConvolverSettings s;
  s.latencyFrames = 256;
  s.maxIrFrames = 96000;
  s.channels = 2;
  auto mixer = ConvolutionMixer::create(s, 3);
  ASSERT_TRUE(mixer.isOk());
  ConvolutionMixer& m = **mixer;
  auto makeIr = [&](uint64_t seed) {
    std::vector<std::vector<float>> ir = {test::decayingNoise(96000, seed), test::decayingNoise(96000, seed + 1)};
    auto p = PreparedIr::create(ir, m.layout());
    EXPECT_TRUE(p.isOk());
    return *p;
  };
  std::vector<float> in(5000);
  for (size_t i = 0; i < in.size(); ++i) in[i] = static_cast<float>((i * 7919) % 101) / 50.0f - 1.0f;
  std::vector<std::vector<float>> out(2, std::vector<float>(5000));
  float* outs[2] = {out[0].data(), out[1].data()};
  const float* ins[3] = {in.data(), nullptr, in.data()};
  const size_t sizes[] = {1, 7, 256, 1000, 4096, 33, 512, 3};

  std::weak_ptr<const PreparedIr> first;
  {
    auto a = makeIr(1);
    first = a;
    ASSERT_TRUE(m.setIr(0, a).isOk());
    ASSERT_TRUE(m.setIr(2, makeIr(5)).isOk());
  }
  long allocs = 0, frees = 0;
  {
    Armed armed;
    for (int rep = 0; rep < 30; ++rep)
      for (size_t b : sizes) m.process(ins, outs, b);
    allocs = armed.allocations();
    frees = armed.releases();
  }
  EXPECT_EQ(allocs, 0);
  EXPECT_EQ(frees, 0);

  // Replace the IR of source 0; the old one's last reference is the mixer's.
  ASSERT_TRUE(m.setIr(0, makeIr(3)).isOk());
  ASSERT_TRUE(m.setIr(1, makeIr(7)).isOk());
  EXPECT_FALSE(first.expired());
  {
    Armed armed;
    for (int rep = 0; rep < 60; ++rep)
      for (size_t b : sizes) m.process(ins, outs, b);
    allocs = armed.allocations();
    frees = armed.releases();
  }
  EXPECT_EQ(allocs, 0) << "allocation on the audio thread";
  EXPECT_EQ(frees, 0) << "release on the audio thread";
  EXPECT_FALSE(first.expired()) << "old IR must wait for the control side";
  m.collectGarbage();
  EXPECT_TRUE(first.expired()) << "old IR released by collectGarbage()";
}

}  // namespace
}  // namespace earshot
