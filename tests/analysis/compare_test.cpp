// JND arithmetic, tolerance files and the verdicts of compareMetrics.
#include "earshot/analysis/compare.h"

#include <gtest/gtest.h>

#include <cmath>

namespace earshot::analysis {
namespace {

std::vector<BandMetrics> uniformMetrics(double t, double c50, double d50, double ts) {
  std::vector<BandMetrics> v(kAnalysisBandCount);
  for (auto& m : v) {
    m.edtS = m.t20S = m.t30S = t;
    m.c50Db = c50;
    m.c80Db = c50 + 3.0;
    m.d50 = d50;
    m.tsS = ts;
  }
  return v;
}

TEST(Compare, DifferencesAreMeasuredInJnd) {
  EXPECT_DOUBLE_EQ(differenceInJnd(Metric::kT30, 1.05, 1.0), 1.0);   // 5 % of the reference
  EXPECT_DOUBLE_EQ(differenceInJnd(Metric::kEdt, 1.9, 2.0), -1.0);
  EXPECT_DOUBLE_EQ(differenceInJnd(Metric::kC80, 3.5, 1.5), 2.0);    // 1 dB
  EXPECT_DOUBLE_EQ(differenceInJnd(Metric::kD50, 0.6, 0.5), 2.0);    // 0.05
  EXPECT_NEAR(differenceInJnd(Metric::kTs, 0.035, 0.040), -0.5, 1e-12);  // 10 ms
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(differenceInJnd(Metric::kC50, inf, inf), 0.0);
  EXPECT_EQ(differenceInJnd(Metric::kC50, 20.0, inf), -inf);
  EXPECT_TRUE(std::isnan(differenceInJnd(Metric::kT20, kNaN, 1.0)));
}

TEST(Compare, IdenticalMetricsPassAndAScaledDecayFailsNamingTheMetric) {
  auto ref = uniformMetrics(1.0, 2.0, 0.6, 0.08);
  auto same = compareMetrics(ref, ref);
  ASSERT_TRUE(same.isOk());
  EXPECT_TRUE(same->withinTolerance());
  EXPECT_EQ(same->rows.size(), size_t(kAnalysisBandCount * kMetricCount));

  auto test = ref;
  test[3].t30S = 1.08;  // 1.6 JND at 1 kHz
  auto diff = compareMetrics(test, ref);
  ASSERT_TRUE(diff.isOk());
  EXPECT_EQ(diff->failures, 1);
  EXPECT_NEAR(diff->worstJnd, 1.6, 1e-9);
  for (const auto& row : diff->rows)
    if (row.verdict == Verdict::kFail) {
      EXPECT_EQ(row.metric, Metric::kT30);
      EXPECT_EQ(row.band, 3);
    }
}

TEST(Compare, NotAvailableInTheTestFailsButInTheReferenceIsSkipped) {
  auto ref = uniformMetrics(1.0, 2.0, 0.6, 0.08);
  auto test = ref;
  test[0].t30S = kNaN;
  test[0].naReason[size_t(Metric::kT30)] = "decay range too short";
  ref[1].t20S = kNaN;
  auto r = compareMetrics(test, ref);
  ASSERT_TRUE(r.isOk());
  EXPECT_EQ(r->failures, 1);
  int skipped = 0;
  for (const auto& row : r->rows) {
    if (row.verdict == Verdict::kFail) {
      EXPECT_NE(row.note.find("decay range too short"), std::string::npos);
    }
    if (row.verdict == Verdict::kSkipped) ++skipped;
  }
  EXPECT_EQ(skipped, 1);
}

TEST(Compare, ToleranceFileSetsLimitsPerMetricAndBandAndDisablesMetrics) {
  auto spec = parseTolerance(R"({"default_jnd": 2,
      "metrics": {"T30": 3, "C50": false,
                  "EDT": {"jnd": 1.5, "bands": {"125": 4, "8k": false, "broadband": 0.5}}}})",
                             "tol.json");
  ASSERT_TRUE(spec.isOk()) << spec.status().message();
  EXPECT_EQ(spec->limit(Metric::kT20, 2), 2.0);
  EXPECT_EQ(spec->limit(Metric::kT30, 2), 3.0);
  EXPECT_FALSE(spec->isEnabled(Metric::kC50, 4));
  EXPECT_EQ(spec->limit(Metric::kEdt, 0), 4.0);
  EXPECT_EQ(spec->limit(Metric::kEdt, 3), 1.5);
  EXPECT_FALSE(spec->isEnabled(Metric::kEdt, 6));
  EXPECT_EQ(spec->limit(Metric::kEdt, kBroadbandIndex), 0.5);

