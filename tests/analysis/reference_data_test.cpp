// Our ISO 3382-1 parameters against independent reference data
// (tests/data/reference, see PROVENANCE.md there).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>

#include "earshot/analysis/compare.h"
#include "earshot/analysis/room_acoustics.h"
#include "earshot/io/wav.h"

namespace earshot::analysis {
namespace {

const std::string kRefDir = std::string(EARSHOT_TEST_DATA_DIR) + "/reference";

nlohmann::json readJson(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  return nlohmann::json::parse(in);
}

// shoebox_multiband/meta.json lists the metrics of the exact specular IR per
// band; band_irs_7ch.wav holds that IR, one already band-limited impulse train
// per channel, so it is measured WITHOUT an octave filter (analyzeBandSignal).
//
// How meta.json defines them (found by matching, to 1e-6 relative):
// - time and the EDC start at the direct sound (ISO onset), not at t = 0: Ts
//   measured from t = 0 would be 14.6 ms (the direct delay, 1.5 JND) larger;
// - the EDC is integrated over the exact part only (t < t_complete = 2.0 s,
//   the whole file) with no tail compensation: NoiseTreatment::kNone;
// - early energy is the samples with t - t_direct < 50 / 80 ms.
// With those, EDT, C50, C80, D50, Ts and the converged T20/T30 agree within
// 0.01 JND (the residue is float32 storage of the WAV: ~1e-7 relative).
TEST(ReferenceData, ShoeboxBandMetricsMatchMetaJson) {
  auto wav = readAudioFile(kRefDir + "/shoebox_multiband/band_irs_7ch.wav");
  ASSERT_TRUE(wav.isOk()) << wav.status().message();
  ASSERT_EQ(wav->channelCount(), size_t(kNumBands));
  const auto meta = readJson(kRefDir + "/shoebox_multiband/meta.json");
  const auto& bm = meta.at("band_metrics");
  for (int b = 0; b < kNumBands; ++b) {
    const std::string key = std::to_string(int(kBandCentersHz[size_t(b)]));
    const auto& ref = bm.at(key);
    const auto& ch = wav->channels[size_t(b)];
    for (NoiseTreatment nt : {NoiseTreatment::kNone, NoiseTreatment::kLundeby}) {
      // With the default (Lundeby) the exact data must be recognised as
      // noise-free (its last 10 % still decays) and give the same numbers.
      BandMetrics m = analyzeBandSignal(ch.data(), ch.size(), wav->sampleRateHz, -1, 0, nt);
      EXPECT_FALSE(m.noiseFloorFound) << key;
      const double tol = 0.01;  // JND
      EXPECT_NEAR(differenceInJnd(Metric::kEdt, m.edtS, ref.at("EDT").get<double>()), 0.0, tol) << key;
      EXPECT_NEAR(differenceInJnd(Metric::kC50, m.c50Db, ref.at("C50").get<double>()), 0.0, tol) << key;
      EXPECT_NEAR(differenceInJnd(Metric::kC80, m.c80Db, ref.at("C80").get<double>()), 0.0, tol) << key;
      EXPECT_NEAR(differenceInJnd(Metric::kD50, m.d50, ref.at("D50").get<double>()), 0.0, tol) << key;
      EXPECT_NEAR(differenceInJnd(Metric::kTs, m.tsS, ref.at("Ts").get<double>()), 0.0, tol) << key;
      if (ref.at("T20_converged").get<bool>()) {
        EXPECT_NEAR(differenceInJnd(Metric::kT20, m.t20S, ref.at("T20").get<double>()), 0.0, tol)
            << key << " " << m.reason(Metric::kT20);
      }
      if (ref.at("T30_converged").get<bool>()) {
        EXPECT_NEAR(differenceInJnd(Metric::kT30, m.t30S, ref.at("T30").get<double>()), 0.0, tol)
            << key << " " << m.reason(Metric::kT30);
      }
    }
  }
}

// pyroomacoustics' pure image-source IRs (one broadband channel, sinc taps, a
// global delay of 40 samples) against the metrics its summary.json lists.
//
// Findings: summary.json's `metrics_pra` are broadband, timed from the direct
// sound (the 40-sample delay does not enter Ts), and their EDC covers only the
// exact part t < t_complete. Measured that way (window end = t_complete) we
// agree within 0.05 JND on every metric of all three files, except one we
// refuse to give: the alpha = 0.1 T30. There the exact part ends when the
// decay is only ~44.8 dB down (extrapolated), short of the 10 dB margin below
// the -35 dB fit end, so the truncated EDC bends down inside the fit range and
// the summary's 2.395 s is biased short: over the whole file (which goes on
// past t_complete = 1.90 s with an incomplete set of images, order <= 245, so
// the EDC's end is higher) T30 is 2.420 s, and the true infinite-order value
// is longer still. Who is wrong: the summary's alpha = 0.1 T30 is a truncation
// artefact of ~1 % (0.2 JND); pyroomacoustics' IR itself is right (its
// `metrics_ismref_*` from an independent image-source code agree to 1e-4).
TEST(ReferenceData, PyroomacousticsIsmMetricsMatchItsSummary) {
  const auto summary = readJson(kRefDir + "/pyroomacoustics/summary.json");
  struct Case {
    const char* alpha;
    const char* file;
  };
  for (Case c : {Case{"0.1", "pra_ism_a0.1_order245.wav"}, Case{"0.3", "pra_ism_a0.3_order97.wav"},
                 Case{"0.6", "pra_ism_a0.6_order40.wav"}}) {
    const auto& s = summary.at("ism").at(c.alpha);
    auto wav = readAudioFile(kRefDir + "/pyroomacoustics/" + c.file);
    ASSERT_TRUE(wav.isOk()) << wav.status().message();
    AnalysisOptions o;
    o.windowEndS = s.at("t_complete_s").get<double>();
    auto r = analyzeIr(wav->channels[0], wav->sampleRateHz, o);
    ASSERT_TRUE(r.isOk()) << r.status().message();
    const BandMetrics& bb = (*r)[kBroadbandIndex];
    const auto& ref = s.at("metrics_pra");
    for (Metric m : kAllMetrics) {
      if (std::string(c.alpha) == "0.1" && m == Metric::kT30) {
        EXPECT_TRUE(std::isnan(bb.t30S));
        EXPECT_NE(bb.reason(m).find("data ends"), std::string::npos) << bb.reason(m);
        continue;
      }
      const double d = differenceInJnd(m, bb.value(m), ref.at(metricName(m)).get<double>());
      EXPECT_NEAR(d, 0.0, 0.05) << c.file << " " << metricName(m) << " " << bb.value(m) << " "
                                << bb.reason(m);
    }
    // The direct sound (5 m, 40-sample global delay) is where ISO's onset puts
    // it, up to 2 samples early: the first side lobe of a sinc tap at a
    // fractional position (sinc(1.7) = -16 dB) is already within 20 dB.
    EXPECT_NEAR(bb.onsetS, 5.0 / 343.0 + 40.0 / 48000.0, 2.0 / 48000.0) << c.file;
  }
}

// The whole-file T30 of the alpha = 0.1 file, documenting the finding above:
// the tail past t_complete lengthens it against the summary's truncated value
// by ~1 % (0.2 JND).
TEST(ReferenceData, PyroomacousticsTailPastCompletionLengthensT30) {
  auto wav = readAudioFile(kRefDir + "/pyroomacoustics/pra_ism_a0.1_order245.wav");
  ASSERT_TRUE(wav.isOk());
  const auto summary = readJson(kRefDir + "/pyroomacoustics/summary.json");
  const double truncated = summary.at("ism").at("0.1").at("metrics_pra").at("T30").get<double>();
  auto whole = analyzeIr(wav->channels[0], wav->sampleRateHz);
  ASSERT_TRUE(whole.isOk());
  const double tw = (*whole)[kBroadbandIndex].t30S;
  EXPECT_GT(tw, truncated * 1.005);
  EXPECT_LT(tw, truncated * 1.02);
}

}  // namespace
}  // namespace earshot::analysis
