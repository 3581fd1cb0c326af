#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>

#include <nlohmann/json.hpp>

#include "earshot/core/math.h"
#include "earshot/core/thread_pool.h"
#include "earshot/propagation/direct_path.h"
#include "earshot/propagation/image_sources.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot {
namespace {

// The reference shoebox (tests/data/reference/shoebox_multiband, see its
// PROVENANCE.md): six walls with their own per-band absorption, specular only.
struct ReferenceShoebox {
  nlohmann::json meta, early;
  MaterialTable materials;
  std::unique_ptr<RayTracer> tracer;
  ReferenceShoebox() {
    const std::string dir = std::string(EARSHOT_TEST_DATA_DIR) + "/reference/shoebox_multiband/";
    std::ifstream(dir + "meta.json") >> meta;
    std::ifstream(dir + "early_arrivals.json") >> early;
    std::array<uint32_t, 6> ids{};
    for (int w = 0; w < 6; ++w) {
      Material m;
      m.name = "wall" + std::to_string(w);
      for (int b = 0; b < kNumBands; ++b) m.absorption[b] = meta["alpha"][w][b].get<float>();
      m.scattering = filledBands(0.0f);
      m.transmission = filledBands(0.0f);
      ids[w] = materials.add(m);
    }
    // makeBox's face order (west, east, south, north, floor, ceiling) is the reference's wall order.
    auto rt = RayTracer::create(makeBox({0, 0, 0}, {10, 7, 3}, ids));
    tracer = std::move(rt.value());
  }
  Vec3d source() const { return {meta["src"][0], meta["src"][1], meta["src"][2]}; }
  Vec3d listener() const { return {meta["mic"][0], meta["mic"][1], meta["mic"][2]}; }
};

}  // namespace

// Every one of the 63 arrivals up to order 3 (62 reflections + the direct
// sound) at the right delay (within 1/fs) with per-band amplitude within
// 0.1 dB. The reference uses 1/(4 pi r) spreading: x 4 pi for earshot's 1/r.
TEST(ImageSources, ShoeboxMatchesTheExactImageSourceSolutionToOrderThree) {
  ReferenceShoebox box;
  ASSERT_EQ(box.early["n_arrivals"].get<int>(), 63);
  ImageSourceSettings s;
  s.maxOrder = 3;
  auto r = findImageSources(*box.tracer, box.materials, box.source(), box.listener(), s);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_TRUE(r->exhaustive);
  EXPECT_EQ(r->paths.size(), 62u);
  const double fs = box.meta["fs"].get<double>();
  DirectPath direct = computeDirectPath(box.tracer.get(), box.materials, box.source(), box.listener(), {});
  int matched = 0;
  for (const auto& a : box.early["arrivals"]) {
    const Vec3d image{a["image_pos"][0], a["image_pos"][1], a["image_pos"][2]};
    const double delay = a["delay_s"];
    BandArrayD gain{};
    uint32_t order = a["order"];
    if (order == 0) {
      EXPECT_NEAR(direct.delaySeconds, delay, 1.0 / fs);
      for (int b = 0; b < kNumBands; ++b) gain[b] = direct.spreadingGain * direct.bandGain[b];
    } else {
      const SpecularPath* found = nullptr;
      for (const auto& p : r->paths)
        if (length(p.imageSource - image) < 1e-6) found = &p;
      ASSERT_NE(found, nullptr) << "image at " << image.x << "," << image.y << "," << image.z << " missing";
      EXPECT_EQ(found->order, order);
      EXPECT_NEAR(found->delaySeconds, delay, 1.0 / fs);
      for (int b = 0; b < kNumBands; ++b) gain[b] = found->spreadingGain * found->bandGain[b];
    }
    for (int b = 0; b < kNumBands; ++b) {
      const double want = a["amp"][b].get<double>() * 4.0 * kPi;
      EXPECT_NEAR(gainToDb(gain[b]), gainToDb(want), 0.1) << "order " << order << " band " << b;
    }
    ++matched;
  }
  EXPECT_EQ(matched, 63);
}

