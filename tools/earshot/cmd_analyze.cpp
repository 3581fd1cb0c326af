// `earshot analyze IR.wav [--json] [--channel N]`: ISO 3382-1 parameters per
// octave band and broadband, per channel (left, right for a binaural IR), and
// for a two-channel IR the binaural cues (ITD, ILD, IACC; analysis/binaural.h).
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>

#include "command.h"
#include "earshot/analysis/binaural.h"
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
  std::string bands = "octave";
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

nlohmann::ordered_json bandJson(const std::string& label, const BandMetrics& m) {
  nlohmann::ordered_json j;
  j["band"] = label;
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
  for (int b = 0; b < int(bands.size()); ++b) {
    const BandMetrics& m = bands[size_t(b)];
    std::printf("  %-10s %8s %8s %8s %8s %8s %7s %8s\n", analysis::bandLabel(b, bands.size()).c_str(),
                cell(Metric::kEdt, m.edtS).c_str(), cell(Metric::kT20, m.t20S).c_str(),
                cell(Metric::kT30, m.t30S).c_str(), cell(Metric::kC50, m.c50Db).c_str(),
                cell(Metric::kC80, m.c80Db).c_str(), cell(Metric::kD50, m.d50).c_str(),
                cell(Metric::kTs, m.tsS).c_str());
  }
  // Reasons, one line per distinct reason and band.
  for (int b = 0; b < int(bands.size()); ++b) {
    const BandMetrics& m = bands[size_t(b)];
    const std::string label = analysis::bandLabel(b, bands.size());
    std::string last;
    std::string names;
    for (Metric k : analysis::kAllMetrics) {
      if (m.reason(k).empty()) continue;
      if (m.reason(k) != last && !names.empty()) {
        std::printf("  n/a %s %s: %s\n", label.c_str(), names.c_str(), last.c_str());
        names.clear();
      }
      names += names.empty() ? analysis::metricName(k) : std::string(",") + analysis::metricName(k);
      last = m.reason(k);
    }
    if (!names.empty()) std::printf("  n/a %s %s: %s\n", label.c_str(), names.c_str(), last.c_str());
  }
}

// A value as printed: "n/a", "+inf", or fixed-point (with its sign if `sign`).
std::string fixed(double v, int decimals, bool sign) {
  if (std::isnan(v)) return "n/a";
  if (std::isinf(v)) return v > 0 ? "+inf" : "-inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, sign ? "%+.*f" : "%.*f", decimals, v);
  return buf;
}

nlohmann::ordered_json binauralJson(const analysis::BinauralMetrics& m) {
  nlohmann::ordered_json j;
  j["onset_s"] = number(m.onsetS);
  j["direct_window_s"] = {number(m.directStartS), number(m.directEndS)};
  j["itd_s"] = number(m.itdS);
  j["itd_us"] = number(m.itdS * 1e6);
  j["itd_at_search_limit"] = m.itdAtSearchLimit;
  j["itd_peak_correlation"] = number(m.itdPeakCorrelation);
  j["ild_db"] = number(m.ildDb);
  j["iacc_e3"] = number(m.iaccE3);
  j["iacc_l3"] = number(m.iaccL3);
  nlohmann::ordered_json notes = nlohmann::ordered_json::object();
  if (!m.itdReason.empty()) notes["ITD"] = m.itdReason;
  if (std::isinf(m.ildDb)) notes["ILD"] = m.ildDb > 0 ? "+inf: right ear silent" : "-inf: left ear silent";
  j["notes"] = notes;
  j["bands"] = nlohmann::ordered_json::array();
  for (int b = 0; b < analysis::kAnalysisBandCount; ++b) {
    const analysis::IaccBand& band = m.iacc[size_t(b)];
    nlohmann::ordered_json bj;
    bj["band"] = analysis::bandLabel(b);
    bj["center_hz"] = band.bandCenterHz;
    bj["IACC_E"] = number(band.early);
    bj["IACC_E_lag_s"] = number(band.earlyLagS);
    bj["IACC_L"] = number(band.late);
    bj["IACC_L_lag_s"] = number(band.lateLagS);
    nlohmann::ordered_json bandNotes = nlohmann::ordered_json::object();
    if (!band.earlyReason.empty()) bandNotes["IACC_E"] = band.earlyReason;
    if (!band.lateReason.empty()) bandNotes["IACC_L"] = band.lateReason;
    bj["notes"] = bandNotes;
    j["bands"].push_back(bj);
  }
  return j;
}

