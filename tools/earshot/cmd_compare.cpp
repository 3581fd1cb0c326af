// `earshot compare IR.wav REF.wav ...`: per-band differences of the ISO 3382-1
// parameters in JND; exit 0 within tolerance, 1 beyond, 2 on error.
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <memory>
#include <sstream>

#include "command.h"
#include "earshot/analysis/compare.h"
#include "earshot/analysis/room_acoustics.h"
#include "earshot/io/wav.h"

namespace earshot::cli {
namespace {

using analysis::Metric;
using analysis::MetricDifference;
using analysis::Verdict;

struct CompareCliOptions {
  std::string irPath, refPath;
  bool json = false;
  std::string bands;
  std::string tolerancePath;
  bool alignDirect = false;
  bool ignoreDirect = false;
  std::string window;
  int channel = -1;
  bool thirdOctaves = false;
};

std::string value(Metric m, double v) {
  if (std::isnan(v)) return "n/a";
  if (std::isinf(v)) return v > 0 ? "+inf" : "-inf";
  char buf[40];
  if (m == Metric::kTs)
    std::snprintf(buf, sizeof buf, "%.1f ms", v * 1000.0);
  else if (m == Metric::kD50)
    std::snprintf(buf, sizeof buf, "%.3f", v);
  else
    std::snprintf(buf, sizeof buf, "%.3f %s", v, analysis::metricUnit(m));
  return buf;
}

std::string jnd(double v) {
  if (std::isnan(v)) return "-";
  if (std::isinf(v)) return v > 0 ? "+inf" : "-inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%+.2f", v);
  return buf;
}

nlohmann::ordered_json number(double v) { return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr); }

// "START,END" in seconds; END may be "inf".
bool parseWindow(const std::string& text, double& start, double& end) {
  const size_t comma = text.find(',');
  if (comma == std::string::npos) return false;
  try {
    size_t used = 0;
    const std::string a = text.substr(0, comma), b = text.substr(comma + 1);
    start = std::stod(a, &used);
    if (used != a.size()) return false;
    end = std::stod(b, &used);
    if (used != b.size()) return false;
  } catch (...) {
    return false;
  }
  return std::isfinite(start) && !std::isnan(end) && start >= 0.0 && end > start;
}

