// `earshot analyze IR.wav [--json] [--channel N]`: ISO 3382-1 parameters per
// octave band and broadband, per channel (left, right for a binaural IR).
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>

#include "command.h"
#include "earshot/analysis/compare.h"
#include "earshot/analysis/room_acoustics.h"
#include "earshot/io/wav.h"

namespace earshot::cli {
namespace {

using analysis::BandMetrics;
using analysis::Metric;

struct AnalyzeOptions {
  std::string path;
  bool json = false;
  int channel = -1;
};

std::string channelLabel(size_t index, size_t count) {
  if (count == 1) return "mono";
  if (count == 2) return index == 0 ? "left" : "right";
  return "channel " + std::to_string(index);
}

// A metric as printed: seconds as ms for Ts, +inf, "n/a".
std::string cell(Metric m, double v) {
  if (std::isnan(v)) return "n/a";
  if (std::isinf(v)) return v > 0 ? "+inf" : "-inf";
  char buf[32];
  switch (m) {
    case Metric::kC50:
    case Metric::kC80: std::snprintf(buf, sizeof buf, "%.2f", v); break;
    case Metric::kD50: std::snprintf(buf, sizeof buf, "%.3f", v); break;
    case Metric::kTs: std::snprintf(buf, sizeof buf, "%.1f", v * 1000.0); break;
    default: std::snprintf(buf, sizeof buf, "%.3f", v); break;
  }
  return buf;
}

nlohmann::ordered_json number(double v) { return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr); }

nlohmann::ordered_json bandJson(int band, const BandMetrics& m) {
  nlohmann::ordered_json j;
  j["band"] = analysis::bandLabel(band);
  j["center_hz"] = m.bandCenterHz;
  nlohmann::ordered_json notes = nlohmann::ordered_json::object();
  for (Metric k : analysis::kAllMetrics) {
    const double v = m.value(k);
    j[analysis::metricName(k)] = number(v);
    if (std::isinf(v)) notes[analysis::metricName(k)] = v > 0 ? "+inf: no late energy" : "-inf: no early energy";
    else if (std::isnan(v)) notes[analysis::metricName(k)] = m.reason(k);
  }
  j["onset_s"] = number(m.onsetS);
  j["decay_end_s"] = number(m.decayEndS);
  j["noise_floor_found"] = m.noiseFloorFound;
  j["noise_floor_db"] = number(m.noiseFloorDb);
  j["dynamic_range_db"] = number(m.dynamicRangeDb);
  j["notes"] = notes;
  return j;
}

void printTable(const std::vector<BandMetrics>& bands) {
  std::printf("  %-10s %8s %8s %8s %8s %8s %7s %8s\n", "band", "EDT s", "T20 s", "T30 s", "C50 dB", "C80 dB", "D50",
              "Ts ms");
  for (int b = 0; b < analysis::kAnalysisBandCount; ++b) {
    const BandMetrics& m = bands[size_t(b)];
    std::printf("  %-10s %8s %8s %8s %8s %8s %7s %8s\n", analysis::bandLabel(b).c_str(),
                cell(Metric::kEdt, m.edtS).c_str(), cell(Metric::kT20, m.t20S).c_str(),
                cell(Metric::kT30, m.t30S).c_str(), cell(Metric::kC50, m.c50Db).c_str(),
                cell(Metric::kC80, m.c80Db).c_str(), cell(Metric::kD50, m.d50).c_str(),
                cell(Metric::kTs, m.tsS).c_str());
  }
  // Reasons, one line per distinct reason and band.
  for (int b = 0; b < analysis::kAnalysisBandCount; ++b) {
    const BandMetrics& m = bands[size_t(b)];
    std::string last;
    std::string names;
    for (Metric k : analysis::kAllMetrics) {
      if (m.reason(k).empty()) continue;
      if (m.reason(k) != last && !names.empty()) {
        std::printf("  n/a %s %s: %s\n", analysis::bandLabel(b).c_str(), names.c_str(), last.c_str());
        names.clear();
      }
      names += names.empty() ? analysis::metricName(k) : std::string(",") + analysis::metricName(k);
      last = m.reason(k);
    }
    if (!names.empty()) std::printf("  n/a %s %s: %s\n", analysis::bandLabel(b).c_str(), names.c_str(), last.c_str());
  }
}

void runAnalyze(const AnalyzeOptions& o) {
  auto audio = readAudioFile(o.path);
  if (!check(audio.status())) return;
  if (audio->frameCount() == 0) {
    printError(o.path + ": no samples (empty audio file)");
    return;
  }
  auto result = analysis::analyzeAudio(*audio, {}, o.channel);
  if (!result) {
    printError(o.path + ": " + result.status().message());
    return;
  }
  const size_t count = audio->channelCount();
  if (o.json) {
    nlohmann::ordered_json j;
    j["file"] = o.path;
    j["sample_rate_hz"] = audio->sampleRateHz;
    j["frames"] = audio->frameCount();
    j["duration_s"] = double(audio->frameCount()) / audio->sampleRateHz;
    j["channels"] = nlohmann::ordered_json::array();
    for (size_t i = 0; i < result->channels.size(); ++i) {
      const size_t c = o.channel >= 0 ? size_t(o.channel) : i;
      nlohmann::ordered_json cj;
      cj["channel"] = c;
      cj["label"] = channelLabel(c, count);
      cj["bands"] = nlohmann::ordered_json::array();
      for (int b = 0; b < analysis::kAnalysisBandCount; ++b) cj["bands"].push_back(bandJson(b, result->channels[i][size_t(b)]));
      j["channels"].push_back(cj);
    }
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::printf("%s: %zu channel%s, %.0f Hz, %.3f s (ISO 3382-1; times from the direct sound)\n", o.path.c_str(), count,
              count == 1 ? "" : "s", audio->sampleRateHz, double(audio->frameCount()) / audio->sampleRateHz);
  for (size_t i = 0; i < result->channels.size(); ++i) {
    const size_t c = o.channel >= 0 ? size_t(o.channel) : i;
    const BandMetrics& bb = result->channels[i][analysis::kBroadbandIndex];
    std::printf("channel %zu (%s): direct sound at %.2f ms\n", c, channelLabel(c, count).c_str(), bb.onsetS * 1000.0);
    printTable(result->channels[i]);
  }
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<AnalyzeOptions>();
  CLI::App* cmd = root.add_subcommand(
      "analyze", "ISO 3382-1 parameters (EDT, T20, T30, C50, C80, D50, Ts) per octave band 125 Hz-8 kHz and broadband");
  cmd->add_option("IR", o->path, "impulse response (WAV or any format libsndfile reads)")->required();
  cmd->add_flag("--json", o->json, "write a JSON object to stdout instead of the table");
  cmd->add_option("--channel", o->channel, "analyse only this channel (0 = left, 1 = right)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([o] { runAnalyze(*o); });
});

}  // namespace
}  // namespace earshot::cli