void printBinaural(const analysis::BinauralMetrics& m) {
  std::printf("binaural (left, right): direct sound at %.2f ms, direct window %.2f .. %.2f ms\n", m.onsetS * 1000.0,
              m.directStartS * 1000.0, m.directEndS * 1000.0);
  std::printf("  ITD %s us (positive: left ear leads)%s\n", fixed(m.itdS * 1e6, 1, true).c_str(),
              m.itdAtSearchLimit ? ", at the +-1 ms search limit" : "");
  if (!m.itdReason.empty()) std::printf("  n/a ITD: %s\n", m.itdReason.c_str());
  std::printf("  ILD %s dB (positive: left ear louder)\n", fixed(m.ildDb, 2, true).c_str());
  std::printf("  %-10s %8s %8s\n", "band", "IACC_E", "IACC_L");
  for (int b = 0; b < analysis::kAnalysisBandCount; ++b) {
    const analysis::IaccBand& band = m.iacc[size_t(b)];
    std::printf("  %-10s %8s %8s\n", analysis::bandLabel(b).c_str(), fixed(band.early, 3, false).c_str(),
                fixed(band.late, 3, false).c_str());
  }
  std::printf("  IACC_E3 %s, IACC_L3 %s (mean of 500 Hz, 1 kHz, 2 kHz)\n", fixed(m.iaccE3, 3, false).c_str(),
              fixed(m.iaccL3, 3, false).c_str());
  for (int b = 0; b < analysis::kAnalysisBandCount; ++b) {
    const analysis::IaccBand& band = m.iacc[size_t(b)];
    const std::string label = analysis::bandLabel(b);
    if (!band.earlyReason.empty() && band.earlyReason == band.lateReason) {
      std::printf("  n/a %s IACC_E,IACC_L: %s\n", label.c_str(), band.earlyReason.c_str());
      continue;
    }
    if (!band.earlyReason.empty()) std::printf("  n/a %s IACC_E: %s\n", label.c_str(), band.earlyReason.c_str());
    if (!band.lateReason.empty()) std::printf("  n/a %s IACC_L: %s\n", label.c_str(), band.lateReason.c_str());
  }
}