  auto ref = uniformMetrics(1.0, 2.0, 0.6, 0.08);
  auto test = ref;
  test[2].t30S = 1.12;   // 2.4 JND < 3: passes
  test[2].c50Db = 10.0;  // disabled
  CompareOptions o;
  o.tolerance = *spec;
  auto r = compareMetrics(test, ref, o);
  ASSERT_TRUE(r.isOk());
  EXPECT_TRUE(r->withinTolerance());
}

TEST(Compare, ToleranceFileErrorsNameTheField) {
  auto bad = parseTolerance(R"({"metrics": {"T30": -1}})", "tol.json");
  ASSERT_FALSE(bad.isOk());
  EXPECT_NE(bad.status().message().find("tol.json: metrics.T30"), std::string::npos) << bad.status().message();
  auto unknownMetric = parseTolerance(R"({"metrics": {"RT60": 1}})", "tol.json");
  ASSERT_FALSE(unknownMetric.isOk());
  EXPECT_NE(unknownMetric.status().message().find("RT60"), std::string::npos);
  auto unknownKey = parseTolerance(R"({"default": 1})", "tol.json");
  ASSERT_FALSE(unknownKey.isOk());
  EXPECT_NE(unknownKey.status().message().find("\"default\""), std::string::npos);
  // The file's keys and names are escaped onto one line (quotedName).
  auto newlineKey = parseTolerance(R"({"x\nFAKE": 1})", "tol.json");
  ASSERT_FALSE(newlineKey.isOk());
  EXPECT_EQ(newlineKey.status().message(), R"(tol.json: unknown key "x\nFAKE" (expected default_jnd, metrics))");
  auto newlineMetric = parseTolerance(R"({"metrics": {"T\r30": 1}})", "tol.json");
  ASSERT_FALSE(newlineMetric.isOk());
  EXPECT_NE(newlineMetric.status().message().find(R"("T\r30")"), std::string::npos) << newlineMetric.status().message();
  EXPECT_EQ(newlineMetric.status().message().find_first_of("\n\r"), std::string::npos);
  auto badBand = parseTolerance(R"({"metrics": {"EDT": {"bands": {"300": 1}}}})", "tol.json");
  ASSERT_FALSE(badBand.isOk());
  EXPECT_NE(badBand.status().message().find("300"), std::string::npos);
  EXPECT_FALSE(parseTolerance("{not json", "tol.json").isOk());
  // A number past a double: an error, not an escaping exception, and without
  // the file's text.
  auto overflow = parseTolerance(R"({"metrics": {"T30": 1e999}})", "tol.json");
  ASSERT_FALSE(overflow.isOk());
  EXPECT_EQ(overflow.status().message(), "tol.json: not valid JSON (number overflow parsing)");
  EXPECT_FALSE(loadToleranceFile("/nonexistent/tol.json").isOk());
}

