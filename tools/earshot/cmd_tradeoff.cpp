// `earshot tradeoff`: accuracy against cost of the IR pipeline, over a grid of
// (rays, bounces) or, with --presets, per named quality preset (all of its
// settings: rays, bounces, image-source order, histogram bin, tail probes).
// Each point runs computeOmniIr (the one implementation behind `earshot ir`)
// --repeats times with different seeds, takes the median wall time, and
// measures the error of each run against a reference IR as ISO 3382-1
// just-noticeable differences (analysis/compare.h): per metric, the mean |JND|
// over the 250 Hz .. 4 kHz octave bands, averaged over the repeats. max_jnd is
// the largest of those seven per-metric means (the worst metric).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>

#include <sys/wait.h>

#include <nlohmann/json.hpp>

#include "command.h"
#include "earshot/io/input_file.h"
#include "earshot/analysis/compare.h"
#include "earshot/analysis/room_acoustics.h"
#include "earshot/core/thread_pool.h"
#include "earshot/io/atomic_file.h"
#include "earshot/io/wav.h"
#include "earshot/analysis/binaural.h"
#include "earshot/analysis/octave_filter.h"
#include "earshot/ir/ambisonic_decoder.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/materials/material.h"
#include "earshot/scene/gltf_loader.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot::cli {
namespace {

namespace an = earshot::analysis;

struct TradeoffOptions {
  std::string geometry;
  std::string materials;
  std::string materialMap;
  std::array<double, 3> source{}, listener{};
  std::string rays = "1000,4000,16000,64000";
  std::string bounces = "6,12,24";
  std::string presets;  ///< non-empty: evaluate these quality presets instead of the grid
  std::string reference;
  int repeats = 3;
  unsigned threads = 0;
  std::string air = "20,50";
  std::string output;
  std::string plot;
  std::string plotScript = "tools/plot_tradeoff.py";
  std::string python = "python3";
  // Issue 15: ambisonic reflections against exact binaural ones.
  std::string ambisonicOrders;
  std::array<double, 3> forward{0.0, 0.0, -1.0}, up{0.0, 1.0, 0.0};
  std::string hrtf;
  std::string quality = "balanced";
  // Issue 16: how the sweep's points are traced (the reference: per source).
  std::string trace = "per-source";
};

/** Octave bands whose errors are averaged: 250 Hz .. 4 kHz. */
constexpr double kLowestBandHz = 250.0, kHighestBandHz = 4000.0;
/** Seed of the default reference run, apart from the sweep's seeds 1..repeats. */
constexpr uint64_t kReferenceSeed = 1000003;

Result<std::vector<uint32_t>> parseList(const std::string& option, const std::string& text, uint32_t minValue) {
  std::vector<uint32_t> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    size_t used = 0;
    unsigned long long v = 0;
    try {
      v = std::stoull(item, &used);
    } catch (...) {
      used = 0;
    }
    if (used == 0 || used != item.size() || item[0] == '-' || v < minValue || v > 100000000ull)
      return invalidArgument(option + ": '" + item + "' in '" + text + "' is not an integer in [" +
                             std::to_string(minValue) + ", 100000000]");
    out.push_back(uint32_t(v));
  }
  if (out.empty()) return invalidArgument(option + ": '" + text + "' is not a comma-separated list of integers");
  return out;
}

/** --presets: comma-separated names of quality presets, or "all" for every
 *  preset in qualityPresets() order. An unknown or empty name is an error
 *  naming it and the valid ones. */
Result<std::vector<QualityPreset>> parsePresets(const std::string& text) {
  std::vector<QualityPreset> out;
  if (text == "all") return qualityPresets();
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    auto p = qualityPreset(item);
    if (!p.isOk()) return invalidArgument("--presets: '" + text + "': " + p.status().message() + " (or 'all')");
    out.push_back(*p);
  }
  if (out.empty() || text.back() == ',')
    return invalidArgument("--presets: '" + text + "' is not a comma-separated list of quality presets");
  return out;
}

