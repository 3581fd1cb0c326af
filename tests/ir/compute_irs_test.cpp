// computeIrs (issue 16): several sources at one listener, per source or from
// shared traces, the same whatever the thread count and however the sources
// are grouped into traces.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "earshot/core/thread_pool.h"
#include "earshot/io/input_file.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot {
namespace {

struct Room {
  MaterialTable materials;
  std::unique_ptr<RayTracer> tracer;
  explicit Room(float absorption = 0.3f) {
    Material m;
    m.name = "wall";
    m.absorption = filledBands(absorption);
    m.scattering = filledBands(0.4f);
    m.transmission = filledBands(0.0f);
    TriangleMesh mesh = makeBox({0, 0, 0}, {10, 7, 3}, materials.add(m));
    mesh.append(makeBox({4.5, 2.0, 0.0}, {4.7, 4.0, 2.0}, 0));  // a partition: shadow rays matter
    auto rt = RayTracer::create(mesh);
    EXPECT_TRUE(rt.isOk());
    tracer = std::move(rt.value());
  }
};

std::vector<IrRequest> ringOfSources(size_t n) {
  std::vector<IrRequest> out;
  for (size_t i = 0; i < n; ++i) {
    IrRequest r;
    const double a = 6.283185307179586 * double(i) / double(n);
    r.source = {5.0 + 3.5 * std::cos(a), 3.5 + 2.5 * std::sin(a), 0.8 + 0.05 * double(i % 20)};
    out.push_back(r);
  }
  return out;
}

}  // namespace

// 20 sources with a 30 s histogram: their sums exceed
// kSharedTraceBudgetBytes and they go through two traces, of 16 and 4
// sources on 1 thread, of 12 and 8 on 2 (traceMemoryBytes); every IR is
// the same bit for bit, and the same as the source's shared trace alone.
TEST(ComputeIrs, SharedTracesGiveTheSameIrsHoweverTheSourcesAreGrouped) {
  Room room;
  OmniIrSettings s;
  s.sampleRateHz = 8000;
  s.rays = 1000;
  s.bounces = 6;
  s.imageSourceOrder = 1;
  s.lengthSeconds = 30;
  const std::vector<IrRequest> requests = ringOfSources(20);
  const Vec3d listener{7.2, 2.6, 1.6};
  ThreadPool one(1), two(2);
  auto a = computeIrs(*room.tracer, room.materials, listener, requests, s, TraceMode::kShared, one);
  auto b = computeIrs(*room.tracer, room.materials, listener, requests, s, TraceMode::kShared, two);
  ASSERT_TRUE(a.isOk()) << a.status().message();
  ASSERT_TRUE(b.isOk()) << b.status().message();
  ASSERT_EQ(a->size(), requests.size());
  ASSERT_EQ(b->size(), requests.size());
  for (size_t i = 0; i < requests.size(); ++i) {
    EXPECT_EQ((*a)[i].ir.channels, (*b)[i].ir.channels) << "source " << i;
    EXPECT_GT((*a)[i].traceStats.shadowRays, 0u);
  }
  for (size_t i : {size_t(0), size_t(13)}) {
    auto alone = computeIrs(*room.tracer, room.materials, listener, {requests[i]}, s, TraceMode::kShared, two);
    ASSERT_TRUE(alone.isOk());
    EXPECT_EQ(alone->front().ir.channels, (*b)[i].ir.channels) << "source " << i;
  }
}

