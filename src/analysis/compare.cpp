// Differences of ISO 3382-1 parameters in just-noticeable differences
// (ISO 3382-1:2009, Annex A, Table A.1) and tolerance files.
#include "earshot/analysis/compare.h"

#include <algorithm>

#include "earshot/io/input_file.h"

#include <nlohmann/json.hpp>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>

namespace earshot::analysis {
namespace {
constexpr double kInfinity() { return std::numeric_limits<double>::infinity(); }
}  // namespace

double jndSize(Metric metric, double referenceValue) {
  switch (metric) {
    case Metric::kEdt:
    case Metric::kT20:
    case Metric::kT30: return kJndDecayRelative * std::abs(referenceValue);
    case Metric::kC50:
    case Metric::kC80: return kJndClarityDb;
    case Metric::kD50: return kJndDefinition;
    case Metric::kTs: return kJndCentreTimeS;
  }
  return kNaN;
}

double differenceInJnd(Metric metric, double testValue, double referenceValue) {
  if (std::isnan(testValue) || std::isnan(referenceValue)) return kNaN;
  if (testValue == referenceValue) return 0.0;  // also +inf == +inf
  const double jnd = jndSize(metric, referenceValue);
  if (!(jnd > 0.0) || std::isinf(jnd)) return testValue > referenceValue ? kInfinity() : -kInfinity();
  return (testValue - referenceValue) / jnd;
}

ToleranceSpec::ToleranceSpec(double jnd) {
  for (auto& row : limitJnd) row.fill(jnd);
  for (auto& row : enabled) row.fill(true);
}

namespace {

// "125 Hz", "1.25 kHz".
std::string frequencyLabel(double f) {
  char buf[32];
  if (f >= 1000.0)
    std::snprintf(buf, sizeof buf, "%g kHz", f / 1000.0);
  else
    std::snprintf(buf, sizeof buf, "%g Hz", f);
  return buf;
}

// A band name as a frequency in Hz ("125", "125Hz", "1.25k"); *broadband
// for "broadband", "bb", "0", "all"; NaN if it is neither.
double bandNameHz(const std::string& name, bool* broadband) {
  std::string s;
  for (char c : name)
    if (c != ' ') s.push_back(char(std::tolower(static_cast<unsigned char>(c))));
  *broadband = s == "broadband" || s == "bb" || s == "0" || s == "all";
  if (*broadband) return std::nan("");
  double scale = 1.0;
  if (s.size() > 2 && s.compare(s.size() - 2, 2, "hz") == 0) s.resize(s.size() - 2);
  if (!s.empty() && s.back() == 'k') {
    scale = 1000.0;
    s.pop_back();
  }
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  return !s.empty() && end == s.c_str() + s.size() ? v * scale : std::nan("");
}

}  // namespace

std::string bandLabel(int band) {
  if (band == kBroadbandIndex) return "broadband";
  if (band < 0 || band >= kNumBands) return "?";
  return frequencyLabel(kBandCentersHz[size_t(band)]);
}

Result<int> parseThirdOctaveBandName(const std::string& name) {
  bool broadband = false;
  const double hz = bandNameHz(name, &broadband);
  if (broadband) return kNumThirdOctaveBands;
  for (int j = 0; j < kNumThirdOctaveBands; ++j)
    if (std::abs(hz - kThirdOctaveNominalHz[size_t(j)]) < 0.5) return j;
  return invalidArgument("unknown third-octave band " + quotedName(name) +
                         " (expected a nominal centre 100, 125, 160 .. 10000 or broadband)");
}

std::string bandLabel(int band, size_t count) {
  if (count != size_t(kThirdOctaveAnalysisBandCount)) return bandLabel(band);
  if (band == kNumThirdOctaveBands) return "broadband";
  if (band < 0 || band > kNumThirdOctaveBands) return "?";
  return frequencyLabel(kThirdOctaveNominalHz[size_t(band)]);
}

int octaveOfThirdOctave(int j) { return std::clamp(int(std::lround(double(j - 1) / 3.0)), 0, kNumBands - 1); }

Result<int> parseBandName(const std::string& name) {
  bool broadband = false;
  const double hz = bandNameHz(name, &broadband);
  if (broadband) return kBroadbandIndex;
  for (int b = 0; b < kNumBands; ++b)
    if (std::abs(hz - kBandCentersHz[size_t(b)]) < 0.5) return b;
  return invalidArgument("unknown band " + quotedName(name) + " (expected 125, 250, 500, 1000, 2000, 4000, 8000 or broadband)");
}

namespace {
using nlohmann::json;

Status applyLimit(const json& v, const std::string& where, double& limit, bool& enabled) {
  if (v.is_boolean()) {
    enabled = v.get<bool>();
    return Status::ok();
  }
  if (v.is_number()) {
    const double d = v.get<double>();
    if (!(d > 0.0) || !std::isfinite(d))
      return invalidArgument(where + " = " + v.dump() + " must be a positive number of JND (or false)");
    limit = d;
    enabled = true;
    return Status::ok();
  }
  return invalidArgument(where + " = " + v.dump() + " must be a number of JND or a boolean");
}
}  // namespace

Result<ToleranceSpec> parseTolerance(const std::string& jsonText, const std::string& sourceName) {
  EARSHOT_RETURN_IF_ERROR(checkJsonDepth(jsonText, sourceName));
  json root;
  try {
    root = json::parse(jsonText);
  } catch (const json::exception& e) {  // a parse error, or a number out of range (1e999)
    return parseError(sourceName + ": not valid JSON (" + jsonErrorWithoutContent(e.what()) + ")");
  }
  if (!root.is_object()) return parseError(sourceName + ": expected a JSON object");
  ToleranceSpec spec(1.0);
  for (auto it = root.begin(); it != root.end(); ++it)
    if (it.key() != "default_jnd" && it.key() != "metrics")
      return invalidArgument(sourceName + ": unknown key " + quotedName(it.key()) + " (expected default_jnd, metrics)");
  if (root.contains("default_jnd")) {
    const json& d = root["default_jnd"];
    if (!d.is_number() || !(d.get<double>() > 0.0) || !std::isfinite(d.get<double>()))
      return invalidArgument(sourceName + ": default_jnd = " + d.dump() + " must be a positive number");
    spec = ToleranceSpec(d.get<double>());
  }
  if (!root.contains("metrics")) return spec;
  const json& metrics = root["metrics"];
  if (!metrics.is_object()) return invalidArgument(sourceName + ": \"metrics\" must be an object");
  for (auto it = metrics.begin(); it != metrics.end(); ++it) {
    auto metric = parseMetric(it.key());
    if (!metric) return invalidArgument(sourceName + ": metrics: " + metric.status().message());
    const size_t mi = size_t(*metric);
    const std::string where = sourceName + ": metrics." + it.key();
    const json& v = it.value();
    if (!v.is_object()) {
      double limit = spec.limitJnd[mi][0];
      bool on = true;
      EARSHOT_RETURN_IF_ERROR(applyLimit(v, where, limit, on));
      for (int b = 0; b < kAnalysisBandCount; ++b) {
        spec.limitJnd[mi][size_t(b)] = limit;
        spec.enabled[mi][size_t(b)] = on;
      }
      continue;
    }
    for (auto f = v.begin(); f != v.end(); ++f)
      if (f.key() != "jnd" && f.key() != "enabled" && f.key() != "bands")
        return invalidArgument(where + ": unknown key " + quotedName(f.key()) + " (expected jnd, enabled, bands)");
    if (v.contains("jnd")) {
      double limit = 0.0;
      bool on = true;
      EARSHOT_RETURN_IF_ERROR(applyLimit(v["jnd"], where + ".jnd", limit, on));
      if (!v["jnd"].is_number()) return invalidArgument(where + ".jnd must be a number");
      spec.limitJnd[mi].fill(limit);
    }
    if (v.contains("enabled")) {
      if (!v["enabled"].is_boolean()) return invalidArgument(where + ".enabled must be true or false");
      spec.enabled[mi].fill(v["enabled"].get<bool>());
    }
    if (v.contains("bands")) {
      const json& bands = v["bands"];
      if (!bands.is_object()) return invalidArgument(where + ".bands must be an object");
      for (auto b = bands.begin(); b != bands.end(); ++b) {
        auto band = parseBandName(b.key());
        if (!band) return invalidArgument(where + ".bands: " + band.status().message());
        bool on = spec.enabled[mi][size_t(*band)];
        EARSHOT_RETURN_IF_ERROR(applyLimit(b.value(), where + ".bands." + b.key(), spec.limitJnd[mi][size_t(*band)], on));
        spec.enabled[mi][size_t(*band)] = on;
      }
    }
  }
  return spec;
}

Result<ToleranceSpec> loadToleranceFile(const std::string& path) {
  auto text = readInputFile(path, "tolerance file", kMaxJsonFileBytes);
  if (!text) return text.status();
  return parseTolerance(*text, path);
}

Result<Comparison> compareMetrics(const std::vector<BandMetrics>& test, const std::vector<BandMetrics>& reference,
                                  const CompareOptions& options) {
  const int count = int(test.size());
  if (test.size() != reference.size() || (count != kAnalysisBandCount && count != kThirdOctaveAnalysisBandCount))
    return invalidArgument("compareMetrics: expected " + std::to_string(kAnalysisBandCount) + " bands (or " +
                           std::to_string(kThirdOctaveAnalysisBandCount) + ", third octaves) in both, got " +
                           std::to_string(test.size()) + " and " + std::to_string(reference.size()));
  const bool thirds = count == kThirdOctaveAnalysisBandCount;
  // The tolerance's band: an octave's own; a third octave's octave's.
  auto toleranceBand = [&](int b) { return !thirds ? b : b == count - 1 ? kBroadbandIndex : octaveOfThirdOctave(b); };
  std::vector<int> bands = options.bands;
  if (bands.empty())
    for (int b = 0; b < count; ++b) bands.push_back(b);
  Comparison out;
  for (int b : bands) {
    if (b < 0 || b >= count) return invalidArgument("compareMetrics: band index " + std::to_string(b) + " is out of range");
    const int tb = toleranceBand(b);
    for (Metric m : kAllMetrics) {
      MetricDifference row;
      row.metric = m;
      row.band = b;
      row.testValue = test[size_t(b)].value(m);
      row.referenceValue = reference[size_t(b)].value(m);
      row.limitJnd = options.tolerance.limit(m, tb);
      if (!options.tolerance.isEnabled(m, tb)) {
        row.note = "disabled by tolerance";
      } else if (std::isnan(row.referenceValue)) {
        row.note = "reference n/a: " + reference[size_t(b)].reason(m);
      } else if (std::isnan(row.testValue)) {
        row.verdict = Verdict::kFail;
        row.differenceJnd = kInfinity();
        row.note = "n/a in IR: " + test[size_t(b)].reason(m);
      } else if (std::isinf(row.testValue) || std::isinf(row.referenceValue)) {
        // C50/C80 of an IR with no energy after 50/80 ms (in the window) is
        // +inf: equal infinities are no difference in JND, and one infinity
        // is a difference no JND measures.
        const bool same = row.testValue == row.referenceValue;
        row.verdict = same ? Verdict::kSkipped : Verdict::kFail;
        row.differenceJnd = same ? 0.0 : kInfinity();
        row.note = same ? "both infinite: no energy after the early window in either"
                        : "infinite in " + std::string(std::isinf(row.testValue) ? "the IR" : "the reference") +
                              ": no energy after the early window";
      } else {
        row.differenceJnd = differenceInJnd(m, row.testValue, row.referenceValue);
        row.verdict = std::abs(row.differenceJnd) <= row.limitJnd ? Verdict::kPass : Verdict::kFail;
      }
      if (row.verdict == Verdict::kFail) ++out.failures;
      if (row.verdict != Verdict::kSkipped) out.worstJnd = std::max(out.worstJnd, std::abs(row.differenceJnd));
      out.rows.push_back(std::move(row));
    }
  }
  return out;
}

Result<AudioComparison> compareAudio(const AudioBuffer& test, const AudioBuffer& reference,
                                     const CompareOptions& options, const AnalysisOptions& analysis,
                                     int onlyChannel) {
  if (onlyChannel < 0 && test.channelCount() != reference.channelCount())
    return invalidArgument("IR has " + std::to_string(test.channelCount()) + " channels but the reference has " +
                           std::to_string(reference.channelCount()) + "; compare one channel");
  auto a = analyzeAudio(test, analysis, onlyChannel);
  if (!a) return Status(a.status().code(), "IR: " + a.status().message());
  auto b = analyzeAudio(reference, analysis, onlyChannel);
  if (!b) return Status(b.status().code(), "reference: " + b.status().message());
  AudioComparison out;
  for (size_t i = 0; i < a->channels.size(); ++i) {
    auto c = compareMetrics(a->channels[i], b->channels[i], options);
    if (!c) return c.status();
    out.failures += c->failures;
    out.worstJnd = std::max(out.worstJnd, c->worstJnd);
    out.channelIndices.push_back(onlyChannel >= 0 ? onlyChannel : int(i));
    out.channels.push_back(std::move(*c));
  }
  return out;
}

}  // namespace earshot::analysis