TEST(ImageSources, AnOccluderHidesThePathsItBlocks) {
  // Floor only, with a small panel between source and the floor reflection point.
  MaterialTable materials;
  TriangleMesh mesh;
  mesh.positions = {{-20, -20, 0}, {20, -20, 0}, {20, 20, 0}, {-20, 20, 0}};
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  mesh.materialIds = {0, 0};
  auto open = RayTracer::create(mesh);
  ASSERT_TRUE(open.isOk());
  ImageSourceSettings s;
  auto a = findImageSources(**open, materials, {0, 0, 2}, {4, 0, 2}, s);
  ASSERT_TRUE(a.isOk());
  ASSERT_EQ(a->paths.size(), 1u);  // one floor reflection
  EXPECT_NEAR(a->paths[0].lengthMeters, std::sqrt(16.0 + 16.0), 1e-9);
  // Block it: a horizontal panel at z = 1 where the leg from the reflection
  // point (2, 0, 0) to the listener passes (3, 0, 1).
  TriangleMesh blocker;
  blocker.positions = {{2.5f, -0.5f, 1}, {3.5f, -0.5f, 1}, {3.5f, 0.5f, 1}, {2.5f, 0.5f, 1}};
  blocker.triangles = {{0, 1, 2}, {0, 2, 3}};
  blocker.materialIds = {0, 0};
  mesh.append(blocker);
  auto blocked = RayTracer::create(mesh);
  ASSERT_TRUE(blocked.isOk());
  auto b = findImageSources(**blocked, materials, {0, 0, 2}, {4, 0, 2}, s);
  ASSERT_TRUE(b.isOk());
  for (const auto& p : b->paths) EXPECT_NE(p.planes[0], a->paths[0].planes[0]) << "floor path not blocked";
}

TEST(ImageSources, RayCandidatesFindTheSameShoeboxPathsAsExhaustiveSearch) {
  ReferenceShoebox box;
  ImageSourceSettings s;
  auto exact = findImageSources(*box.tracer, box.materials, box.source(), box.listener(), s);
  s.maxPlanesExhaustive = 0;  // force ray candidates
  auto rays = findImageSources(*box.tracer, box.materials, box.source(), box.listener(), s);
  ASSERT_TRUE(exact.isOk() && rays.isOk());
  EXPECT_FALSE(rays->exhaustive);
  EXPECT_EQ(rays->found, exact->found);
}

// Candidates from the listener's rays, reversed (what a trace shared by
// many sources uses, issue 16): in the reference shoebox, every path the
// exhaustive search finds, and the same paths.
TEST(ImageSources, ListenerCandidatesFindTheSameShoeboxPathsAsExhaustiveSearch) {
  ReferenceShoebox box;
  ImageSourceSettings s;
  auto exact = findImageSources(*box.tracer, box.materials, box.source(), box.listener(), s);
  const std::vector<PlaneSequence> fromListener = imageSourceCandidates(*box.tracer, box.listener(), s, true);
  s.maxPlanesExhaustive = 0;
  s.candidates = &fromListener;
  auto rays = findImageSources(*box.tracer, box.materials, box.source(), box.listener(), s);
  ASSERT_TRUE(exact.isOk() && rays.isOk());
  EXPECT_FALSE(rays->exhaustive);
  EXPECT_EQ(rays->candidates, fromListener.size());
  EXPECT_EQ(rays->found, exact->found);
  ASSERT_EQ(rays->paths.size(), exact->paths.size());
  for (size_t i = 0; i < exact->paths.size(); ++i)
    EXPECT_NEAR(rays->paths[i].lengthMeters, exact->paths[i].lengthMeters, 1e-9);
}