void runCompare(const CompareCliOptions& o) {
  analysis::CompareOptions cmp;
  if (!o.tolerancePath.empty()) {
    auto tol = analysis::loadToleranceFile(o.tolerancePath);
    if (!check(tol.status())) return;
    cmp.tolerance = *tol;
  }
  if (!o.bands.empty()) {
    std::stringstream ss(o.bands);
    std::string item;
    while (std::getline(ss, item, ',')) {
      auto b = o.thirdOctaves ? analysis::parseThirdOctaveBandName(item) : analysis::parseBandName(item);
      if (!b) {
        printError("--bands: " + b.status().message());
        return;
      }
      cmp.bands.push_back(*b);
    }
  }
  analysis::AnalysisOptions ao;
  if (o.thirdOctaves) ao.bands = analysis::AnalysisOptions::Bands::kThirdOctave;
  const size_t bandCount = size_t(o.thirdOctaves ? analysis::kThirdOctaveAnalysisBandCount : analysis::kAnalysisBandCount);
  if (!o.window.empty() && !parseWindow(o.window, ao.windowStartS, ao.windowEndS)) {
    printError("--window: '" + o.window + "' is not START,END in seconds with 0 <= START < END");
    return;
  }
  ao.windowOrigin = o.alignDirect ? analysis::WindowOrigin::kDirectSound : analysis::WindowOrigin::kEmission;
  ao.direct = o.ignoreDirect ? analysis::DirectSound::kExclude : analysis::DirectSound::kInclude;

  auto ir = readAudioFile(o.irPath);
  if (!check(ir.status())) return;
  auto ref = readAudioFile(o.refPath);
  if (!check(ref.status())) return;
  for (const auto* f : {&o.irPath, &o.refPath}) {
    const AudioBuffer& a = f == &o.irPath ? *ir : *ref;
    if (a.frameCount() == 0) {
      printError(*f + ": no samples (empty audio file)");
      return;
    }
    if (o.channel >= int(a.channelCount())) {
      printError(*f + ": --channel " + std::to_string(o.channel) + " does not exist (" +
                 std::to_string(a.channelCount()) + " channels, numbered from 0)");
      return;
    }
  }
  if (o.channel < 0 && ir->channelCount() != ref->channelCount()) {
    printError(o.irPath + " has " + std::to_string(ir->channelCount()) + " channels but " + o.refPath + " has " +
               std::to_string(ref->channelCount()) + "; choose one with --channel");
    return;
  }
  auto cmpResult = analysis::compareAudio(*ir, *ref, cmp, ao, o.channel);
  if (!cmpResult) {
    const std::string& msg = cmpResult.status().message();
    // Name the file rather than "IR"/"reference".
    if (msg.rfind("IR: ", 0) == 0)
      printError(o.irPath + ": " + msg.substr(4));
    else if (msg.rfind("reference: ", 0) == 0)
      printError(o.refPath + ": " + msg.substr(11));
    else
      printError(msg);
    return;
  }
  // Nothing compared is no verdict: a window too short for any metric, or a
  // tolerance that disables them all, must not read as PASS.
  size_t compared = 0;
  for (const auto& c : cmpResult->channels)
    for (const MetricDifference& r : c.rows) compared += r.verdict != Verdict::kSkipped ? 1 : 0;
  if (compared == 0) {
    printError(o.irPath + " vs " + o.refPath + ": no metric could be compared (every one is n/a or disabled" +
               (o.window.empty() ? std::string(")") : "; is --window " + o.window + " too short?)"));
    return;
  }
  const int failures = cmpResult->failures;
  const double worst = cmpResult->worstJnd;
  std::vector<std::pair<size_t, analysis::Comparison>> perChannel;
  for (size_t i = 0; i < cmpResult->channels.size(); ++i)
    perChannel.emplace_back(size_t(cmpResult->channelIndices[i]), std::move(cmpResult->channels[i]));

  if (o.json) {
    nlohmann::ordered_json j;
    j["ir"] = o.irPath;
    j["reference"] = o.refPath;
    j["within_tolerance"] = failures == 0;
    j["failures"] = failures;
    j["worst_jnd"] = number(worst);
    j["channels"] = nlohmann::ordered_json::array();
    for (const auto& [ch, c] : perChannel) {
      nlohmann::ordered_json cj;
      cj["channel"] = ch;
      cj["rows"] = nlohmann::ordered_json::array();
      for (const MetricDifference& r : c.rows) {
        nlohmann::ordered_json rj;
        rj["band"] = analysis::bandLabel(r.band, bandCount);
        rj["metric"] = analysis::metricName(r.metric);
        rj["ir"] = number(r.testValue);
        rj["reference"] = number(r.referenceValue);
        rj["difference_jnd"] = number(r.differenceJnd);
        rj["limit_jnd"] = r.limitJnd;
        rj["verdict"] = r.verdict == Verdict::kPass ? "pass" : r.verdict == Verdict::kFail ? "fail" : "skipped";
        if (!r.note.empty()) rj["note"] = r.note;
        cj["rows"].push_back(rj);
      }
      j["channels"].push_back(cj);
    }
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf("%s vs reference %s (differences in JND: EDT/T20/T30 5 %%, C50/C80 1 dB, D50 0.05, Ts 10 ms)\n",
                o.irPath.c_str(), o.refPath.c_str());
    for (const auto& [ch, c] : perChannel) {
      std::printf("channel %zu\n  %-10s %-6s %12s %12s %8s %6s  %s\n", ch, "band", "metric", "IR", "reference", "JND",
                  "limit", "verdict");
      for (const MetricDifference& r : c.rows) {
        const char* verdict = r.verdict == Verdict::kPass ? "ok" : r.verdict == Verdict::kFail ? "FAIL" : "skipped";
        std::printf("  %-10s %-6s %12s %12s %8s %6.2f  %s%s%s\n", analysis::bandLabel(r.band, bandCount).c_str(),
                    analysis::metricName(r.metric), value(r.metric, r.testValue).c_str(),
                    value(r.metric, r.referenceValue).c_str(), jnd(r.differenceJnd).c_str(), r.limitJnd, verdict,
                    r.note.empty() ? "" : ": ", r.note.c_str());
      }
    }
    for (const auto& [ch, c] : perChannel)
      for (const MetricDifference& r : c.rows)
        if (r.verdict == Verdict::kFail)
          std::printf("FAIL channel %zu %s %s: %s vs %s = %s JND (limit %.2f)%s%s\n", ch, analysis::metricName(r.metric),
                      analysis::bandLabel(r.band, bandCount).c_str(), value(r.metric, r.testValue).c_str(),
                      value(r.metric, r.referenceValue).c_str(), jnd(r.differenceJnd).c_str(), r.limitJnd,
                      r.note.empty() ? "" : "; ", r.note.c_str());
    if (failures == 0)
      std::printf("PASS: all compared metrics within tolerance (worst %.2f JND)\n", worst);
    else
      std::printf("%d metric/band value%s beyond tolerance\n", failures, failures == 1 ? "" : "s");
  }
  if (failures > 0) setExitCode(1);
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<CompareCliOptions>();
  CLI::App* cmd = root.add_subcommand(
      "compare", "Compare the ISO 3382-1 parameters of an IR with a reference in JND; exit 0 within tolerance, 1 beyond, 2 on error");
  cmd->add_option("IR", o->irPath, "impulse response to judge")->required();
  cmd->add_option("REF", o->refPath, "reference impulse response")->required();
  cmd->add_flag("--json", o->json, "write a JSON object to stdout instead of the table");
  cmd->add_option("--bands", o->bands,
                  "bands to compare, e.g. 250,500,1000,broadband (default: all 7 and broadband; with "
                  "--third-octaves nominal third octaves, e.g. 315,400,broadband)");
  cmd->add_flag("--third-octaves", o->thirdOctaves,
                "compare in the 21 third octaves 100 Hz-10 kHz (earshot analyze --bands third-octave); each takes the "
                "tolerance file's limit of the octave it lies in");
  cmd->add_option("--tolerance", o->tolerancePath,
                  "JSON file with limits in JND per metric and band, metrics disabled with false (default 1 JND)");
  cmd->add_flag("--align-direct", o->alignDirect,
                "count --window from each IR's own direct sound (metrics are always timed from it)");
  cmd->add_flag("--ignore-direct", o->ignoreDirect,
                "leave the direct sound (0.5 ms before to 2.5 ms after its onset) out of both IRs");
  cmd->add_option("--window", o->window, "use only START,END seconds of both IRs (e.g. a reference exact up to END)");
  cmd->add_option("--channel", o->channel, "compare only this channel (0 = left, 1 = right)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([o] { runCompare(*o); });
});

}  // namespace
}  // namespace earshot::cli
