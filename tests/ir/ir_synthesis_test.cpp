#include <gtest/gtest.h>

#include <kiss_fftr.h>

#include <cmath>
#include <complex>
#include <vector>

#include "earshot/analysis/room_acoustics.h"
#include "earshot/core/math.h"
#include "earshot/ir/ambisonic_synthesis.h"
#include "earshot/io/input_file.h"
#include "earshot/ir/ir_synthesis.h"

namespace earshot {
namespace {

// |H(f)| of a real signal at frequency hz, by direct DFT (exact, slow, fine).
double magnitudeAt(const std::vector<float>& x, double fs, double hz) {
  std::complex<double> acc = 0;
  for (size_t n = 0; n < x.size(); ++n) acc += double(x[n]) * std::polar(1.0, -2.0 * kPi * hz * double(n) / fs);
  return std::abs(acc);
}

DirectPath freeFieldDirect(double distance, const AirConditions& air) {
  DirectPathSettings s;
  s.air = air;
  MaterialTable none;
  return computeDirectPath(nullptr, none, {distance, 0, 0}, {0, 0, 0}, s);
}

}  // namespace

// Direct sound alone: peak at round(r/c fs) within one sample; magnitude
// response 1/r within 0.1 dB below 1 kHz (the band-limited fractional delay is
// exact there: the weights sum to one and only the phase carries the delay).
TEST(IrSynthesis, DirectSoundArrivesAtRoverCWithAmplitudeOneOverR) {
  AirConditions noAir;
  noAir.enabled = false;
  IrSynthesisSettings s;
  for (double r : {1.0, 3.7, 10.0, 42.42}) {
    DirectPath d = freeFieldDirect(r, noAir);
    auto ir = synthesizeOmniIr(&d, nullptr, s);
    ASSERT_TRUE(ir.isOk()) << ir.status().message();
    const auto& x = ir->channels[0];
    size_t peak = 0;
    for (size_t i = 0; i < x.size(); ++i)
      if (std::fabs(x[i]) > std::fabs(x[peak])) peak = i;
    const double expected = std::round(r / 343.0 * s.sampleRateHz);
    EXPECT_NEAR(double(peak), expected, 1.0) << r;
    for (double hz : {63.0, 125.0, 250.0, 500.0, 800.0, 1000.0})
      EXPECT_NEAR(gainToDb(magnitudeAt(x, s.sampleRateHz, hz)), gainToDb(1.0 / r), 0.1) << r << " m, " << hz << " Hz";
  }
}

TEST(IrSynthesis, IntegerDelayGivesAnExactImpulse) {
  AirConditions noAir;
  noAir.enabled = false;
  IrSynthesisSettings s;
  s.sampleRateHz = 34300;  // 343 m/s: 1 m = 100 samples exactly
  DirectPath d = freeFieldDirect(2.0, noAir);
  auto ir = synthesizeOmniIr(&d, nullptr, s);
  ASSERT_TRUE(ir.isOk());
  const auto& x = ir->channels[0];
  EXPECT_NEAR(x[200], 0.5, 1e-6);
  double rest = 0;
  for (size_t i = 0; i < x.size(); ++i)
    if (i != 200) rest = std::max(rest, double(std::fabs(x[i])));
  EXPECT_LT(rest, 1e-6);
}

// ISO 9613-1 at 100 m per band: the band's magnitude at its centre frequency
// (where its weight is 1 and the others 0) is 1/r times the air attenuation.
// Expected dB/m are the reference's own values (see air_absorption_test.cpp).
TEST(IrSynthesis, AirAbsorptionAtOneHundredMetresMatchesIso9613PerBand) {
  const double dbPerM[kNumBands] = {0.00043978997709849435, 0.0013097497659238589, 0.002728134134938444,
                                    0.004664731873821475,   0.009887015588697921,  0.029665528426392616,
                                    0.10529092572360696};
  IrSynthesisSettings s;
  DirectPath d = freeFieldDirect(100.0, AirConditions{});
  auto ir = synthesizeOmniIr(&d, nullptr, s);
  ASSERT_TRUE(ir.isOk());
  for (int b = 0; b < kNumBands; ++b) {
    const double got = gainToDb(magnitudeAt(ir->channels[0], s.sampleRateHz, kBandCentersHz[b]));
    const double want = gainToDb(1.0 / 100.0) - dbPerM[b] * 100.0;
    EXPECT_NEAR(got, want, 0.5) << kBandCentersHz[b] << " Hz";
  }
}

// Reflections: energy of the synthesised noise equals the histogram's (the
// relative error of a sum of M squared Gaussians is sqrt(2/M); M = 24000 here).
TEST(IrSynthesis, ReflectionEnergyEqualsHistogramEnergy) {
  EnergyHistogram h(0.001, 600);
  for (size_t bin = 100; bin < 600; ++bin)
    h.add(bin, filledBands(1e-3 * std::exp(-double(bin) / 100.0)), {1, 0, 0});
  IrSynthesisSettings s;
  s.lengthSeconds = 0.7;
  auto ir = synthesizeOmniIr(nullptr, &h, s);
  ASSERT_TRUE(ir.isOk());
  double e = 0;
  for (float v : ir->channels[0]) e += double(v) * v;
  const double want = h.totalEnergy()[0];
  EXPECT_NEAR(e, want, 5.0 * std::sqrt(2.0 / 24000.0) * want + 0.01 * want);
}

// A histogram with energy in one band only gives an IR whose spectrum is
// concentrated in that band.
TEST(IrSynthesis, OneBandHistogramGivesSpectrumInThatBand) {
  EnergyHistogram h(0.001, 300);
  BandArrayD only1k{};
  only1k[3] = 1e-4;
  for (size_t bin = 10; bin < 300; ++bin) h.add(bin, only1k, {0, 1, 0});
  IrSynthesisSettings s;
  auto ir = synthesizeOmniIr(nullptr, &h, s);
  ASSERT_TRUE(ir.isOk());
  const auto& x = ir->channels[0];
  const double in = magnitudeAt(x, s.sampleRateHz, 1000.0) + magnitudeAt(x, s.sampleRateHz, 1100.0);
  const double out = magnitudeAt(x, s.sampleRateHz, 250.0) + magnitudeAt(x, s.sampleRateHz, 4000.0);
  EXPECT_GT(in, 1000.0 * out);
}

TEST(IrSynthesis, SameSeedSameIrDifferentSeedDifferentNoise) {
  EnergyHistogram h(0.001, 100);
  BandArrayD only500{};
  only500[2] = 1e-3;
  for (size_t bin = 5; bin < 100; ++bin) h.add(bin, only500, {0, 0, 1});
  IrSynthesisSettings s;
  auto a = synthesizeOmniIr(nullptr, &h, s), b = synthesizeOmniIr(nullptr, &h, s);
  s.seed = 2;
  auto c = synthesizeOmniIr(nullptr, &h, s);
  ASSERT_TRUE(a.isOk() && b.isOk() && c.isOk());
  EXPECT_EQ(a->channels, b->channels);
  EXPECT_NE(a->channels, c->channels);
}

TEST(IrSynthesis, LengthIsExactWhenGivenAndRatesOutOfRangeAreErrors) {
  IrSynthesisSettings s;
  s.lengthSeconds = 1.0 / 48000.0;
  DirectPath d = freeFieldDirect(1.0, AirConditions{});
  auto one = synthesizeOmniIr(&d, nullptr, s);
  ASSERT_TRUE(one.isOk());
  EXPECT_EQ(one->frameCount(), 1u);
  s.sampleRateHz = 1000;
  auto bad = synthesizeOmniIr(&d, nullptr, s);
  ASSERT_FALSE(bad.isOk());
  EXPECT_NE(bad.status().message().find("sample rate"), std::string::npos);
}

// An IR whose synthesis would hold more than the memory limit is refused
// before it is made (kOutOfRange, naming --max-memory): under 64 MiB a 10 s
// omni IR (~92 MB: the IR, its band envelopes, its noises of 2^19 samples)
// and a 10 s third-order ambisonic IR are refused, a 2 s one is made.
// Without the check the 10 s IRs are made (checked).
TEST(IrSynthesis, AnIrOverTheMemoryLimitIsRefusedBeforeItIsMade) {
  EnergyHistogram h(0.001, 2000);
  for (size_t bin = 10; bin < 2000; ++bin)
    h.add(bin, filledBands(1e-3 * std::exp(-double(bin) / 300.0)), {1, 0, 0});
  struct Restore {
    InputLimits saved = defaultInputLimits();
    ~Restore() { setDefaultInputLimits(saved); }
  } restore;
  InputLimits low = restore.saved;
  low.maxMemoryBytes = uint64_t(64) << 20;
  setDefaultInputLimits(low);
  IrSynthesisSettings s;
  s.lengthSeconds = 10;
  auto omni = synthesizeOmniIr(nullptr, &h, s);
  ASSERT_FALSE(omni.isOk());
  EXPECT_EQ(omni.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(omni.status().message().find("480000 samples"), std::string::npos) << omni.status().message();
  EXPECT_NE(omni.status().message().find("--max-memory"), std::string::npos) << omni.status().message();
  auto ambi = synthesizeAmbisonicIr({}, &h, s, 3, worldAmbisonicFrame());
  ASSERT_FALSE(ambi.isOk());
  EXPECT_NE(ambi.status().message().find("16 channels"), std::string::npos) << ambi.status().message();
  s.lengthSeconds = 2;
  auto shorter = synthesizeOmniIr(nullptr, &h, s);
  ASSERT_TRUE(shorter.isOk()) << shorter.status().message();
  EXPECT_EQ(shorter->frameCount(), 96000u);
  auto shorterAmbi = synthesizeAmbisonicIr({}, &h, s, 3, worldAmbisonicFrame());
  ASSERT_TRUE(shorterAmbi.isOk()) << shorterAmbi.status().message();
}

}  // namespace earshot

namespace earshot {
// The late part is one realisation of noise: its octave-band decay metrics
// scatter around the histogram's. Over 16 noise seeds, from one exponential
// histogram (T60 1 s in every band, from 5 ms), per band 250 Hz - 4 kHz: the
// mean EDT and T30 within 1 JND (5 %) of 1 s, their spread (standard
// deviation) under 1 and 0.5 JND. Plain noise spread EDT by 2.1 / 1.9 / 1.0
// / 0.5 / 0.5 JND and T30 by 0.8 .. 0.2; levelled band noise (see
// SpectralSynth::levelledBandNoise) by 0.85 / 0.53 / 0.30 / 0.21 / 0.17 and
// 0.19 .. 0.05.
TEST(IrSynthesis, NoiseSeedsBarelyMoveTheDecayMetrics) {
  EnergyHistogram h(0.001, 1400);
  const double rate = 13.8155 / 1.0;  // energy, 1/s
  for (size_t bin = 5; bin < 1400; ++bin)
    h.add(bin, filledBands(1e-3 * std::exp(-rate * double(bin) * 0.001)), {1, 0, 0});
  std::vector<std::vector<double>> edt(7), t30(7);
  for (uint64_t seed = 1; seed <= 16; ++seed) {
    IrSynthesisSettings s;
    s.seed = seed;
    s.lengthSeconds = 1.45;
    auto ir = synthesizeOmniIr(nullptr, &h, s);
    ASSERT_TRUE(ir.isOk());
    auto m = analysis::analyzeIr(ir->channels[0], 48000.0, {});
    ASSERT_TRUE(m.isOk());
    for (int b = 1; b <= 5; ++b) {
      edt[size_t(b)].push_back((*m)[size_t(b)].edtS);
      t30[size_t(b)].push_back((*m)[size_t(b)].t30S);
    }
  }
  auto meanOf = [](const std::vector<double>& x) {
    double mean = 0;
    for (double v : x) mean += v / double(x.size());
    return mean;
  };
  auto spreadJnd = [&](const std::vector<double>& x) {
    const double mean = meanOf(x);
    double var = 0;
    for (double v : x) var += (v - mean) * (v - mean) / double(x.size() - 1);
    return std::sqrt(var) / mean / 0.05;
  };
  for (int b = 1; b <= 5; ++b) {
    const auto &e = edt[size_t(b)], &t = t30[size_t(b)];
    std::printf("band %d: EDT mean %.3f s spread %.2f JND, T30 mean %.3f s spread %.2f JND\n", b, meanOf(e),
                spreadJnd(e), meanOf(t), spreadJnd(t));
    EXPECT_NEAR(meanOf(e), 1.0, 0.05) << "band " << b;
    EXPECT_NEAR(meanOf(t), 1.0, 0.05) << "band " << b;
    EXPECT_LT(spreadJnd(e), 1.0) << "band " << b;
    EXPECT_LT(spreadJnd(t), 0.5) << "band " << b;
  }
}
}  // namespace earshot