// A room with furniture (a 9 x 6 x 3 m box, a table, a cupboard and a
// partition; candidates from rays): the listener's candidates find what the
// source's find. Per source, over six sources, the found sets differ by at
// most one path (a beam narrower than the rays' spacing may be missed from
// one end; measured: none), and the early specular energy (sum of |gain|^2 /
// length^2) agrees within 1 % (measured: equal).
TEST(ImageSources, ListenerCandidatesFindWhatTheSourcesFindAmidFurniture) {
  MaterialTable materials;
  Material m;
  m.name = "wall";
  m.absorption = filledBands(0.1f);
  m.scattering = filledBands(0.2f);
  m.transmission = filledBands(0.0f);
  const uint32_t id = materials.add(m);
  TriangleMesh mesh = makeBox({0, 0, 0}, {9, 6, 3}, {id, id, id, id, id, id});
  mesh.append(makeBox({2.0, 2.0, 0.7}, {3.6, 3.0, 0.76}, id));   // a table top
  mesh.append(makeBox({6.5, 0.0, 0.0}, {8.0, 0.6, 2.0}, id));    // a cupboard
  mesh.append(makeBox({4.4, 3.5, 0.0}, {4.6, 6.0, 2.2}, id));    // a partition
  auto tracer = RayTracer::create(mesh);
  ASSERT_TRUE(tracer.isOk());
  const Vec3d listener{5.5, 2.2, 1.6};
  ImageSourceSettings s;
  s.maxPlanesExhaustive = 0;
  const std::vector<PlaneSequence> fromListener = imageSourceCandidates(**tracer, listener, s, true);
  auto energy = [](const ImageSourceResult& r) {
    double e = 0;
    for (const SpecularPath& p : r.paths) e += p.bandGain[2] * p.bandGain[2] * p.spreadingGain * p.spreadingGain;
    return e;
  };
  size_t paths = 0;
  for (const Vec3d& source : {Vec3d{1.0, 1.0, 1.2}, Vec3d{2.8, 4.5, 1.5}, Vec3d{7.5, 4.0, 1.0}, Vec3d{3.0, 2.5, 0.3},
                              Vec3d{8.2, 1.5, 2.5}, Vec3d{4.0, 5.2, 1.8}}) {
    ImageSourceSettings own = s;
    auto a = findImageSources(**tracer, materials, source, listener, own);
    own.candidates = &fromListener;
    auto b = findImageSources(**tracer, materials, source, listener, own);
    ASSERT_TRUE(a.isOk() && b.isOk());
    size_t onlyA = 0, onlyB = 0;
    for (const PlaneSequence& q : a->found) onlyA += b->found.count(q) == 0;
    for (const PlaneSequence& q : b->found) onlyB += a->found.count(q) == 0;
    std::printf("source %.1f,%.1f,%.1f: %zu paths from the source's candidates (%llu), %zu from the listener's "
                "(%llu); only in one: %zu, %zu\n",
                source.x, source.y, source.z, a->paths.size(), (unsigned long long)a->candidates, b->paths.size(),
                (unsigned long long)b->candidates, onlyA, onlyB);
    EXPECT_LE(onlyA + onlyB, 1u);
    EXPECT_NEAR(energy(*b) / energy(*a), 1.0, 0.01);
    paths += a->paths.size();
    // On a pool's threads: the same candidates and paths.
    ThreadPool two(2);
    auto c = findImageSources(**tracer, materials, source, listener, s, &two);
    ASSERT_TRUE(c.isOk());
    EXPECT_EQ(c->found, a->found);
    EXPECT_EQ(c->candidates, a->candidates);
    ASSERT_EQ(c->paths.size(), a->paths.size());
    for (size_t i = 0; i < a->paths.size(); ++i) EXPECT_EQ(c->paths[i].lengthMeters, a->paths[i].lengthMeters);
  }
  EXPECT_GT(paths, 6u * 30u);  // furniture: many paths per source
  ThreadPool two(2);
  EXPECT_EQ(imageSourceCandidates(**tracer, listener, s, true, &two), fromListener);
}

// A mirror smaller than the scene: a reflection exists where its point lies
// on the panel, edge included, and not 2 cm beyond it (the bounds of a
// plane's triangles reject such legs before a ray is traced: the result
// must be the ray's). Two panels on one plane with a gap between them: a
// point in the gap is within the plane's bounds, so the ray decides.
TEST(ImageSources, ASmallMirrorReflectsOnItAndNotBesideIt) {
  MaterialTable materials;
  TriangleMesh mesh;
  // Plane x = 5: panel A y in [0, 1], panel B y in [2, 3]; z in [0, 1].
  mesh.positions = {{5, 0, 0}, {5, 1, 0}, {5, 1, 1}, {5, 0, 1}, {5, 2, 0}, {5, 3, 0}, {5, 3, 1}, {5, 2, 1}};
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}};
  mesh.materialIds = {0, 0, 0, 0};
  auto tracer = RayTracer::create(mesh);
  ASSERT_TRUE(tracer.isOk());
  ASSERT_EQ((*tracer)->planes().planes.size(), 1u);
  ImageSourceSettings s;
  s.maxOrder = 1;
  // Source and listener at x = 3, z = 0.5: the reflection point's y is the
  // mean of theirs.
  auto reflections = [&](double pointY) {
    auto r = findImageSources(**tracer, materials, {3, pointY - 0.4, 0.5}, {3, pointY + 0.4, 0.5}, s);
    EXPECT_TRUE(r.isOk());
    return r.isOk() ? r->paths.size() : size_t(99);
  };
  EXPECT_EQ(reflections(0.5), 1u);   // on panel A
  EXPECT_EQ(reflections(1.0), 1u);   // on its edge
  EXPECT_EQ(reflections(1.02), 0u);  // in the gap, 2 cm beside A: within the plane's bounds, the ray misses
  EXPECT_EQ(reflections(1.5), 0u);   // the gap's middle
  EXPECT_EQ(reflections(2.5), 1u);   // on panel B
  EXPECT_EQ(reflections(3.02), 0u);  // 2 cm beyond B: beyond the plane's bounds
  EXPECT_EQ(reflections(-0.02), 0u); // 2 cm before A
}

}  // namespace earshot