void runAnalyze(const AnalyzeOptions& o) {
  auto audio = readAudioFile(o.path);
  if (!check(audio.status())) return;
  if (audio->frameCount() == 0) {
    printError(o.path + ": no samples (empty audio file)");
    return;
  }
  analysis::AnalysisOptions options;
  if (o.bands == "third-octave") options.bands = analysis::AnalysisOptions::Bands::kThirdOctave;
  auto result = analysis::analyzeAudio(*audio, options, o.channel);
  if (!result) {
    printError(o.path + ": " + result.status().message());
    return;
  }
  const size_t count = audio->channelCount();
  // A two-channel IR analysed whole is binaural (left, right).
  Result<analysis::BinauralMetrics> binaural = invalidArgument("not binaural");
  const bool isBinaural = count == 2 && o.channel < 0;
  if (isBinaural) {
    binaural = analysis::analyzeBinaural(*audio);
    if (!binaural) {
      printError(o.path + ": " + binaural.status().message());
      return;
    }
  }
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
      const std::vector<BandMetrics>& bands = result->channels[i];
      for (int b = 0; b < int(bands.size()); ++b) cj["bands"].push_back(bandJson(analysis::bandLabel(b, bands.size()), bands[size_t(b)]));
      j["channels"].push_back(cj);
    }
    if (isBinaural) j["binaural"] = binauralJson(*binaural);
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::printf("%s: %zu channel%s, %.0f Hz, %.3f s (ISO 3382-1; times from the direct sound)\n", o.path.c_str(), count,
              count == 1 ? "" : "s", audio->sampleRateHz, double(audio->frameCount()) / audio->sampleRateHz);
  for (size_t i = 0; i < result->channels.size(); ++i) {
    const size_t c = o.channel >= 0 ? size_t(o.channel) : i;
    const BandMetrics& bb = result->channels[i].back();  // broadband
    std::printf("channel %zu (%s): direct sound at %.2f ms\n", c, channelLabel(c, count).c_str(), bb.onsetS * 1000.0);
    printTable(result->channels[i]);
  }
  if (isBinaural) printBinaural(*binaural);
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<AnalyzeOptions>();
  CLI::App* cmd = root.add_subcommand(
      "analyze",
      "ISO 3382-1 parameters (EDT, T20, T30, C50, C80, D50, Ts) per octave band 125 Hz-8 kHz (or third octave, "
      "--bands) and broadband, per "
      "channel; for a 2-channel (left, right) IR also the binaural cues: ITD and ILD of the direct sound, IACC of "
      "the early (0-80 ms) and late (80 ms-end) parts per band");
  cmd->add_option("IR", o->path, "impulse response (WAV or any format libsndfile reads)")->required();
  cmd->add_flag("--json", o->json, "write a JSON object to stdout instead of the table");
  cmd->add_option("--channel", o->channel, "analyse only this channel (0 = left, 1 = right; no binaural cues)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--bands", o->bands,
                  "bands of the ISO 3382-1 parameters: octave (125 Hz-8 kHz) or third-octave (100 Hz-10 kHz, 21 "
                  "bands; zero-phase 1/3-octave filters, -36 dB at the neighbouring bands' centres, whose longer "
                  "ringing makes decays under 45 / fc (EDT) and 36 / fc (T20, T30) n/a); the binaural cues stay in "
                  "octaves")
      ->check(CLI::IsMember({"octave", "third-octave"}))
      ->capture_default_str();
  cmd->footer(
      "Binaural cues (2-channel IR, no --channel), times from the direct sound:\n"
      "  ITD  arrival(right) - arrival(left), us: positive = left ear leads (source on the left);\n"
      "       peak of the cross-correlation of the ears' direct sound (-1 .. +2.5 ms) low-passed at\n"
      "       1.5 kHz, searched within +-1 ms\n"
      "  ILD  10 log10(E_left / E_right) over the same window, dB: positive = left ear louder\n"
      "  IACC max |normalised interaural cross-correlation| over +-1 ms, per octave band:\n"
      "       IACC_E 0-80 ms, IACC_L 80 ms-end (ISO 3382-1 A.3); IACC_E3/L3 = mean of 500 Hz-2 kHz\n"
      "JSON: {file, sample_rate_hz, frames, duration_s, channels: [{channel, label, bands: [{band,\n"
      "  center_hz, EDT, T20, T30, C50, C80, D50, Ts (s, dB), onset_s, decay_end_s, noise_floor_found,\n"
      "  noise_floor_db, dynamic_range_db, notes}]}], binaural (2 channels only): {onset_s,\n"
      "  direct_window_s: [start, end], itd_s, itd_us, itd_at_search_limit, itd_peak_correlation, ild_db,\n"
      "  iacc_e3, iacc_l3, notes, bands: [{band, center_hz, IACC_E, IACC_E_lag_s, IACC_L, IACC_L_lag_s,\n"
      "  notes}]}}. n/a values are null, with the reason under notes.");
  cmd->callback([o] { runAnalyze(*o); });
});

}  // namespace
}  // namespace earshot::cli
