// Issue 20, band-exact synthesis: in a room that absorbs in one octave band
// only, that band's decay in the output IR is the band's own traced decay,
// not its slower neighbours'.
//
// How a band of the output is measured: the ISO 3382 octave filters
// (analyzeIr) cannot tell: their skirts pass enough of the neighbouring
// octaves that even an ideal IR (each band's noise confined by a brick wall
// to its octave, the 250 Hz band decaying in 0.52 s and the others in 2.8 s)
// reads EDT 2.36 s at 250 Hz through them (measured with numpy; a real
// measurement would be fooled alike). So the band is taken where only it
// may carry energy: a zero-phase mask over the part of its octave that the
// synthesis's crossovers (kNoiseCrossoverOctaves) leave to it alone, with
// 1/12-octave raised-cosine edges. The reference is the band's energy as
// traced: the late histogram plus the direct sound and image sources,
// smoothed by the mask's own energy response (which spreads the 125 Hz
// direct sound over +-10 ms), with EDT and T20 computed the same way
// (Schroeder, no noise treatment).
#include <gtest/gtest.h>

#include <kiss_fftr.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "earshot/analysis/room_acoustics.h"
#include "earshot/core/math.h"
#include "earshot/core/thread_pool.h"
#include "earshot/ir/band_filter_bank.h"
#include "earshot/ir/binaural_synthesis.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/materials/material.h"
#include "earshot/scene/ray_tracer.h"
#include "band_mask_util.h"