// Under a memory limit below kSharedTraceBudgetBytes (--max-memory 48M)
// the sources go through traces of two (~20 MB each with a 30 s histogram
// on 2 threads; the six together would be refused), and the IRs are the
// bits of the unlimited run. Below one source's trace, an error naming
// the limit.
TEST(ComputeIrs, UnderAMemoryLimitSharedTracesTakeFewerSourcesAndGiveTheSameIrs) {
  Room room;
  OmniIrSettings s;
  s.sampleRateHz = 8000;
  s.rays = 1000;
  s.bounces = 6;
  s.imageSourceOrder = 1;
  s.lengthSeconds = 30;
  const std::vector<IrRequest> requests = ringOfSources(6);
  const Vec3d listener{7.2, 2.6, 1.6};
  ThreadPool pool(2);
  auto whole = computeIrs(*room.tracer, room.materials, listener, requests, s, TraceMode::kShared, pool);
  ASSERT_TRUE(whole.isOk()) << whole.status().message();
  struct Restore {
    InputLimits saved = defaultInputLimits();
    ~Restore() { setDefaultInputLimits(saved); }
  } restore;
  InputLimits low = restore.saved;
  low.maxMemoryBytes = uint64_t(48) << 20;
  setDefaultInputLimits(low);
  auto limited = computeIrs(*room.tracer, room.materials, listener, requests, s, TraceMode::kShared, pool);
  ASSERT_TRUE(limited.isOk()) << limited.status().message();
  ASSERT_EQ(limited->size(), requests.size());
  for (size_t i = 0; i < requests.size(); ++i)
    EXPECT_EQ((*limited)[i].ir.channels, (*whole)[i].ir.channels) << "source " << i;
  low.maxMemoryBytes = uint64_t(8) << 20;
  setDefaultInputLimits(low);
  auto refused = computeIrs(*room.tracer, room.materials, listener, requests, s, TraceMode::kShared, pool);
  ASSERT_FALSE(refused.isOk());
  EXPECT_EQ(refused.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(refused.status().message().find("--max-memory"), std::string::npos) << refused.status().message();
}

// A ListenerCache kept between shared simulations: from the same place the
// second simulation traces no ray, makes no tail rates and searches no
// image-source candidates, and its IRs are the same bits as without the cache; from another place
// both are made anew. The room has 14 boxes in it (over 64 planes: the
// image sources' candidates come from rays).
TEST(ComputeIrs, AListenerCacheGivesTheSameIrs) {
  Room room;
  TriangleMesh mesh = room.tracer->mesh();
  for (int i = 0; i < 14; ++i) {  // boxes apart in every coordinate: no faces coplanar
    const double x = 0.8 + 0.61 * double(i), y = 0.7 + 0.37 * double(i % 7), z = 0.05 + 0.09 * double(i);
    mesh.append(makeBox({x, y, z}, {x + 0.2 + 0.01 * double(i), y + 0.25, z + 0.3}, 1));
  }
  auto furnished = RayTracer::create(mesh);
  ASSERT_TRUE(furnished.isOk());
  ASSERT_GT((*furnished)->planes().planes.size(), ImageSourceSettings{}.maxPlanesExhaustive);
  OmniIrSettings s;
  s.sampleRateHz = 8000;
  s.rays = 1000;
  s.bounces = 6;
  s.imageSourceOrder = 2;
  s.lengthSeconds = 1;
  const std::vector<IrRequest> all = ringOfSources(6);
  const std::vector<IrRequest> first(all.begin(), all.begin() + 3), second(all.begin() + 3, all.end());
  const Vec3d listener{7.2, 2.6, 1.6};
  ThreadPool pool(2);
  ListenerCache cache;
  auto a = computeIrs(**furnished, room.materials, listener, first, s, TraceMode::kShared, pool, nullptr, nullptr,
                      &cache);
  ASSERT_TRUE(a.isOk()) << a.status().message();
  EXPECT_FALSE(a->front().traceStats.pathsReused);
  EXPECT_TRUE(cache.candidates.valid);
  EXPECT_FALSE(cache.candidates.sequences.empty());
  EXPECT_GT(cache.paths.bytes(), 0u);
  const std::vector<PlaneSequence> kept = cache.candidates.sequences;
  auto b = computeIrs(**furnished, room.materials, listener, second, s, TraceMode::kShared, pool, nullptr, nullptr,
                      &cache);
  auto fresh = computeIrs(**furnished, room.materials, listener, second, s, TraceMode::kShared, pool);
  ASSERT_TRUE(b.isOk() && fresh.isOk());
  EXPECT_EQ(cache.candidates.sequences, kept);
  size_t early = 0;
  for (size_t i = 0; i < second.size(); ++i) {
    EXPECT_TRUE((*b)[i].traceStats.pathsReused);
    EXPECT_EQ((*b)[i].ir.channels, (*fresh)[i].ir.channels) << "source " << i;
    EXPECT_EQ((*b)[i].early.size(), (*fresh)[i].early.size()) << "source " << i;
    early += (*b)[i].early.size();
  }
  EXPECT_GT(early, 0u);
  const Vec3d moved{6.9, 2.6, 1.6};
  auto c = computeIrs(**furnished, room.materials, moved, second, s, TraceMode::kShared, pool, nullptr, nullptr,
                      &cache);
  auto cFresh = computeIrs(**furnished, room.materials, moved, second, s, TraceMode::kShared, pool);
  ASSERT_TRUE(c.isOk() && cFresh.isOk());
  EXPECT_FALSE(c->front().traceStats.pathsReused);
  EXPECT_EQ(cache.candidates.listener.x, moved.x);
  for (size_t i = 0; i < second.size(); ++i) EXPECT_EQ((*c)[i].ir.channels, (*cFresh)[i].ir.channels);
  // So are the kept tail rates: twice the decay rate, other late tails.
  ASSERT_TRUE(cache.rates.has_value());
  EXPECT_EQ(cache.ratesGeneration, cache.paths.generation());
  for (double& r : cache.rates->info.decayRatePerSecond) r *= 2;
  auto e = computeIrs(**furnished, room.materials, moved, second, s, TraceMode::kShared, pool, nullptr, nullptr,
                      &cache);
  ASSERT_TRUE(e.isOk());
  EXPECT_TRUE(e->front().traceStats.pathsReused);
  EXPECT_NE(e->front().ir.channels, cFresh->front().ir.channels);
  // The kept candidates are what the next simulation from there uses (no
  // search): emptied, they give no image source.
  cache.candidates.sequences.clear();
  auto d = computeIrs(**furnished, room.materials, moved, second, s, TraceMode::kShared, pool, nullptr, nullptr,
                      &cache);
  ASSERT_TRUE(d.isOk());
  for (size_t i = 0; i < second.size(); ++i) EXPECT_TRUE((*d)[i].early.empty()) << "source " << i;
}

// kAuto traces 1 or 2 sources from themselves (computeIr's IRs) and 3 or
// more from the listener.
TEST(ComputeIrs, AutoSharesFromThreeSources) {
  EXPECT_EQ(effectiveTraceMode(TraceMode::kAuto, 2), TraceMode::kPerSource);
  EXPECT_EQ(effectiveTraceMode(TraceMode::kAuto, 3), TraceMode::kShared);
  EXPECT_EQ(effectiveTraceMode(TraceMode::kPerSource, 30), TraceMode::kPerSource);
  EXPECT_EQ(effectiveTraceMode(TraceMode::kShared, 1), TraceMode::kShared);
  Room room;
  OmniIrSettings s;
  s.rays = 1000;
  s.bounces = 6;
  ThreadPool pool(2);
  const std::vector<IrRequest> two = ringOfSources(2);
  const Vec3d listener{7.2, 2.6, 1.6};
  auto irs = computeIrs(*room.tracer, room.materials, listener, two, s, TraceMode::kAuto, pool);
  ASSERT_TRUE(irs.isOk());
  for (size_t i = 0; i < two.size(); ++i) {
    auto one = computeIr(*room.tracer, room.materials, two[i].source, listener, s, pool, nullptr);
    ASSERT_TRUE(one.isOk());
    EXPECT_EQ((*irs)[i].ir.channels, one->ir.channels);
  }
  EXPECT_EQ(toString(TraceMode::kAuto), std::string("auto"));
  EXPECT_FALSE(traceModeFromString("both").isOk());
}

// OmniIrSettings::maxLengthSeconds (the runtime's cut): in a reverberant
// room (absorption 0.01, T60 ~14 s) the automatic length runs to ~10 s
// (air absorption ends it; measured 9.8 s); a
// cap of 1 s ends the trace's histogram, the tail and so the IR there
// (the IR then 50 ms longer, as an automatic length is), and cuts an
// explicit length. Before the cap the IR is the uncapped one's within the
// noise of the tail's rates (which see the shorter trace). Bad caps are
// refused.
TEST(ComputeIr, ALengthCapEndsTheReflectionsThere) {
  Room room(0.01f);
  OmniIrSettings s;
  s.sampleRateHz = 8000;
  s.rays = 2000;
  s.bounces = 8;
  s.imageSourceOrder = 1;
  const Vec3d source{2.0, 3.0, 1.2}, listener{7.2, 2.6, 1.6};
  ThreadPool pool(2);
  auto whole = computeIr(*room.tracer, room.materials, source, listener, s, pool, nullptr);
  ASSERT_TRUE(whole.isOk()) << whole.status().message();
  EXPECT_GT(whole->ir.frameCount(), size_t(5 * s.sampleRateHz)) << "the automatic length of a reverberant room";
  s.maxLengthSeconds = 1.0;
  auto capped = computeIr(*room.tracer, room.materials, source, listener, s, pool, nullptr);
  ASSERT_TRUE(capped.isOk()) << capped.status().message();
  EXPECT_LE(capped->late.binCount(), size_t(std::ceil(1.0 / s.binSeconds)) + 1);
  EXPECT_GE(capped->ir.frameCount(), size_t(1.0 * s.sampleRateHz));
  EXPECT_LE(capped->ir.frameCount(), size_t(1.06 * s.sampleRateHz));
  // Energy of 0.1-0.9 s, in 0.2 s windows: the same room either way.
  for (size_t w = 0; w < 4; ++w) {
    double a = 0, b = 0;
    for (size_t i = size_t((0.1 + 0.2 * double(w)) * s.sampleRateHz); i < size_t((0.3 + 0.2 * double(w)) * s.sampleRateHz); ++i) {
      a += double(whole->ir.channels[0][i]) * whole->ir.channels[0][i];
      b += double(capped->ir.channels[0][i]) * capped->ir.channels[0][i];
    }
    EXPECT_NEAR(10 * std::log10(b / a), 0.0, 0.5) << "window " << w;
  }
  s.lengthSeconds = 5.0;
  auto cut = computeIr(*room.tracer, room.materials, source, listener, s, pool, nullptr);
  ASSERT_TRUE(cut.isOk()) << cut.status().message();
  EXPECT_EQ(cut->ir.frameCount(), size_t(1.0 * s.sampleRateHz)) << "an explicit length cut to the cap";
  for (double bad : {-1.0, 601.0, std::nan("")}) {
    s.maxLengthSeconds = bad;
    auto refused = computeIr(*room.tracer, room.materials, source, listener, s, pool, nullptr);
    ASSERT_FALSE(refused.isOk()) << bad;
    EXPECT_NE(refused.status().message().find("IR length cap"), std::string::npos) << refused.status().message();
  }
}

}  // namespace earshot
