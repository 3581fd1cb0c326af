#pragma once
/** @file Comparison of two IRs' ISO 3382-1 parameters in just-noticeable
 *  differences (JND), with per-metric and per-band tolerances.
 *
 *  JND sizes (room_acoustics.h): EDT, T20, T30 5 % of the reference value;
 *  C50, C80 1 dB; D50 0.05; Ts 10 ms. A difference is "within tolerance" when
 *  |test - reference| / JND <= the limit (default 1 JND).
 *
 *  Threading: pure functions; any thread. */
#include <array>
#include <string>
#include <vector>

#include "earshot/analysis/room_acoustics.h"
#include "earshot/core/status.h"

namespace earshot::analysis {

/** Size of one JND of `metric` in its own unit, given the reference value
 *  (used by the relative JND of decay times). */
double jndSize(Metric metric, double referenceValue);

/** Signed difference (test - reference) in JND. Equal values (including
 *  +inf == +inf) give 0; NaN in either gives NaN. */
double differenceInJnd(Metric metric, double testValue, double referenceValue);

/** Tolerance per metric and per analysis band (index < kAnalysisBandCount:
 *  octave bands then broadband), in JND. */
struct ToleranceSpec {
  std::array<std::array<double, kAnalysisBandCount>, kMetricCount> limitJnd;
  std::array<std::array<bool, kAnalysisBandCount>, kMetricCount> enabled;

  /** Every metric and band enabled with `jnd` (> 0). */
  explicit ToleranceSpec(double jnd);
  /** Every metric and band enabled with 1 JND. */
  ToleranceSpec() : ToleranceSpec(1.0) {}
  double limit(Metric m, int band) const { return limitJnd[size_t(m)][size_t(band)]; }
  bool isEnabled(Metric m, int band) const { return enabled[size_t(m)][size_t(band)]; }
};

/** Parses a tolerance file's text. Format (all keys optional):
 *  { "default_jnd": 1.0,
 *    "metrics": { "T30": 2.0,                 // limit for every band
 *                 "C50": false,               // metric disabled
 *                 "EDT": { "jnd": 1.5, "enabled": true,
 *                          "bands": { "125": 3.0, "8000": false, "broadband": 1.0 } } } }
 *  Unknown keys, unknown metrics or bands, and limits <= 0 are errors naming
 *  `sourceName` and the field. */
Result<ToleranceSpec> parseTolerance(const std::string& jsonText, const std::string& sourceName);
/** Reads and parses a tolerance file (errors name the path). */
Result<ToleranceSpec> loadToleranceFile(const std::string& path);

/** Index into kAnalysisBandCount for a band name: "125" .. "8000" (also
 *  "125Hz", "1k"), "broadband"/"bb"/"0". Errors name the value. */
Result<int> parseBandName(const std::string& name);
/** "125 Hz" .. "8 kHz", "broadband". */
std::string bandLabel(int band);

/** Third octaves (AnalysisOptions::Bands::kThirdOctave; issue 20): index
 *  j < 21 by its nominal name ("100" .. "10000", "1.25k", "3150 Hz"),
 *  kNumThirdOctaveBands for broadband. Errors name the value. */
Result<int> parseThirdOctaveBandName(const std::string& name);
/** Band `band` of an analysis of `count` results (octaves or third octaves):
 *  "100 Hz" .. "10 kHz" for third octaves, else as bandLabel. */
std::string bandLabel(int band, size_t count);
/** The octave band (index < kNumBands) a third octave lies in: whose
 *  tolerance it takes from a ToleranceSpec (files name octaves). */
int octaveOfThirdOctave(int thirdOctave);

enum class Verdict { kPass, kFail, kSkipped };

/** One metric in one band. */
struct MetricDifference {
  Metric metric = Metric::kEdt;
  int band = 0;                 ///< index into the analysis's bands (octaves or third octaves, broadband last)
  double testValue = kNaN;
  double referenceValue = kNaN;
  double differenceJnd = kNaN;  ///< signed, (test - reference) / JND
  double limitJnd = kNaN;
  Verdict verdict = Verdict::kSkipped;
  std::string note;             ///< why skipped or failed without a number (n/a), else empty
};

struct Comparison {
  std::vector<MetricDifference> rows;  ///< band-major, metrics in kAllMetrics order
  int failures = 0;
  double worstJnd = 0.0;               ///< largest |differenceJnd| over compared rows (inf if n/a failed)
  bool withinTolerance() const { return failures == 0; }
};

struct CompareOptions {
  std::vector<int> bands;  ///< band indices to compare; empty = all kAnalysisBandCount
  ToleranceSpec tolerance;
};

/** Compares per-band results of analyzeIr (both kAnalysisBandCount long, or
 *  both kThirdOctaveAnalysisBandCount: third octaves, each with the
 *  tolerance of its octave, octaveOfThirdOctave; options.bands then index
 *  third octaves).
 *  Rules: a metric n/a in the reference is skipped (noted); n/a in the test
 *  but not in the reference fails. Errors: wrong sizes, bad band index. */
Result<Comparison> compareMetrics(const std::vector<BandMetrics>& test, const std::vector<BandMetrics>& reference,
                                  const CompareOptions& options = {});

/** Comparison of every channel of two IRs (mono or binaural). */
struct AudioComparison {
  std::vector<int> channelIndices;     ///< channel number of each entry of `channels`
  std::vector<Comparison> channels;
  int failures = 0;
  double worstJnd = 0.0;
  bool withinTolerance() const { return failures == 0; }
};

/** Analyses both IRs (analyzeAudio with `analysis`) and compares them channel
 *  by channel, or only channel `onlyChannel` if >= 0. Errors: different
 *  channel counts (without onlyChannel), a missing channel, analysis errors
 *  (messages say "IR" or "reference"). Cost: two analyzeAudio calls. */
Result<AudioComparison> compareAudio(const AudioBuffer& test, const AudioBuffer& reference,
                                     const CompareOptions& options = {}, const AnalysisOptions& analysis = {},
                                     int onlyChannel = -1);

}  // namespace earshot::analysis