/** Runs a shell command quietly; returns its exit status (-1 if it did not run). */
int runQuiet(const std::string& command) {
  int status = std::system((command + " >/dev/null 2>&1").c_str());
  if (status == -1) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string shellQuote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += (c == '\'') ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string formatNumber(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

struct PointResult {
  std::string preset;  ///< empty in grid mode
  uint32_t rays = 0, bounces = 0;
  double secondsMedian = 0;
  std::array<double, an::kMetricCount> jnd{};  ///< mean |JND| over bands, averaged over repeats
  double maxJnd = 0;
};

/** Mean |JND| per metric over the 250 Hz .. 4 kHz bands. A metric n/a in the
 *  reference is skipped in that band; n/a in the test (with a reference value)
 *  is skipped too and counted in `naCount`. No band compared gives NaN. */
Result<std::array<double, an::kMetricCount>> errorPerMetric(const std::vector<an::BandMetrics>& test,
                                                             const std::vector<an::BandMetrics>& reference,
                                                             int& naCount) {
  an::CompareOptions co;
  for (int b = 0; b < kNumBands; ++b)
    if (kBandCentersHz[size_t(b)] >= kLowestBandHz && kBandCentersHz[size_t(b)] <= kHighestBandHz)
      co.bands.push_back(b);
  auto cmp = an::compareMetrics(test, reference, co);
  if (!cmp.isOk()) return cmp.status();
  std::array<double, an::kMetricCount> sum{}, count{};
  for (const auto& row : cmp->rows) {
    if (std::isnan(row.referenceValue)) continue;
    // compareMetrics scores "n/a in the test only" as +inf JND; one such band
    // would make the mean inf and the point unplottable, so it is left out
    // and counted (the command warns with the count).
    if (std::isnan(row.testValue) || std::isnan(row.differenceJnd)) {
      ++naCount;
      continue;
    }
    sum[size_t(row.metric)] += std::fabs(row.differenceJnd);
    count[size_t(row.metric)] += 1;
  }
  std::array<double, an::kMetricCount> mean{};
  for (int m = 0; m < an::kMetricCount; ++m) mean[size_t(m)] = count[size_t(m)] > 0 ? sum[size_t(m)] / count[size_t(m)] : an::kNaN;
  return mean;
}

/** Runs the pipeline with `settings` `repeats` times (seeds 1..repeats) and
 *  scores each IR against `reference` (metrics at `rateHz`): the median wall
 *  time of the pipeline call and the per-metric error averaged over the
 *  repeats. `label` names the point in errors; n/a values are counted in
 *  `naCount` (errorPerMetric). */
Result<PointResult> evaluatePoint(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& source,
                                  const Vec3d& listener, const OmniIrSettings& settings, int repeats,
                                  ThreadPool& pool, const std::vector<an::BandMetrics>& reference, double rateHz,
                                  const std::string& label, int& naCount, TraceMode trace) {
  PointResult p;
  std::vector<double> seconds;
  std::array<double, an::kMetricCount> sum{};
  for (int i = 0; i < repeats; ++i) {
    OmniIrSettings s = settings;
    s.seed = uint64_t(i + 1);
    const auto t0 = std::chrono::steady_clock::now();
    auto r = computeIrs(tracer, materials, listener, {IrRequest{source, s.directivity, s.includeDirect, {}}}, s, trace, pool);
    seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    if (!r.isOk()) return Status(r.status().code(), label + ": " + r.status().message());
    auto m = an::analyzeIr(r->front().ir.channels[0], rateHz);
    if (!m.isOk()) return Status(m.status().code(), "IR at " + label + ": " + m.status().message());
    auto e = errorPerMetric(*m, reference, naCount);
    if (!e.isOk()) return e.status();
    for (int k = 0; k < an::kMetricCount; ++k) sum[size_t(k)] += (*e)[size_t(k)];
  }
  p.secondsMedian = median(seconds);
  for (int k = 0; k < an::kMetricCount; ++k) {
    p.jnd[size_t(k)] = sum[size_t(k)] / repeats;
    if (!std::isnan(p.jnd[size_t(k)])) p.maxJnd = std::max(p.maxJnd, p.jnd[size_t(k)]);
  }
  return p;
}

/** --ambisonic-orders: what the runtime's ambisonic reflections (world-frame
 *  IR of each order, rotated to the head and decoded by the HRTF set's
 *  decoder) cost in accuracy against the exact binaural reflections (every
 *  arrival through its own HRTF) of the same simulation (same seed: the same
 *  rays, image sources and noise), both with the exact direct sound as the
 *  runtime renders it. Per order: the first reflection's ILD per octave
 *  (the ear energies of each octave band within -1 .. +3 ms of the first
 *  image source's arrival), the late IACC per octave, EDT and C80 per ear in
 *  JND (mean |JND| over 250 Hz .. 4 kHz), and the bus's channels (the
 *  audio thread's multiply-adds per source grow with them). */
int runAmbisonic(const TradeoffOptions& o) {
  std::vector<int> orders;
  {
    auto list = parseList("--ambisonic-orders", o.ambisonicOrders, 1);
    if (!check(list.status())) return 2;
    for (uint32_t v : *list) {
      if (v > uint32_t(kMaxAmbisonicOrder)) {
        printError("--ambisonic-orders: " + std::to_string(v) + " is outside [1, 3]");
        return 2;
      }
      orders.push_back(int(v));
    }
  }
  ListenerOrientation orientation{{o.forward[0], o.forward[1], o.forward[2]}, {o.up[0], o.up[1], o.up[2]}};
  if (!check(validate(orientation))) return 2;
  auto air = parseCliAir(o.air);
  if (!check(air.status())) return 2;
  if (!o.output.empty() && !check(checkOutputPath(o.output))) return 2;
  auto scene = loadSceneInputs(o.geometry, o.materials, o.materialMap);
  if (!check(scene.status())) return 2;
  OmniIrSettings s;
  auto preset = qualityPreset(o.quality);
  if (!check(preset.status())) return 2;
  apply(*preset, s);
  s.air = *air;
  s.seed = kReferenceSeed;
  auto model = loadBinauralModel(o.hrtf, s.sampleRateHz);
  if (!check(model.status())) return 2;
  ThreadPool pool(o.threads);
  const Vec3d source{o.source[0], o.source[1], o.source[2]}, listener{o.listener[0], o.listener[1], o.listener[2]};
  const double fs = s.sampleRateHz;

  // The exact binaural IR, with and without the direct sound (the runtime's
  // direct sound is the difference).
  BinauralReceiver binaural{*model, orientation};
  auto full = computeIr(*scene->tracer, scene->materials, source, listener, s, pool, &binaural);
  if (!check(full.status())) return 2;
  OmniIrSettings sr = s;
  sr.includeDirect = false;
  auto exactRefl = computeIr(*scene->tracer, scene->materials, source, listener, sr, pool, &binaural);
  if (!check(exactRefl.status())) return 2;
  if (full->early.empty()) {
    printError("no image source reaches the listener: no first reflection to compare");
    return 2;
  }
  double first = full->early.front().delaySeconds;
  for (const SpecularPath& p : full->early) first = std::min(first, p.delaySeconds);
  const size_t n = exactRefl->ir.frameCount();

  const double bands[] = {250, 500, 1000, 2000, 4000};
  // Ear energies per octave in the first reflection's window.
  auto firstReflectionIld = [&](const AudioBuffer& ir) {
    std::array<double, 5> ild{};
    const size_t a = size_t(std::max(0.0, (first - 0.001) * fs)), b = std::min(ir.frameCount(), size_t((first + 0.003) * fs));
    for (size_t k = 0; k < 5; ++k) {
      double e[2] = {0, 0};
      for (int ear = 0; ear < 2; ++ear) {
        size_t guard = 0;
        const std::vector<double> f =
            an::octaveBandFilter(ir.channels[size_t(ear)].data(), ir.frameCount(), fs, bands[k], &guard);
        for (size_t i = a; i < b && i + guard < f.size(); ++i) e[ear] += f[i + guard] * f[i + guard];
      }
      ild[k] = 10.0 * std::log10(e[0] / e[1]);
    }
    return ild;
  };
  auto withDirect = [&](const AudioBuffer& refl) {
    AudioBuffer out = full->ir;
    for (int ear = 0; ear < 2; ++ear)
      for (size_t i = 0; i < out.frameCount(); ++i)
        out.channels[size_t(ear)][i] += (i < refl.frameCount() ? refl.channels[size_t(ear)][i] : 0.0f) -
                                        (i < n ? exactRefl->ir.channels[size_t(ear)][i] : 0.0f);
    return out;
  };
  struct Row {
    int order;
    std::array<double, 5> ildError;
    std::array<double, 3> iaccLate, iaccError;  // 500, 1000, 2000 Hz
    double edtJnd[2], c80Jnd[2];
  };
  auto evaluate = [&](const AudioBuffer& refl, int order, const std::array<double, 5>& exactIld,
                      const an::BinauralMetrics& exactCues, const an::IrAnalysis& exactParams) -> Result<Row> {
    Row r{};
    r.order = order;
    const std::array<double, 5> ild = firstReflectionIld(refl);
    for (size_t k = 0; k < 5; ++k) r.ildError[k] = ild[k] - exactIld[k];
    const AudioBuffer heard = withDirect(refl);
    auto cues = an::analyzeBinaural(heard);
    if (!cues.isOk()) return cues.status();
    auto params = an::analyzeAudio(heard);
    if (!params.isOk()) return params.status();
    for (size_t k = 0; k < 3; ++k) {
      const int band = int(k) + 2;  // 500 Hz, 1 kHz, 2 kHz
      r.iaccLate[k] = cues->iacc[size_t(band)].late;
      r.iaccError[k] = cues->iacc[size_t(band)].late - exactCues.iacc[size_t(band)].late;
    }
    for (int ear = 0; ear < 2; ++ear) {
      double edt = 0, c80 = 0;
      int count = 0;
      for (int band = 0; band < kNumBands; ++band) {
        if (kBandCentersHz[size_t(band)] < kLowestBandHz || kBandCentersHz[size_t(band)] > kHighestBandHz) continue;
        const an::BandMetrics& t = params->channels[size_t(ear)][size_t(band)];
        const an::BandMetrics& ref = exactParams.channels[size_t(ear)][size_t(band)];
        const double de = an::differenceInJnd(an::Metric::kEdt, t.edtS, ref.edtS),
                     dc = an::differenceInJnd(an::Metric::kC80, t.c80Db, ref.c80Db);
        if (!std::isfinite(de) || !std::isfinite(dc)) continue;  // n/a in either (said by the count)
        edt += std::fabs(de);
        c80 += std::fabs(dc);
        ++count;
      }
      r.edtJnd[ear] = count > 0 ? edt / count : an::kNaN;
      r.c80Jnd[ear] = count > 0 ? c80 / count : an::kNaN;
    }
    return r;
  };
  const std::array<double, 5> exactIld = firstReflectionIld(exactRefl->ir);
  auto exactCues = an::analyzeBinaural(full->ir);
  if (!check(exactCues.status())) return 2;
  auto exactParams = an::analyzeAudio(full->ir);
  if (!check(exactParams.status())) return 2;

  std::vector<Row> rows;
  {
    // The floor: the exact binaural reflections of another seed (other rays,
    // other noise) differ from the reference by this much already.
    OmniIrSettings other = sr;
    other.seed = kReferenceSeed + 1;
    auto ir = computeIr(*scene->tracer, scene->materials, source, listener, other, pool, &binaural);
    if (!check(ir.status())) return 2;
    AudioBuffer refl(2, n, fs);
    for (int ear = 0; ear < 2; ++ear)
      for (size_t i = 0; i < n && i < ir->ir.frameCount(); ++i) refl.channels[size_t(ear)][i] = ir->ir.channels[size_t(ear)][i];
    auto row = evaluate(refl, 0, exactIld, *exactCues, *exactParams);
    if (!check(row.status())) return 2;
    rows.push_back(*row);
  }
  for (int order : orders) {
    AmbisonicReceiver amb;
    amb.order = order;
    amb.frame.worldToFrame = worldToAmbisonicFrame(orientation.forward, orientation.up);
    auto ir = computeIr(*scene->tracer, scene->materials, source, listener, sr, pool, nullptr, &amb);
    if (!check(ir.status())) return 2;
    AmbisonicDecoderSettings ds;
    ds.order = order;
    auto decoder = AmbisonicDecoder::create(**model, ds);
    if (!check(decoder.status())) return 2;
    auto ears = (*decoder)->decode(ir->ir);
    if (!check(ears.status())) return 2;
    // Undo the decoder's bulk delay, keep the exact IR's length.
    AudioBuffer refl(2, n, fs);
    for (int ear = 0; ear < 2; ++ear)
      for (size_t i = 0; i < n; ++i) refl.channels[size_t(ear)][i] = ears->channels[size_t(ear)][i + (*decoder)->delayFrames()];
    auto row = evaluate(refl, order, exactIld, *exactCues, *exactParams);
    if (!check(row.status())) return 2;
    rows.push_back(*row);
  }
  std::string csv =
      "order,channels,ild_err_250_db,ild_err_500_db,ild_err_1000_db,ild_err_2000_db,ild_err_4000_db,"
      "iacc_late_err_500,iacc_late_err_1000,iacc_late_err_2000,edt_jnd_left,edt_jnd_right,c80_jnd_left,"
      "c80_jnd_right\n";
  std::printf("exact binaural: first reflection at %.2f ms; its ILD per octave 250..4000 Hz:", first * 1000);
  for (double v : exactIld) std::printf(" %.1f", v);
  std::printf(" dB; late IACC 500/1k/2k: %.2f %.2f %.2f\n", exactCues->iacc[2].late, exactCues->iacc[3].late,
              exactCues->iacc[4].late);
  for (const Row& r : rows) {
    csv += (r.order == 0 ? std::string("binaural_other_seed,2") : std::to_string(r.order) + "," + std::to_string(ambisonicChannels(r.order)));
    for (double v : r.ildError) csv += "," + formatNumber(v);
    for (double v : r.iaccError) csv += "," + formatNumber(v);
    csv += "," + formatNumber(r.edtJnd[0]) + "," + formatNumber(r.edtJnd[1]) + "," + formatNumber(r.c80Jnd[0]) + "," +
           formatNumber(r.c80Jnd[1]) + "\n";
    if (r.order == 0)
      std::printf("binaural, another seed (the floor): first-reflection ILD error");
    else
      std::printf("order %d (%d channels): first-reflection ILD error", r.order, ambisonicChannels(r.order));
    for (double v : r.ildError) std::printf(" %+.1f", v);
    std::printf(" dB; late IACC error %+.2f %+.2f %+.2f; EDT %.2f/%.2f JND, C80 %.2f/%.2f JND (left/right)\n",
                r.iaccError[0], r.iaccError[1], r.iaccError[2], r.edtJnd[0], r.edtJnd[1], r.c80Jnd[0], r.c80Jnd[1]);
  }
  if (!o.output.empty() && !check(writeTextFileAtomically(o.output, csv))) return 2;
  return 0;
}

int run(const TradeoffOptions& o) {
  if (!o.ambisonicOrders.empty()) {
    if (!o.presets.empty() || !o.reference.empty() || !o.plot.empty()) {
      printError("--ambisonic-orders: compares against its own exact binaural rendering; --presets, --reference "
                 "and --plot do not apply");
      return 2;
    }
    return runAmbisonic(o);
  }
  // Everything that can be checked before the (long) sweep is checked first,
  // so an error never leaves a CSV or plot behind.
  auto rays = parseList("--rays", o.rays, 1);
  if (!check(rays.status())) return 2;
  auto bounces = parseList("--bounces", o.bounces, 0);
  if (!check(bounces.status())) return 2;
  std::vector<QualityPreset> presets;
  if (!o.presets.empty()) {
    auto parsed = parsePresets(o.presets);
    if (!check(parsed.status())) return 2;
    presets = std::move(*parsed);
  }
  auto air = parseCliAir(o.air);
  if (!check(air.status())) return 2;
  std::string python;
  if (!o.plot.empty()) {
    if (!std::filesystem::is_regular_file(o.plotScript)) {
      printError("--plot-script: " + o.plotScript + ": no such file (run from the source tree or give --plot-script)");
      return 2;
    }
    // "python3" first; a python3 earlier in PATH (pyenv, venv) may lack
    // matplotlib while Debian's /usr/bin/python3 has python3-matplotlib.
    std::vector<std::string> candidates{o.python};
    if (o.python == "python3") candidates.push_back("/usr/bin/python3");
    bool anyPython = false;
    for (const auto& py : candidates) {
      if (runQuiet(shellQuote(py) + " -c 'import sys'") != 0) continue;
      anyPython = true;
      if (runQuiet(shellQuote(py) + " -c 'import matplotlib'") == 0) {
        python = py;
        break;
      }
    }
    if (!anyPython) {
      printError("--plot: " + o.python + " not found (install python3 and python3-matplotlib, or leave out --plot)");
      return 2;
    }
    if (python.empty()) {
      printError("--plot: " + o.python +
                 " cannot import matplotlib (install python3-matplotlib, give --python, or leave out --plot)");
      return 2;
    }
  }

  auto scene = loadSceneInputs(o.geometry, o.materials, o.materialMap);
  if (!check(scene.status())) return 2;
  const MaterialTable& materials = scene->materials;
  auto& tracer = scene->tracer;

  ThreadPool pool(o.threads);
  const Vec3d source{o.source[0], o.source[1], o.source[2]};
  const Vec3d listener{o.listener[0], o.listener[1], o.listener[2]};

  OmniIrSettings base;  // the balanced preset's defaults; rays and bounces are swept, or a preset applied
  base.air = *air;

  // Reference IR: a file, or the 'reference' quality preset.
  std::vector<float> referenceIr;
  double rateHz = base.sampleRateHz;
  // Refuse an output that would replace an input (or a FIFO, a device)
  // before the reference run and the sweep (the writes check again).
  if (!o.reference.empty()) rememberInputFile(o.reference);
  if (!o.plot.empty()) rememberInputFile(o.plotScript);
  if (!check(checkOutputPaths({o.output, o.plot}, {"-o", "--plot"}))) return 2;
  if (!o.reference.empty()) {
    auto ref = readAudioFile(o.reference);
    if (!ref.isOk()) {
      printError("--reference: " + ref.status().message());
      return 2;
    }
    if (ref->channels.size() != 1) {
      printError("--reference: " + o.reference + " has " + std::to_string(ref->channels.size()) +
                 " channels, expected 1 (an omni IR)");
      return 2;
    }
    rateHz = ref->sampleRateHz;
    referenceIr = std::move(ref->channels[0]);
  } else {
    OmniIrSettings s = base;
    auto preset = qualityPreset("reference");
    if (!check(preset.status())) return 2;
    apply(*preset, s);
    s.seed = kReferenceSeed;
    std::cerr << "earshot: tradeoff: reference run (" << s.rays << " rays x " << s.bounces << " bounces)...\n";
    auto r = computeOmniIr(*tracer, materials, source, listener, s, pool);
    if (!check(r.status())) return 2;
    referenceIr = std::move(r->ir.channels[0]);
  }
  base.sampleRateHz = rateHz;
  auto refMetrics = an::analyzeIr(referenceIr, rateHz);
  if (!refMetrics.isOk()) {
    printError("reference: " + refMetrics.status().message());
    return 2;
  }

  std::vector<PointResult> points;
  int naCount = 0;
  auto evaluate = [&](PointResult p, const OmniIrSettings& settings, const std::string& label) -> bool {
    const int naBefore = naCount;
    auto e = evaluatePoint(*tracer, materials, source, listener, settings, o.repeats, pool, *refMetrics, rateHz,
                           label, naCount, *traceModeFromString(o.trace));
    if (!check(e.status())) return false;
    p.secondsMedian = e->secondsMedian;
    p.jnd = e->jnd;
    p.maxJnd = e->maxJnd;
    std::cerr << "earshot: tradeoff: " << label << ": " << formatNumber(p.secondsMedian) << " s, max "
              << formatNumber(p.maxJnd) << " JND";
    if (naCount > naBefore) std::cerr << " (" << naCount - naBefore << " metric/band values n/a, left out)";
    std::cerr << "\n";
    points.push_back(p);
    return true;
  };
  if (!presets.empty()) {
    for (const QualityPreset& preset : presets) {
      OmniIrSettings s = base;
      apply(preset, s);
      PointResult p;
      p.preset = preset.name;
      p.rays = s.rays;
      p.bounces = s.bounces;
      if (!evaluate(p, s, "preset " + preset.name)) return 2;
    }
  } else {
    for (uint32_t b : *bounces) {
      for (uint32_t n : *rays) {
        OmniIrSettings s = base;
        s.rays = n;
        s.bounces = b;
        PointResult p;
        p.rays = n;
        p.bounces = b;
        if (!evaluate(p, s, std::to_string(n) + " rays x " + std::to_string(b) + " bounces")) return 2;
      }
    }
  }
  if (naCount > 0)
    std::cerr << "earshot: warning: " << naCount
              << " metric/band value(s) in all were n/a in a sweep IR but not in the reference (e.g. decay range too "
                 "short for T30); left out of the means\n";

  std::string csv = presets.empty() ? "" : "preset,";
  csv += "rays,bounces,seconds_median,edt_jnd,t20_jnd,t30_jnd,c50_jnd,c80_jnd,d50_jnd,ts_jnd,max_jnd\n";
  for (const auto& p : points) {
    if (!presets.empty()) csv += p.preset + ",";
    csv += std::to_string(p.rays) + "," + std::to_string(p.bounces) + "," + formatNumber(p.secondsMedian);
    for (double v : p.jnd) csv += "," + formatNumber(v);
    csv += "," + formatNumber(p.maxJnd) + "\n";
  }
  if (!check(writeTextFileAtomically(o.output, csv))) return 2;

  if (!o.plot.empty()) {
    const std::string cmd = shellQuote(python) + " " + shellQuote(o.plotScript) + " " + shellQuote(o.output) + " " + shellQuote(o.plot);
    int status = std::system(cmd.c_str());
    if (status != 0) {
      printError("--plot: '" + cmd + "' failed (the CSV " + o.output + " was written)");
      return 2;
    }
  }
  return 0;
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<TradeoffOptions>();
  CLI::App* cmd = root.add_subcommand(
      "tradeoff",
      "Error (JND vs a reference IR) against compute time over a grid of rays x bounces, or per quality preset");
  cmd->add_option("geometry", o->geometry, "Scene geometry (glTF 2.0, .gltf or .glb)")->required()->check(CLI::ExistingFile);
  addVec3Option(*cmd, "--source", o->source, "Source position in metres")->required();
  addVec3Option(*cmd, "--listener", o->listener, "Listener position in metres")->required();
  cmd->add_option("-o,--output", o->output,
                  "Output CSV (rays,bounces,seconds_median,<metric>_jnd...,max_jnd; with --presets a preset column "
                  "first)")
      ->required();
  cmd->add_option("--materials", o->materials, "Materials JSON (default: the built-in materials/default.json)");
  cmd->add_option("--material-map", o->materialMap, "JSON object mapping glTF material names to acoustic materials");
  auto* raysOpt = cmd->add_option("--rays", o->rays, "Comma-separated ray counts")->capture_default_str();
  auto* bouncesOpt = cmd->add_option("--bounces", o->bounces, "Comma-separated bounce limits")->capture_default_str();
  cmd->add_option("--presets", o->presets,
                  "Instead of the grid, one row per quality preset (all its settings): comma-separated names of "
                  "draft, balanced, high, reference, or 'all'")
      ->excludes(raysOpt)
      ->excludes(bouncesOpt);
  cmd->add_option("--reference", o->reference,
                  "Reference IR (mono WAV; its rate is used for the sweep); default: a run of the 'reference' preset")
      ->check(CLI::ExistingFile);
  cmd->add_option("--repeats", o->repeats, "Runs per point (seeds 1..N); time is their median")
      ->check(CLI::Range(1, 1000))->capture_default_str();
  cmd->add_option("--threads", o->threads, "Threads (0 = all cores)")->check(CLI::Range(0u, 256u))->capture_default_str();
  cmd->add_option("--air", o->air, "Air absorption: TEMP_C,HUMIDITY_PCT or off (ISO 9613-1)")->capture_default_str();
  cmd->add_option("--plot", o->plot, "Also draw error vs time to this SVG (python3 + matplotlib)");
  cmd->add_option("--plot-script", o->plotScript, "The plotting script, relative to the current directory")
      ->capture_default_str();
  cmd->add_option("--python", o->python, "Python interpreter for --plot (needs matplotlib)")->capture_default_str();
  auto* ambOpt = cmd->add_option("--ambisonic-orders", o->ambisonicOrders,
                                 "Instead of the sweep: ambisonic reflections of these orders (e.g. 1,2,3) against "
                                 "exact binaural ones of the same simulation: first-reflection ILD per octave, late "
                                 "IACC, EDT and C80 per ear (JND); the CSV has one row per order, after a row of "
                                 "binaural reflections of another seed (the floor those figures sit on)");
  ambOpt->excludes(raysOpt)->excludes(bouncesOpt);
  addVec3Option(*cmd, "--forward", o->forward, "Listener forward vector, with --ambisonic-orders (default 0,0,-1)");
  addVec3Option(*cmd, "--up", o->up, "Listener up vector, with --ambisonic-orders (default 0,1,0)");
  cmd->add_option("--hrtf", o->hrtf, "HRTF set for --ambisonic-orders (default: the shipped KU100 set)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--trace", o->trace,
                  "How the sweep's points are traced: per-source (from the source) or shared (from the listener, "
                  "the source detecting: the runtime's shared trace); the reference run is traced per source")
      ->check(CLI::IsMember({"per-source", "shared"}))
      ->excludes(ambOpt)
      ->capture_default_str();
  cmd->add_option("--quality", o->quality, "Quality preset of the --ambisonic-orders simulation")
      ->check(CLI::IsMember({"draft", "balanced", "high", "reference"}))
      ->capture_default_str();
  cmd->callback([o] { setExitCode(run(*o)); });
});

}  // namespace
}  // namespace earshot::cli
