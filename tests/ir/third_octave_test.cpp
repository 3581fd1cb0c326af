// Issue 20, third-octave bands: in a room that absorbs in one third octave
// only (materials given in third octaves), that band's decay in the output
// IR is the band's own traced decay; and the pieces that make it (the pass
// weights, materials and air at shifted bands).
//
// How a band of the output is measured (as band_exact_test.cpp does for
// octaves): a zero-phase mask over the part of the third octave that the
// crossovers (kThirdOctaveCrossoverOctaves) leave to it alone, a sixth of
// an octave, with 1/24-octave raised-cosine edges inside it; the reference
// is the band's traced energy (its pass's histogram, direct sound and image
// sources) smoothed by the mask's own energy response.
#include <gtest/gtest.h>

#include <kiss_fftr.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "earshot/analysis/room_acoustics.h"
#include "earshot/core/math.h"
#include "earshot/core/random.h"
#include "earshot/core/thread_pool.h"
#include "earshot/ir/third_octave.h"
#include "earshot/materials/material.h"
#include "earshot/propagation/air_absorption.h"
#include "earshot/scene/ray_tracer.h"
#include "band_mask_util.h"

namespace earshot {
namespace {

using analysis::BandMetrics;

TEST(ThirdOctave, PassWeightsSumToOneAndEachBandOwnsASixthOfAnOctave) {
  for (double hz = 20; hz < 24000; hz *= 1.003) {
    double sum = 0;
    for (int p = 0; p < kThirdOctavePasses; ++p) {
      const double w = thirdOctavePassWeight(p, hz);
      EXPECT_GE(w, 0.0);
      EXPECT_LE(w, 1.0);
      sum += w;
    }
    EXPECT_NEAR(sum, 1.0, 1e-12) << hz;
  }
  for (int j = 0; j < kNumThirdOctaveBands; ++j) {
    const double c = thirdOctaveCenterHz(j);
    // Its own sixth of an octave: weight one; beyond a quarter octave: none.
    for (double x : {-1.0 / 12.0 + 1e-9, 0.0, 1.0 / 12.0 - 1e-9}) EXPECT_DOUBLE_EQ(thirdOctaveBandWeight(j, c * std::exp2(x)), 1.0);
    if (j > 0) {
      EXPECT_EQ(thirdOctaveBandWeight(j, c * std::exp2(-0.25 - 1e-9)), 0.0);
    }
    if (j < kNumThirdOctaveBands - 1) {
      EXPECT_EQ(thirdOctaveBandWeight(j, c * std::exp2(0.25 + 1e-9)), 0.0);
    }
  }
  EXPECT_NEAR(thirdOctaveCenterHz(0), 99.21, 0.01);
  EXPECT_NEAR(thirdOctaveCenterHz(20), 10079.4, 0.1);
}

TEST(ThirdOctave, MaterialsAndAirAtShiftedBands) {
  // A file in third octaves: each pass reads its own bands' values, nominal
  // names (400 Hz for 396.9) included; octaves 0 leaves the table as it was.
  std::string bands, values;
  for (int j = 0; j < kNumThirdOctaveBands; ++j) {
    bands += (j ? "," : "") + std::to_string(int(kThirdOctaveNominalHz[size_t(j)]));
    values += (j ? "," : "") + std::to_string(0.01 + 0.04 * j);
  }
  auto table = parseMaterials("{\"bands_hz\": [" + bands + "], \"materials\": {\"m\": {\"absorption\": [" + values +
                                  "], \"scattering\": 0.3}}}",
                              "test");
  ASSERT_TRUE(table.isOk()) << table.status().message();
  const uint32_t id = *table->find("m");
  for (int p = 0; p < kThirdOctavePasses; ++p) {
    const MaterialTable shifted = table->atBandShift(thirdOctavePassShift(p));
    for (int b = 0; b < kNumBands; ++b) {
      const int j = 3 * b + p;
      EXPECT_FLOAT_EQ(shifted[id].absorption[size_t(b)], float(0.01 + 0.04 * j)) << "band " << j;
      EXPECT_FLOAT_EQ(shifted[id].scattering[size_t(b)], 0.3f);
    }
  }
  const MaterialTable same = table->atBandShift(0.0);
  for (int b = 0; b < kNumBands; ++b) EXPECT_EQ(same[id].absorption[size_t(b)], (*table)[id].absorption[size_t(b)]);
  // A material made in code (octave values): interpolated between octaves.
  MaterialTable code;
  Material m;
  m.name = "code";
  for (int b = 0; b < kNumBands; ++b) m.absorption[size_t(b)] = 0.1f * float(b);
  const uint32_t cid = code.add(m);
  const MaterialTable up = code.atBandShift(1.0 / 3.0);
  EXPECT_NEAR(up[cid].absorption[0], 0.1 / 3.0, 1e-6);
  EXPECT_NEAR(up[cid].absorption[kNumBands - 1], 0.6, 1e-6);  // held above the top octave
  // Air at the pass's bands.
  AirConditions air;
  air.bandShiftOctaves = 1.0 / 3.0;
  const BandArrayD a = airAttenuationDbPerMeter(air);
  for (int b = 0; b < kNumBands; ++b)
    EXPECT_DOUBLE_EQ(a[size_t(b)], airAttenuationDbPerMeter(thirdOctaveCenterHz(3 * b + 2), air));
  air.bandShiftOctaves = 1.5;
  EXPECT_FALSE(validate(air).isOk());
}

using testing::energyMetrics;
using testing::rise;

// The mask of third octave j described at the top (on log2 frequency).
double thirdMask(int j, double lf) {
  constexpr double kEdge = 1.0 / 24.0;
  const double c = std::log2(thirdOctaveCenterHz(j));
  const double own = 0.5 / 3.0 - 0.5 * kThirdOctaveCrossoverOctaves;  // +-1/12 octave
  // The lowest and highest bands reach to 0 Hz and to Nyquist: there the
  // third octave itself bounds them (as band_exact_test.cpp's octaves).
  const double lo = j > 0 ? c - own : c - 1.0 / 6.0, hi = j < kNumThirdOctaveBands - 1 ? c + own : c + 1.0 / 6.0;
  return rise(lf, lo, kEdge) * (1.0 - rise(lf, hi - kEdge, kEdge));
}

// Third octave j of x, through the mask described at the top.
std::vector<float> bandOnly(const std::vector<float>& x, double fs, int j) {
  return testing::masked(x, fs, [j](double lf) { return thirdMask(j, lf); });
}

// `count` source/listener pairs in the 10 x 7 x 3 m box, over 2 m apart,
// each point 0.5 m inside the walls and 0.3 m off the box's symmetry planes
// (there image sources coincide and add coherently, which no energy
// histogram holds).
std::vector<std::pair<Vec3d, Vec3d>> offSymmetryPairs(size_t count) {
  Pcg32 rng(20, 3);
  auto point = [&] {
    for (;;) {
      const Vec3d p{0.5 + 9.0 * rng.uniformDouble(), 0.5 + 6.0 * rng.uniformDouble(), 0.5 + 2.0 * rng.uniformDouble()};
      if (std::fabs(p.x - 5.0) > 0.3 && std::fabs(p.y - 3.5) > 0.3 && std::fabs(p.z - 1.5) > 0.3) return p;
    }
  };
  std::vector<std::pair<Vec3d, Vec3d>> pairs;
  while (pairs.size() < count) {
    const Vec3d a = point(), b = point();
    if (length(a - b) > 2.0) pairs.emplace_back(a, b);
  }
  return pairs;
}


// Must show (issue 20, item 2 with item 1's criterion): for a room
// absorbing (0.25) in one third octave only, that band's output EDT and T20
// within 5 % of its traced decay, ensemble averages over 8 pairs off the
// room's symmetry planes (as band_exact_test.cpp). Omni; the absorbing band
// steps through every third band from 100 Hz (every pass, every octave).
constexpr size_t kPairs = 64;
constexpr int kBandStep = 4;
TEST(ThirdOctave, OneAbsorbingThirdOctaveKeepsItsOwnDecay) {
  ThreadPool pool(2);
  const std::vector<std::pair<Vec3d, Vec3d>> pairs = offSymmetryPairs(3 * kPairs);
  double worst = 0;
  for (int absorbing = 0; absorbing < kNumThirdOctaveBands; absorbing += kBandStep) {
    std::string bands, values;
    for (int j = 0; j < kNumThirdOctaveBands; ++j) {
      bands += (j ? "," : "") + std::to_string(int(kThirdOctaveNominalHz[size_t(j)]));
      values += std::string(j ? "," : "") + (j == absorbing ? "0.25" : "0.05");
    }
    auto materials = parseMaterials("{\"bands_hz\": [" + bands + "], \"materials\": {\"wall\": {\"absorption\": [" +
                                        values + "], \"scattering\": 0.5}}}",
                                    "test");
    ASSERT_TRUE(materials.isOk()) << materials.status().message();
    auto tracer = RayTracer::create(makeBox({0, 0, 0}, {10, 7, 3}, *materials->find("wall")));
    ASSERT_TRUE(tracer.isOk());
    const int pass = absorbing % kThirdOctavePasses, band = absorbing / kThirdOctavePasses;
    std::vector<double> traced, output;
    double fs = 0, binRate = 0;
    // The 100 Hz band's quarter octave holds the fewest degrees of freedom:
    // with 64 pairs its EDT scattered by +-6 % between two sets of pairs
    // (-1.8 % and +6.3 %; every other band within 3.6 %), so it takes three
    // times as many.
    const size_t count = absorbing == 0 ? 3 * kPairs : kPairs;
    for (size_t i = 0; i < count; ++i) {
      OmniIrSettings s;  // the balanced preset, fewer rays: the reference is this trace itself
      s.rays = 1024;
      s.seed = uint64_t(i + 1);  // a noise per pair: the ensemble average needs their degrees of freedom
      s.lengthSeconds = 1.0;     // the absorbing band is 100 dB down by then
      auto r = computeIrThirdOctave(**tracer, *materials, pairs[i].first, pairs[i].second, s, pool);
      ASSERT_TRUE(r.isOk()) << r.status().message();
      const std::vector<double> e = tracedEnergy(r->passes[size_t(pass)], band);
      if (traced.size() < e.size()) traced.resize(e.size(), 0.0);
      for (size_t k = 0; k < e.size(); ++k) traced[k] += e[k];
      binRate = 1.0 / r->passes[size_t(pass)].late.binSeconds();
      fs = r->ir.sampleRateHz;
      const std::vector<float> y = bandOnly(r->ir.channels[0], fs, absorbing);
      if (output.size() < y.size()) output.resize(y.size(), 0.0);
      for (size_t k = 0; k < y.size(); ++k) output[k] += double(y[k]) * y[k];
    }
    // The mask's own energy response (zero-phase, centred), in histogram
    // bins, +-400 ms of it (the 100 Hz mask is ~12 Hz wide).
    testing::smoothByMaskResponse(traced, binRate, fs, 2.0, 0.4,
                                  [absorbing](double lf) { return thirdMask(absorbing, lf); });
    const BandMetrics want = energyMetrics(traced, binRate), got = energyMetrics(output, fs);
    const double edtErr = got.edtS / want.edtS - 1.0, t20Err = got.t20S / want.t20S - 1.0;
    const std::string what = std::to_string(int(kThirdOctaveNominalHz[size_t(absorbing)])) + " Hz absorbing";
    EXPECT_LE(std::fabs(edtErr), 0.05) << what << ": EDT " << got.edtS << " s, traced " << want.edtS;
    EXPECT_LE(std::fabs(t20Err), 0.05) << what << ": T20 " << got.t20S << " s, traced " << want.t20S;
    worst = std::max({worst, std::fabs(edtErr), std::fabs(t20Err)});
    std::printf("%s: EDT %.3f / %.3f, T20 %.3f / %.3f (output / traced)\n", what.c_str(), got.edtS, want.edtS, got.t20S,
                want.t20S);
  }
  std::printf("worst relative error of an absorbing third octave's EDT and T20: %.1f %%\n", 100.0 * worst);
}

}  // namespace
}  // namespace earshot
