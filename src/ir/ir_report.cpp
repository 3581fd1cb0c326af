// The JSON report of one computed IR (ir_report.h).
#include "earshot/ir/ir_report.h"

#include <cmath>
#include <cstdio>

#include "earshot/ir/third_octave.h"

#include <algorithm>

#include <nlohmann/json.hpp>

namespace earshot {

std::vector<std::string> irWarnings(const OmniIrResult& r) {
  std::vector<std::string> out;
  if (r.tail.cappedAtSeconds > 0) {
    double slowest = 0;
    for (double t : r.tail.t60Seconds) slowest = std::max(slowest, t);
    char text[256];
    std::snprintf(text, sizeof text,
                  "the reverberation had not decayed by 60 dB at %g s, where the automatic length stops (slowest "
                  "band's T60 %.3g s): the IR ends abruptly; check the materials' absorption, or give a length",
                  r.tail.cappedAtSeconds, slowest);
    out.push_back(text);
  }
  return out;
}

std::vector<std::string> thirdOctaveIrWarnings(const ThirdOctaveIrResult& result) {
  std::vector<std::string> out;
  for (const OmniIrResult& pass : result.passes)
    for (std::string& w : irWarnings(pass))
      if (std::find(out.begin(), out.end(), w) == out.end()) out.push_back(std::move(w));
  return out;
}

std::string irReportJson(const OmniIrResult& r, const OmniIrSettings& settings, bool geometryTraced) {
  nlohmann::json stats;
  stats["settings"] = {{"rays", settings.rays},
                       {"bounces", settings.bounces},
                       {"ism_order", settings.imageSourceOrder},
                       {"bin_ms", settings.binSeconds * 1000.0},
                       {"seed", settings.seed},
                       {"sample_rate_hz", settings.sampleRateHz},
                       {"length_s", settings.lengthSeconds},
                       {"tail_probes", std::min(settings.tailProbes, settings.rays)},
                       {"flutter_cones", settings.flutterCones},
                       {"shared_shadow_roulette", settings.sharedShadowRoulette},
                       {"converge_db", settings.convergenceDb},
                       {"receiver_radius_m", settings.receiverRadiusMeters},
                       {"air", settings.air.enabled ? nlohmann::json{{"temperature_c", settings.air.temperatureC},
                                                                     {"humidity_percent", settings.air.humidityPercent}}
                                                    : nlohmann::json("off")}};
  stats["direct"] = {{"distance_m", r.direct.distanceMeters}, {"delay_s", r.direct.delaySeconds},
                     {"surfaces_crossed", r.direct.surfacesCrossed}, {"audible", r.direct.audible},
                     {"occlusion_tested", r.direct.occlusionTested}};
  stats["early_reflections"] = {{"paths", r.early.size()},
                                {"candidates", r.imageSourceCandidates},
                                {"exhaustive", r.imageSourcesExhaustive}};
  const auto& st = r.traceStats;
  stats["rays_traced"] = geometryTraced ? st.raysTraced : 0;
  stats["rays_escaped"] = st.raysEscaped;
  stats["rays_cut_by_bounce_limit"] = st.raysCut;
  stats["rays_ended_by_roulette"] = st.raysRouletted;
  stats["segments_traced"] = st.segmentsTraced;
  stats["tail_probe_segments"] = st.tailProbeSegments;
  stats["flutter_axes"] = st.flutterAxes;
  stats["flutter_cone_rays"] = st.coneRays;
  stats["rays_requested"] = geometryTraced ? settings.rays : 0;
  if (settings.convergenceDb > 0) stats["estimated_error_db"] = st.estimatedErrorDb;
  stats["shadow_rays"] = st.shadowRays;
  stats["shadow_rays_skipped"] = st.shadowRaysSkipped;
  stats["shadow_rays_rouletted"] = st.shadowRaysRouletted;
  stats["specular_detections_left_to_image_sources"] = st.specularExcluded;
  stats["detections"] = st.detections;
  stats["tail_probe_detections"] = st.probeDetections;
  stats["energy_escaped_fraction"] = st.energyEscaped;
  stats["receiver_radius_m"] = st.receiverRadiusMeters;
  // Per band, the decay of the traced energies: what the IR's bands decay
  // at (TracedDecay). The tail's population_t60_s is the rays in flight's
  // decay rate, which continues the tail past where they were traced.
  const TracedDecay decay = tracedDecay(r);
  stats["decay"] = {{"edt_s", decay.edtSeconds}, {"t20_s", decay.t20Seconds}, {"t30_s", decay.t30Seconds}};
  stats["tail"] = {{"extended", r.tail.extended},
                   {"population_t60_s", r.tail.t60Seconds},
                   {"measured_by_probes", r.tail.probed},
                   {"start_s", r.tail.startSeconds},
                   {"mean_loss_per_reflection", r.tail.meanLoss},
                   {"mean_free_path_m", r.tail.meanFreePathMeters},
                   {"detections_per_energy_in_flight", r.tail.kappa},
                   {"length_capped_at_s", r.tail.cappedAtSeconds}};
  stats["skipped"] = r.skipped;
  stats["time_ms"] = {{"direct", r.timings.directMs},     {"early_reflections", r.timings.imageSourcesMs},
                      {"trace", r.timings.traceMs},       {"tail", r.timings.tailMs},
                      {"synthesis", r.timings.synthesisMs}, {"pipeline", r.timings.totalMs}};
  stats["ir_samples"] = r.ir.frameCount();
  stats["ir_seconds"] = double(r.ir.frameCount()) / settings.sampleRateHz;
  bool silent = true;
  for (const auto& ch : r.ir.channels)
    for (float v : ch) silent = silent && v == 0.0f;
  stats["silent"] = silent;
  // NaN (a decay the energies do not span) is written as null.
  return stats.dump();
}

std::string thirdOctaveReportJson(const ThirdOctaveIrResult& result, const OmniIrSettings& settings,
                                  bool geometryTraced) {
  nlohmann::json report = nlohmann::json::parse(irReportJson(result.passes[1], settings, geometryTraced));
  report["bands"] = "third-octave";
  nlohmann::json t;
  std::vector<double> centers;
  for (int j = 0; j < kNumThirdOctaveBands; ++j) centers.push_back(thirdOctaveCenterHz(j));
  t["bands_hz"] = std::vector<double>(kThirdOctaveNominalHz.begin(), kThirdOctaveNominalHz.end());
  t["centers_hz"] = centers;
  const ThirdOctaveDecay d = tracedDecay(result);
  auto orNull = [](const std::array<double, kNumThirdOctaveBands>& v) {
    nlohmann::json a = nlohmann::json::array();
    for (double x : v) a.push_back(std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr));
    return a;
  };
  t["decay"] = {{"edt_s", orNull(d.edtSeconds)}, {"t20_s", orNull(d.t20Seconds)}, {"t30_s", orNull(d.t30Seconds)}};
  t["passes"] = nlohmann::json::array();
  for (int p = 0; p < kThirdOctavePasses; ++p) {
    OmniIrSettings ps = settings;
    ps.air.bandShiftOctaves = thirdOctavePassShift(p);
    nlohmann::json pass = nlohmann::json::parse(irReportJson(result.passes[size_t(p)], ps, geometryTraced));
    pass["shift_octaves"] = thirdOctavePassShift(p);
    t["passes"].push_back(std::move(pass));
  }
  t["combine_ms"] = result.combineMs;
  // The top level's IR and times are the combined IR's: its length and
  // silence, each stage's time summed over the passes, and the combination.
  for (auto& [stage, ms] : report["time_ms"].items()) {
    double sum = 0;
    for (const auto& pass : t["passes"]) sum += pass["time_ms"][stage].get<double>();
    ms = sum;
  }
  report["time_ms"]["combine"] = result.combineMs;
  report["ir_samples"] = result.ir.frameCount();
  report["ir_seconds"] = double(result.ir.frameCount()) / settings.sampleRateHz;
  bool silent = true;
  for (const auto& ch : result.ir.channels)
    for (float v : ch) silent = silent && v == 0.0f;
  report["silent"] = silent;
  report["third_octave"] = std::move(t);
  return report.dump();
}

}  // namespace earshot
