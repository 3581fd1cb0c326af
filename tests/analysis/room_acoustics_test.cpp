// Known-answer tests of the ISO 3382-1 parameters on synthetic IRs.
#include "earshot/analysis/room_acoustics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "earshot/analysis/octave_filter.h"

namespace earshot::analysis {
namespace {

constexpr double kFs = 48000.0;
constexpr double kPi = 3.14159265358979323846;

// Gaussian noise with amplitude envelope exp(-6.9 t / T) (energy falls 60 dB in
// T) starting at `startS`, `lengthS` long; plus stationary noise whose energy
// per sample is `noiseDb` below the decay's initial energy per sample.
std::vector<float> noiseDecay(double tS, double startS, double lengthS, uint32_t seed, double noiseDb = -1000.0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  const size_t n = size_t(lengthS * kFs), start = size_t(startS * kFs);
  const double noiseAmp = std::pow(10.0, noiseDb / 20.0);
  std::vector<float> x(n, 0.0f);
  for (size_t i = 0; i < n; ++i) {
    double v = noiseDb > -900.0 ? noiseAmp * g(rng) : 0.0;
    if (i >= start) v += g(rng) * std::exp(-6.9 * double(i - start) / kFs / tS);
    x[i] = float(v);
  }
  return x;
}

// Statistical tolerance of decay times measured on one noise decay: ISO
// 3382-2:2008 (A.2, after Davy) gives sigma(T20) = 0.88 T sqrt(1 / (B T)) and
// sigma(T30) = 0.55 T sqrt(1 / (B T)) for bandwidth B (one decay, impulse
// method ~ many averages). We allow 4 sigma (a fixed seed, but any seed must
// pass). EDT fits a 10 dB range, half of T20's: the slope variance of a line
// fit grows as range^-3, so sigma(EDT) ~ 2^1.5 sigma(T20).
double sigmaRel(double factor, double bandwidthHz, double tS) { return factor * std::sqrt(1.0 / (bandwidthHz * tS)); }

TEST(RoomAcoustics, ExponentialNoiseDecayGivesItsReverberationTimeBroadband) {
  const double t = 1.0;
  auto ir = noiseDecay(t, 0.01, 1.6, 1);  // ends 96 dB down: noise-free data that simply ends
  auto r = analyzeIr(ir, kFs);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const BandMetrics& bb = (*r)[kBroadbandIndex];
  const double b = kFs / 2;
  EXPECT_NEAR(bb.t20S, t, 4 * sigmaRel(0.88, b, t) * t);
  EXPECT_NEAR(bb.t30S, t, 4 * sigmaRel(0.55, b, t) * t);
  EXPECT_NEAR(bb.edtS, t, 4 * sigmaRel(0.88 * 2.83, b, t) * t);
  EXPECT_FALSE(bb.noiseFloorFound) << "a decay that ends is not noise";
  EXPECT_NEAR(bb.onsetS, 0.01, 1e-3);
}

TEST(RoomAcoustics, ExponentialNoiseDecayGivesItsReverberationTimeInOctaveBands) {
  const double t = 1.0;
  auto ir = noiseDecay(t, 0.01, 1.6, 2);
  auto r = analyzeIr(ir, kFs);
  ASSERT_TRUE(r.isOk());
  for (int b : {3, 4, 5}) {  // 1, 2, 4 kHz: bandwidth fc / sqrt(2)
    const double bw = kBandCentersHz[size_t(b)] / std::sqrt(2.0);
    const BandMetrics& m = (*r)[size_t(b)];
    EXPECT_NEAR(m.t30S, t, 4 * sigmaRel(0.55, bw, t) * t) << kBandCentersHz[size_t(b)];
    EXPECT_NEAR(m.t20S, t, 4 * sigmaRel(0.88, bw, t) * t) << kBandCentersHz[size_t(b)];
  }
}

// A decaying sine at each band centre has one exact decay rate and no
// statistical scatter. A causal octave filter at 125 Hz rings for ~25 ms and
// would lengthen a 0.3 s EDT; the zero-phase filter must not: after its
// ~5 ms build-up the band envelope is the sine's. Tolerance 2 % (0.4 JND): the
// filter's symmetric build-up at the onset shifts the 0..-10 dB fit slightly.
TEST(RoomAcoustics, ShortDecayIsNotLengthenedByTheOctaveFilter) {
  const double t = 0.3;
  for (int b = 0; b < kNumBands; ++b) {
    const double f = kBandCentersHz[size_t(b)];
    std::vector<float> ir(size_t(0.6 * kFs), 0.0f);
    const size_t start = size_t(0.02 * kFs);
    for (size_t i = start; i < ir.size(); ++i) {
      const double ts = double(i - start) / kFs;
      ir[i] = float(std::sin(2 * kPi * f * ts + 0.3) * std::exp(-6.9 * ts / t));
    }
    auto r = analyzeIr(ir, kFs);
    ASSERT_TRUE(r.isOk());
    const BandMetrics& m = (*r)[size_t(b)];
    EXPECT_NEAR(m.edtS, t, 0.02 * t) << f << " Hz";
    EXPECT_NEAR(m.t20S, t, 0.02 * t) << f << " Hz";
    EXPECT_NEAR(m.t30S, t, 0.02 * t) << f << " Hz";
  }
  // The 125 Hz limit: EDT = 0.1 s still within 1 JND (a causal filter would
  // need T > 0.18 s by the usual B T > 16 rule).
  std::vector<float> ir(size_t(0.6 * kFs), 0.0f);
  for (size_t i = 960; i < ir.size(); ++i) {
    const double ts = double(i - 960) / kFs;
    ir[i] = float(std::sin(2 * kPi * 125.0 * ts + 0.3) * std::exp(-6.9 * ts / 0.1));
  }
  auto r = analyzeIr(ir, kFs);
  ASSERT_TRUE(r.isOk());
  EXPECT_NEAR((*r)[0].edtS, 0.1, kJndDecayRelative * 0.1);
}

TEST(RoomAcoustics, PureImpulseHasOnlyEarlyEnergy) {
  std::vector<float> ir(size_t(0.5 * kFs), 0.0f);
  ir[480] = 0.5f;
  auto r = analyzeIr(ir, kFs);
  ASSERT_TRUE(r.isOk());
  const BandMetrics& bb = (*r)[kBroadbandIndex];
  EXPECT_EQ(bb.c50Db, std::numeric_limits<double>::infinity());
  EXPECT_EQ(bb.c80Db, std::numeric_limits<double>::infinity());
  EXPECT_DOUBLE_EQ(bb.d50, 1.0);
  EXPECT_DOUBLE_EQ(bb.tsS, 0.0);
  EXPECT_DOUBLE_EQ(bb.onsetS, 0.01);
  // No decay to fit: n/a with a reason, never a number.
  for (Metric m : {Metric::kEdt, Metric::kT20, Metric::kT30}) {
    EXPECT_TRUE(std::isnan(bb.value(m)));
    EXPECT_NE(bb.reason(m).find("decay range too short"), std::string::npos) << bb.reason(m);
  }
  // Per band the filtered impulse decays with the filter's own ringing
  // (T30 ~ 4.3 / fc), which is not the room's: n/a, naming the filter.
  for (int b = 0; b < kNumBands; ++b)
    for (Metric m : {Metric::kEdt, Metric::kT20, Metric::kT30}) {
      EXPECT_TRUE(std::isnan((*r)[size_t(b)].value(m))) << kBandCentersHz[size_t(b)] << " " << metricName(m);
      EXPECT_FALSE((*r)[size_t(b)].reason(m).empty());
    }
  // Per band the zero-phase filter spreads the impulse symmetrically about the
  // onset (the pre-ringing counts as early energy): D50 = 1 and Ts = 0 up to
  // the -50 dB guard (energy beyond 50 ms is < 1e-5, the moment < 1e-5 s).
  for (int b = 0; b < kNumBands; ++b) {
    const BandMetrics& m = (*r)[size_t(b)];
    EXPECT_NEAR(m.d50, 1.0, 1e-5) << kBandCentersHz[size_t(b)];
    EXPECT_NEAR(m.tsS, 0.0, 1e-5) << kBandCentersHz[size_t(b)];
    EXPECT_GT(m.c50Db, 50.0) << kBandCentersHz[size_t(b)];
  }
}

TEST(RoomAcoustics, ImpulseTrainGivesExactEnergyRatios) {
  // Energies 1 at the onset, 1/4 at +70 ms, 1/16 at +100 ms.
  std::vector<float> ir(size_t(0.3 * kFs), 0.0f);
  const size_t on = 480;
  ir[on] = 1.0f;
  ir[on + size_t(0.070 * kFs)] = 0.5f;
  ir[on + size_t(0.100 * kFs)] = 0.25f;
  for (NoiseTreatment nt : {NoiseTreatment::kLundeby, NoiseTreatment::kNone}) {
    BandMetrics m = analyzeBandSignal(ir.data(), ir.size(), kFs, -1, 0, nt);
    EXPECT_NEAR(m.c50Db, 10 * std::log10(1.0 / 0.3125), 1e-9);
    EXPECT_NEAR(m.c80Db, 10 * std::log10(1.25 / 0.0625), 1e-9);
    EXPECT_NEAR(m.d50, 1.0 / 1.3125, 1e-12);
    EXPECT_NEAR(m.tsS, (0.25 * 0.070 + 0.0625 * 0.100) / 1.3125, 1e-12);
    EXPECT_DOUBLE_EQ(m.onsetS, 0.01);
  }
}

TEST(RoomAcoustics, TwoImpulsesWithinFiftyMillisecondsGiveInfiniteClarity) {
  std::vector<float> ir(4800, 0.0f);
  ir[100] = 1.0f;
  ir[100 + 1440] = -1.0f;  // +30 ms
  BandMetrics m = analyzeBandSignal(ir, kFs);
  EXPECT_EQ(m.c50Db, std::numeric_limits<double>::infinity());
  EXPECT_DOUBLE_EQ(m.d50, 1.0);
  EXPECT_NEAR(m.tsS, 0.015, 1e-12);
}

// Lundeby's treatment: with stationary noise 50 dB below the decay's start,
// T20 and T30 still come out right (4 sigma as above plus 1 % for the
// method's residual bias: over seeds 3..8 the mean T30 error is +0.02 %, it
// was +1.3 % before the noise was also subtracted); integrating the noise
// instead lengthens T30 far beyond that. With noise 30 dB down, T20/T30 lack the ISO 10 dB margin
// and must be n/a, not garbage.
TEST(RoomAcoustics, LundebyTruncationHandlesANoiseFloor) {
  const double t = 0.5;
  auto ir = noiseDecay(t, 0.01, 2.0, 3, -50.0);
  auto r = analyzeIr(ir, kFs);
  ASSERT_TRUE(r.isOk());
  const BandMetrics& bb = (*r)[kBroadbandIndex];
  EXPECT_TRUE(bb.noiseFloorFound);
  EXPECT_NEAR(bb.noiseFloorDb, -50.0, 2.0);
  EXPECT_NEAR(bb.t30S, t, (4 * sigmaRel(0.55, kFs / 2, t) + 0.01) * t);
  EXPECT_NEAR(bb.t20S, t, (4 * sigmaRel(0.88, kFs / 2, t) + 0.01) * t);
  EXPECT_LT(bb.decayEndS, 0.01 + 50.0 / 60.0 * t + 0.1);  // cross-point near where the decay meets the noise

  AnalysisOptions none;
  none.noise = NoiseTreatment::kNone;
  auto raw = analyzeIr(ir, kFs, none);
  ASSERT_TRUE(raw.isOk());
  // Without the treatment the noise either lengthens T30 or (correctly) makes
  // it n/a; it must not come out right by accident, or this test proves nothing.
  EXPECT_FALSE(std::abs((*raw)[kBroadbandIndex].t30S - t) < 0.1 * t) << (*raw)[kBroadbandIndex].t30S;

  auto noisy = analyzeIr(noiseDecay(t, 0.01, 2.0, 4, -30.0), kFs);
  ASSERT_TRUE(noisy.isOk());
  const BandMetrics& nb = (*noisy)[kBroadbandIndex];
  EXPECT_TRUE(std::isnan(nb.t30S));
  EXPECT_TRUE(std::isnan(nb.t20S));
  EXPECT_NE(nb.reason(Metric::kT30).find("decay range too short"), std::string::npos);
  EXPECT_NEAR(nb.edtS, t, 0.1 * t);  // EDT needs only 20 dB
}

// A double-slope decay (fast, then a slow tail 30 dB down, as in a broadband
// IR whose low bands ring longer) that simply ends is not noise: the tail
// still decays at its own, slower rate. T30 is then the -5..-35 dB fit of the
// two-slope EDC, which lies between the two decay times.
TEST(RoomAcoustics, DoubleSlopeDecayIsNotMistakenForNoise) {
  auto fast = noiseDecay(0.3, 0.01, 3.0, 9), slow = noiseDecay(2.0, 0.01, 3.0, 10);
  std::vector<float> ir(fast.size());
  for (size_t i = 0; i < ir.size(); ++i) ir[i] = fast[i] + 0.03f * slow[i];
  auto r = analyzeIr(ir, kFs);
  ASSERT_TRUE(r.isOk());
  const BandMetrics& bb = (*r)[kBroadbandIndex];
  EXPECT_FALSE(bb.noiseFloorFound);
  EXPECT_GT(bb.t30S, 0.3);
  EXPECT_LT(bb.t30S, 2.0);
}

TEST(RoomAcoustics, WindowEndTruncatesTheDecay) {
  auto ir = noiseDecay(1.0, 0.01, 1.6, 5);
  AnalysisOptions o;
  o.windowEndS = 0.45;  // the decay reaches only ~-27 dB by then: EDT yes, T20/T30 no
  auto r = analyzeIr(ir, kFs, o);
  ASSERT_TRUE(r.isOk());
  const BandMetrics& bb = (*r)[kBroadbandIndex];
  EXPECT_TRUE(std::isnan(bb.t30S));
  EXPECT_TRUE(std::isnan(bb.t20S));
  EXPECT_FALSE(std::isnan(bb.edtS));
  EXPECT_NE(bb.reason(Metric::kT20).find("data ends"), std::string::npos) << bb.reason(Metric::kT20);
  EXPECT_LE(bb.decayEndS, 0.45 + 1.0 / kFs);
}

TEST(RoomAcoustics, WindowCanCountFromTheDirectSound) {
  // Impulses at 100 ms (direct) and +30 ms; a window [0, 20 ms) from the
  // emission holds nothing (an error), from the direct sound only the direct.
  std::vector<float> ir(size_t(0.3 * kFs), 0.0f);
  ir[4800] = 1.0f;
  ir[4800 + 1440] = 1.0f;
  AnalysisOptions o;
  o.windowEndS = 0.02;
  EXPECT_FALSE(analyzeIr(ir, kFs, o).isOk());
  o.windowOrigin = WindowOrigin::kDirectSound;
  auto r = analyzeIr(ir, kFs, o);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_DOUBLE_EQ((*r)[kBroadbandIndex].tsS, 0.0);  // the reflection at +30 ms is outside
  o.windowEndS = 0.05;
  r = analyzeIr(ir, kFs, o);
  ASSERT_TRUE(r.isOk());
  EXPECT_NEAR((*r)[kBroadbandIndex].tsS, 0.015, 1e-12);
}

TEST(RoomAcoustics, IgnoringTheDirectSoundRemovesItsEnergy) {
  std::vector<float> ir(size_t(0.3 * kFs), 0.0f);
  ir[480] = 1.0f;
  ir[480 + size_t(0.070 * kFs)] = 0.5f;
  AnalysisOptions o;
  o.direct = DirectSound::kExclude;
  auto r = analyzeIr(ir, kFs, o);
  ASSERT_TRUE(r.isOk());
  const BandMetrics& bb = (*r)[kBroadbandIndex];
  EXPECT_DOUBLE_EQ(bb.d50, 0.0);                 // only the reflection at 70 ms is left
  EXPECT_NEAR(bb.tsS, 0.070, 1e-12);             // time still counts from the direct sound
  EXPECT_EQ(bb.c50Db, -std::numeric_limits<double>::infinity());
}

TEST(RoomAcoustics, BadInputIsAnErrorNotAnAbort) {
  EXPECT_FALSE(analyzeIr({}, kFs).isOk());
  EXPECT_FALSE(analyzeIr(std::vector<float>(100, 0.0f), kFs).isOk());
  std::vector<float> nanIr(100, 0.1f);
  nanIr[7] = std::numeric_limits<float>::quiet_NaN();
  auto r = analyzeIr(nanIr, kFs);
  ASSERT_FALSE(r.isOk());
  EXPECT_NE(r.status().message().find("sample 7"), std::string::npos);
  EXPECT_FALSE(analyzeIr(std::vector<float>(100, 0.1f), -1.0).isOk());
  EXPECT_FALSE(analyzeIr(std::vector<float>(100, 0.1f), 1.0).isOk());
  AnalysisOptions o;
  o.windowStartS = 1.0;
  o.windowEndS = 0.5;
  EXPECT_FALSE(analyzeIr(std::vector<float>(100, 0.1f), kFs, o).isOk());
}

TEST(RoomAcoustics, BandAboveTheSampleRateIsNotAvailable) {
  auto ir = noiseDecay(0.3, 0.01, 0.5, 6);
  auto r = analyzeIr(ir, 16000.0);
  ASSERT_TRUE(r.isOk());
  EXPECT_TRUE(std::isnan((*r)[6].edtS));
  EXPECT_NE((*r)[6].reason(Metric::kEdt).find("sample rate"), std::string::npos);
  EXPECT_FALSE(std::isnan((*r)[3].edtS));
  EXPECT_FALSE(octaveBandAvailable(16000.0, 8000.0));
  EXPECT_TRUE(octaveBandAvailable(44100.0, 8000.0));
}

TEST(RoomAcoustics, EachChannelOfABinauralIrIsAnalysed) {
  AudioBuffer audio(2, size_t(1.2 * kFs), kFs);
  audio.channels[0] = noiseDecay(0.4, 0.01, 1.2, 7);
  audio.channels[1] = noiseDecay(0.8, 0.012, 1.2, 8);
  auto r = analyzeAudio(audio);
  ASSERT_TRUE(r.isOk());
  ASSERT_EQ(r->channels.size(), 2u);
  EXPECT_NEAR(r->channels[0][kBroadbandIndex].t30S, 0.4, 0.02);
  EXPECT_NEAR(r->channels[1][kBroadbandIndex].t30S, 0.8, 0.04);
  EXPECT_NEAR(r->channels[1][kBroadbandIndex].onsetS, 0.012, 1e-3);
  auto one = analyzeAudio(audio, {}, 1);
  ASSERT_TRUE(one.isOk());
  ASSERT_EQ(one->channels.size(), 1u);
  EXPECT_EQ(one->channels[0][kBroadbandIndex].t30S, r->channels[1][kBroadbandIndex].t30S);
  EXPECT_FALSE(analyzeAudio(audio, {}, 2).isOk());
}

TEST(OctaveFilter, PassesItsCentreAndHalfPowerAtTheEdges) {
  // Steady sines (measured after the filter's transient): -3 dB (power 0.5)
  // at the nominal octave edges, exact by design on the pre-warped axis (0.05
  // dB for the sine's finite length); at the centre the prototype's value
  // on the warped axis W = tan(pi f / fs), -0.44 dB well below Nyquist.
  for (double fc : {125.0, 1000.0, 8000.0}) {
    for (double ratio : {1.0, std::sqrt(0.5), std::sqrt(2.0)}) {
      const double f = fc * ratio;
      std::vector<float> x(size_t(kFs), 0.0f);
      for (size_t i = 0; i < x.size(); ++i) x[i] = float(std::sin(2 * kPi * f * double(i) / kFs));
      size_t guard = 0;
      auto y = octaveBandFilter(x.data(), x.size(), kFs, fc, &guard);
      double ein = 0, eout = 0;
      for (size_t i = x.size() / 4; i < 3 * x.size() / 4; ++i) {
        ein += double(x[i]) * x[i];
        eout += y[guard + i] * y[guard + i];
      }
      const double gainDb = 10 * std::log10(eout / ein);
      auto w = [](double hz) { return std::tan(kPi * hz / kFs); };
      const double k = std::pow(std::sqrt(2.0) - 1.0, 1.0 / 8);  // edge factor of the design
      const double whp = w(fc / std::sqrt(2.0)) * k, wlp = w(fc * std::sqrt(2.0)) / k;
      const double centre =
          2 * 10 * std::log10(1.0 / (1.0 + std::pow(whp / w(fc), 8)) / (1.0 + std::pow(w(fc) / wlp, 8)));
      EXPECT_NEAR(gainDb, ratio == 1.0 ? centre : 10 * std::log10(0.5), 0.05) << fc << " Hz x " << ratio;
    }
  }
}

// Third octaves (issue 20): a steady sine's gain at the centre (0 dB), at
// the edges (half power, exact by design on the pre-warped axis; measured
// -3.0102 to -3.0104 dB, 0.05 dB allowed for the sine's finite length as
// the octave test does) and at the neighbouring third octaves' centres (the
// skirts: what a band passes of its neighbours; measured -35 to -39 dB).
TEST(ThirdOctaveAnalysis, FilterPassesItsCentreHalfPowerAtTheEdgesAndDampsItsNeighbours) {
  auto gainDb = [](double fc, double f) {
    std::vector<float> x(size_t(kFs), 0.0f);
    for (size_t i = 0; i < x.size(); ++i) x[i] = float(std::sin(2 * kPi * f * double(i) / kFs));
    std::vector<double> y;
    size_t guard = 0;
    fractionalOctaveBandFilterInto(x.data(), x.size(), kFs, fc, 1.0 / 3.0, y, &guard);
    double ein = 0, eout = 0;
    for (size_t i = x.size() / 4; i < 3 * x.size() / 4; ++i) {
      ein += double(x[i]) * x[i];
      eout += y[guard + i] * y[guard + i];
    }
    return 10 * std::log10(eout / ein);
  };
  for (int j : {1, 10, 19}) {  // 125 Hz, 1 kHz, 8 kHz
    const double fc = thirdOctaveCenterHz(j);
    EXPECT_NEAR(gainDb(fc, fc), 0.0, 0.05) << fc;
    EXPECT_NEAR(gainDb(fc, fc * std::exp2(-1.0 / 6.0)), -3.01, 0.05) << fc;
    EXPECT_NEAR(gainDb(fc, fc * std::exp2(1.0 / 6.0)), -3.01, 0.05) << fc;
    const double below = gainDb(fc, fc * std::exp2(-1.0 / 3.0)), above = gainDb(fc, fc * std::exp2(1.0 / 3.0));
    EXPECT_LT(below, -30.0) << fc;
    EXPECT_LT(above, -30.0) << fc;
    std::printf("third octave %.0f Hz: neighbours' centres at %.1f dB (below) and %.1f dB (above)\n", fc, below, above);
  }
}

// A decaying sine at each third octave's centre: EDT, T20 and T30 within
// 1 JND (5 %) at the shortest decays the analysis reports (EDT 45 / fc,
// T 36 / fc; measured: EDT within 3.3 %, T20/T30 within 1.2 % there, T20
// 7 % long at 24 / fc), n/a below; and 21 + 1 results, broadband last.
TEST(ThirdOctaveAnalysis, ShortestReportedDecaysAreWithinOneJnd) {
  AnalysisOptions options;
  options.bands = AnalysisOptions::Bands::kThirdOctave;
  for (int j = 0; j < kNumThirdOctaveBands; ++j) {
    const double f = thirdOctaveCenterHz(j);
    for (const double tS : {45.0 / f * 1.06, 36.0 / f * 1.02}) {  // EDT reads up to 3.3 % short there
      std::vector<float> ir(size_t((0.05 + 2.5 * tS) * kFs), 0.0f);
      const size_t start = size_t(0.02 * kFs);
      for (size_t i = start; i < ir.size(); ++i) {
        const double ts = double(i - start) / kFs;
        ir[i] = float(std::sin(2 * kPi * f * ts + 0.3) * std::exp(-6.9 * ts / tS));
      }
      auto r = analyzeIr(ir, kFs, options);
      ASSERT_TRUE(r.isOk());
      ASSERT_EQ(r->size(), size_t(kThirdOctaveAnalysisBandCount));
      EXPECT_EQ(r->back().bandCenterHz, 0.0);
      const BandMetrics& m = (*r)[size_t(j)];
      EXPECT_DOUBLE_EQ(m.bandCenterHz, f);
      if (tS * f >= 45.0) {
        EXPECT_NEAR(m.edtS, tS, kJndDecayRelative * tS) << f << " Hz, EDT of " << tS;
      }
      EXPECT_NEAR(m.t20S, tS, kJndDecayRelative * tS) << f << " Hz, T20 of " << tS;
      EXPECT_NEAR(m.t30S, tS, kJndDecayRelative * tS) << f << " Hz, T30 of " << tS;
    }
    // Below the limits: n/a with the reason.
    const double tS = 20.0 / f;
    std::vector<float> ir(size_t((0.05 + 2.5 * tS) * kFs), 0.0f);
    for (size_t i = 960; i < ir.size(); ++i) {
      const double ts = double(i - 960) / kFs;
      ir[i] = float(std::sin(2 * kPi * f * ts + 0.3) * std::exp(-6.9 * ts / tS));
    }
    auto r = analyzeIr(ir, kFs, options);
    ASSERT_TRUE(r.isOk());
    EXPECT_TRUE(std::isnan((*r)[size_t(j)].t20S)) << f;
    EXPECT_NE((*r)[size_t(j)].reason(Metric::kT20).find("third-octave"), std::string::npos);
  }
}

}  // namespace
}  // namespace earshot::analysis