namespace earshot {
namespace {

using analysis::BandMetrics;

const std::string kKu100 = std::string(EARSHOT_SOURCE_DIR) + "/hrtf/FHK_HRIR_L2354.sofa";

using testing::energyMetrics;
using testing::masked;
using testing::rise;

// The mask of band `band` described above (on log2 frequency).
double bandMask(int band, double lf) {
  constexpr double kEdge = 1.0 / 12.0;
  const double lower = std::log2(kBandCentersHz[0]) + double(band) - 0.5 + 0.5 * kNoiseCrossoverOctaves;
  const double upper = std::log2(kBandCentersHz[0]) + double(band) + 0.5 - 0.5 * kNoiseCrossoverOctaves;
  // The lowest and highest bands reach to 0 Hz and to Nyquist: there the
  // octave itself bounds them (below it, all arrivals add coherently).
  const double octaveLow = std::log2(kBandCentersHz[size_t(band)]) - 0.5, octaveHigh = octaveLow + 1.0;
  double m = 1.0;
  m *= rise(lf, band > 0 ? lower : octaveLow, kEdge);
  m *= 1.0 - rise(lf, (band < kNumBands - 1 ? upper : octaveHigh) - kEdge, kEdge);
  return m;
}

// Band `band` of x, through the mask described above.
std::vector<float> bandOnly(const std::vector<float>& x, double fs, int band) {
  return masked(x, fs, [band](double lf) { return bandMask(band, lf); });
}

// Must show (issue 20): for every band, omni and binaural, the output's
// decay within 5 % of the band's traced decay: EDT and T20 omni, T20 at
// each ear (an ear's EDT also carries the HRTF's weighting of the direct
// sound against the diffuse field, which the omni histogram does not).
// Both sides are ensemble averages over 8 source/listener pairs (the
// energies, then the metrics): one IR's decay in 2/3 of an octave scatters
// by several % from its noise alone. The pairs are off the room's symmetry
// planes, where image sources coincide and add coherently (in the middle of
// the room the EDT read 7 - 22 % short). Measured at 1/3-octave crossovers:
// EDT within 4.2 %, T20 within 4.8 % in every band, omni and both ears; with
// the one-octave crossovers before, this test read T20 1.43 - 1.85 s
// (125 Hz - 1 kHz) for a traced 0.52 s.
TEST(BandExact, OneAbsorbingBandKeepsItsOwnDecayInEveryBand) {
  auto model = loadBinauralModel(kKu100, 48000.0);
  ASSERT_TRUE(model.isOk()) << model.status().message();
  BinauralReceiver receiver{*model, {}};
  receiver.orientation.forward = {-1, 0, 0};
  receiver.orientation.up = {0, 0, 1};
  ThreadPool pool(2);
  // Off the room's symmetry planes: there image sources coincide and add
  // coherently, which no energy histogram holds.
  const std::array<std::pair<Vec3d, Vec3d>, 8> kPairs = {{
      {{2.1, 3.1, 1.3}, {6.7, 4.2, 1.7}}, {{1.4, 1.6, 1.1}, {8.2, 5.3, 1.4}}, {{3.2, 5.1, 1.8}, {6.4, 2.2, 1.2}},
      {{5.3, 3.8, 1.6}, {8.6, 1.7, 1.9}}, {{1.3, 5.8, 2.1}, {4.1, 2.3, 1.2}}, {{8.7, 6.1, 1.3}, {2.6, 1.2, 1.8}},
      {{4.6, 1.3, 2.2}, {5.7, 5.9, 1.1}}, {{7.4, 2.9, 0.9}, {2.2, 4.9, 2.3}},
  }};
  constexpr int kSeeds = int(kPairs.size());
  double worst = 0;
  for (int absorbing = 0; absorbing < kNumBands; ++absorbing) {
    MaterialTable materials;
    Material m;
    m.name = "wall";
    m.absorption = filledBands(0.05f);
    m.absorption[size_t(absorbing)] = 0.25f;
    m.scattering = filledBands(0.5f);
    m.transmission = filledBands(0.0f);
    auto tracer = RayTracer::create(makeBox({0, 0, 0}, {10, 7, 3}, materials.add(m)));
    ASSERT_TRUE(tracer.isOk());
    const std::vector<const BinauralReceiver*> receivers = {nullptr, &receiver};
    for (const BinauralReceiver* rx : receivers) {
      std::vector<double> traced;
      std::vector<std::vector<double>> output(rx ? 2 : 1);
      double fs = 0, binRate = 0;
      for (int seed = 1; seed <= kSeeds; ++seed) {
        OmniIrSettings s;  // the balanced preset, fewer rays: the reference is this trace itself
        s.rays = 4096;
        s.seed = uint64_t(seed);
        const auto& [source, listener] = kPairs[size_t(seed - 1)];
        auto r = computeIr(**tracer, materials, source, listener, s, pool, rx);
        ASSERT_TRUE(r.isOk()) << r.status().message();
        const std::vector<double> e = tracedEnergy(*r, absorbing);
        if (traced.size() < e.size()) traced.resize(e.size(), 0.0);
        for (size_t i = 0; i < e.size(); ++i) traced[i] += e[i];
        binRate = 1.0 / r->late.binSeconds();
        fs = r->ir.sampleRateHz;
        for (size_t ch = 0; ch < output.size(); ++ch) {
          const std::vector<float> y = bandOnly(r->ir.channels[ch], fs, absorbing);
          if (output[ch].size() < y.size()) output[ch].resize(y.size(), 0.0);
          for (size_t i = 0; i < y.size(); ++i) output[ch][i] += double(y[i]) * y[i];
        }
      }
      // What the mask does to an energy envelope: its own energy response
      // (zero-phase, so centred), in histogram bins. The 125 Hz mask is ~60 Hz
      // wide and spreads the direct sound over +-10 ms: compared unsmoothed,
      // the traced EDT read 7 - 12 % short at 125 - 500 Hz.
      testing::smoothByMaskResponse(traced, binRate, fs, 1.0, 0.05,
                                    [absorbing](double lf) { return bandMask(absorbing, lf); });
      const BandMetrics want = energyMetrics(traced, binRate);
      for (size_t ch = 0; ch < output.size(); ++ch) {
        const BandMetrics got = energyMetrics(output[ch], fs);
        const std::string what = std::string(rx ? (ch ? "binaural right" : "binaural left") : "omni") + ", " +
                                 std::to_string(int(kBandCentersHz[size_t(absorbing)])) + " Hz absorbing";
        const double edtErr = got.edtS / want.edtS - 1.0, t20Err = got.t20S / want.t20S - 1.0;
        if (!rx) {
          EXPECT_LE(std::fabs(edtErr), 0.05) << what << ": EDT " << got.edtS << " s, traced " << want.edtS;
          worst = std::max(worst, std::fabs(edtErr));
        }
        EXPECT_LE(std::fabs(t20Err), 0.05) << what << ": T20 " << got.t20S << " s, traced " << want.t20S;
        worst = std::max(worst, std::fabs(t20Err));
        std::printf("%s: EDT %.3f / %.3f, T20 %.3f / %.3f (output / traced)\n", what.c_str(), got.edtS, want.edtS,
                      got.t20S, want.t20S);
      }
    }
  }
  std::printf("worst relative error of an absorbing band's EDT (omni) and T20: %.1f %%\n", 100.0 * worst);
}

}  // namespace
}  // namespace earshot