TEST(Compare, AudioComparisonGoesChannelByChannel) {
  // Two-channel IRs: left identical, right with a 20 % longer decay.
  const double fs = 48000.0;
  auto decay = [&](double t) {
    std::vector<float> x(size_t(fs), 0.0f);
    uint32_t state = 12345;
    for (size_t i = 480; i < x.size(); ++i) {
      state = state * 1664525u + 1013904223u;  // LCG noise: same in both IRs
      const double u = double(state >> 8) / double(1u << 24) - 0.5;
      x[i] = float(u * std::exp(-6.9 * double(i - 480) / fs / t));
    }
    return x;
  };
  AudioBuffer ref(2, size_t(fs), fs), test(2, size_t(fs), fs);
  ref.channels[0] = ref.channels[1] = test.channels[0] = decay(0.4);
  test.channels[1] = decay(0.48);
  auto r = compareAudio(test, ref);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  ASSERT_EQ(r->channels.size(), 2u);
  EXPECT_TRUE(r->channels[0].withinTolerance());
  EXPECT_FALSE(r->channels[1].withinTolerance());
  auto left = compareAudio(test, ref, {}, {}, 0);
  ASSERT_TRUE(left.isOk());
  EXPECT_TRUE(left->withinTolerance());
  EXPECT_EQ(left->channelIndices, std::vector<int>{0});
  AudioBuffer mono(1, size_t(fs), fs);
  mono.channels[0] = decay(0.4);
  EXPECT_FALSE(compareAudio(test, mono).isOk());
}

TEST(Compare, BandNamesParse) {
  EXPECT_EQ(*parseBandName("125"), 0);
  EXPECT_EQ(*parseBandName("1k"), 3);
  EXPECT_EQ(*parseBandName("8000Hz"), 6);
  EXPECT_EQ(*parseBandName("broadband"), kBroadbandIndex);
  EXPECT_FALSE(parseBandName("300").isOk());
  EXPECT_EQ(bandLabel(3), "1 kHz");
  EXPECT_EQ(bandLabel(0), "125 Hz");
}

// Third octaves (issue 20): 21 bands and broadband compared, each third
// octave under its octave's tolerance (files name octaves), names parsed by
// their nominal centres; mixed band counts are an error.
TEST(Compare, ThirdOctavesTakeTheirOctavesTolerance) {
  std::vector<BandMetrics> ref(kThirdOctaveAnalysisBandCount), test;
  for (auto& m : ref) {
    m.edtS = m.t20S = m.t30S = 1.0;
    m.c50Db = 0.0;
    m.c80Db = 3.0;
    m.d50 = 0.5;
    m.tsS = 0.08;
  }
  test = ref;
  test[5].t20S = 1.08;  // 315 Hz: 1.6 JND
  auto tol = parseTolerance(R"({"metrics": {"T20": {"bands": {"250": 2.0}}}})", "tol");
  ASSERT_TRUE(tol.isOk());
  CompareOptions options;
  options.tolerance = *tol;
  auto c = compareMetrics(test, ref, options);
  ASSERT_TRUE(c.isOk()) << c.status().message();
  EXPECT_EQ(c->failures, 0) << "315 Hz lies in the 250 Hz octave, whose T20 limit is 2 JND";
  EXPECT_NEAR(c->worstJnd, 1.6, 1e-9);
  test[5].t20S = 1.0;
  test[6].t20S = 1.08;  // 400 Hz: the 500 Hz octave, 1 JND
  c = compareMetrics(test, ref, options);
  ASSERT_TRUE(c.isOk());
  ASSERT_EQ(c->failures, 1);
  for (const MetricDifference& r : c->rows)
    if (r.verdict == Verdict::kFail) {
      EXPECT_EQ(r.band, 6);
      EXPECT_EQ(bandLabel(r.band, ref.size()), "400 Hz");
    }
  EXPECT_EQ(octaveOfThirdOctave(0), 0);
  EXPECT_EQ(octaveOfThirdOctave(2), 0);
  EXPECT_EQ(octaveOfThirdOctave(3), 1);
  EXPECT_EQ(octaveOfThirdOctave(20), kNumBands - 1);
  EXPECT_EQ(*parseThirdOctaveBandName("3150"), 15);
  EXPECT_EQ(*parseThirdOctaveBandName("1.25k"), 11);
  EXPECT_EQ(*parseThirdOctaveBandName("broadband"), kNumThirdOctaveBands);
  EXPECT_FALSE(parseThirdOctaveBandName("300").isOk());
  EXPECT_EQ(bandLabel(kNumThirdOctaveBands, ref.size()), "broadband");
  EXPECT_FALSE(compareMetrics(test, std::vector<BandMetrics>(kAnalysisBandCount), {}).isOk());
}

}  // namespace
}  // namespace earshot::analysis
