// `earshot bench synth`: IR synthesis speed from traced data (binaural,
// omni, ambisonic orders 1 and 3, each also per output channel), and the
// HRTF lookup cost per direction; medians of repeated runs.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>

#include "command.h"
#include "earshot/core/thread_pool.h"
#include "earshot/hrtf/coordinates.h"
#include "earshot/ir/ambisonic_synthesis.h"
#include "earshot/ir/binaural_synthesis.h"
#include "earshot/ir/ir_pipeline.h"

namespace earshot::cli {
namespace {

struct BenchSynthOptions {
  std::string geometry;
  std::string materialMap;
  std::string hrtf;
  std::string quality = "balanced";
  std::array<double, 3> source{2, 3.5, 1.5}, listener{7, 3.5, 1.5};
  double seconds = 2.0;
  int runs = 15;
};

using Clock = std::chrono::steady_clock;

int run(const BenchSynthOptions& o) {
  auto scene = loadSceneInputs(o.geometry, "", o.materialMap);
  if (!check(scene.status())) return 2;
  OmniIrSettings settings;
  auto preset = qualityPreset(o.quality);
  if (!check(preset.status())) return 2;
  apply(*preset, settings);
  settings.lengthSeconds = o.seconds;
  const auto tLoad = Clock::now();
  auto model = loadBinauralModel(o.hrtf, settings.sampleRateHz);
  if (!check(model.status())) return 2;
  const double loadMs = msSince(tLoad);
  ThreadPool pool(1);
  const Vec3d src{o.source[0], o.source[1], o.source[2]}, lis{o.listener[0], o.listener[1], o.listener[2]};
  auto traced = computeIr(*scene->tracer, scene->materials, src, lis, settings, pool, nullptr);
  if (!check(traced.status())) return 2;
  const std::vector<Arrival> arrivals = arrivalsOf(*traced, true);
  IrSynthesisSettings is;
  is.sampleRateHz = settings.sampleRateHz;
  is.lengthSeconds = o.seconds;
  ListenerOrientation orientation;
  std::vector<double> binauralMs, omniMs, amb1Ms, amb3Ms;
  for (int i = 0; i <= o.runs; ++i) {  // run 0 warms up
    auto t = Clock::now();
    auto b = synthesizeBinauralIr(arrivals, &traced->late, is, **model, orientation);
    const double bm = msSince(t);
    if (!check(b.status())) return 2;
    t = Clock::now();
    auto m = synthesizeOmniIr(arrivals, &traced->late, is);
    const double om = msSince(t);
    if (!check(m.status())) return 2;
    double am[2];
    for (int k = 0; k < 2; ++k) {
      t = Clock::now();
      auto a = synthesizeAmbisonicIr(arrivals, &traced->late, is, k == 0 ? 1 : 3, worldAmbisonicFrame());
      am[k] = msSince(t);
      if (!check(a.status())) return 2;
    }
    if (i == 0) continue;
    binauralMs.push_back(bm);
    omniMs.push_back(om);
    amb1Ms.push_back(am[0]);
    amb3Ms.push_back(am[1]);
  }
  // HRTF lookups over a Fibonacci sphere: the audio thread's time-domain
  // lookup and the IR synthesis's frequency-domain one.
  const int directions = 2000;
  auto pair = std::make_unique<hrtf::HrirPair>();
  std::vector<std::complex<float>> spectrum;
  std::vector<double> lookupUs, spectrumUs;
  for (int rep = 0; rep < 5; ++rep) {
    auto t = Clock::now();
    for (int i = 0; i < directions; ++i) {
      const double z = 1.0 - 2.0 * (i + 0.5) / directions, r = std::sqrt(1.0 - z * z), phi = 2.39996322972865332 * i;
      (*model)->hrtf().lookup(Vec3f(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)), *pair);
    }
    lookupUs.push_back(msSince(t) * 1000.0 / directions);
    t = Clock::now();
    for (int i = 0; i < directions; i += 10) {
      const double z = 1.0 - 2.0 * (i + 0.5) / directions, r = std::sqrt(1.0 - z * z), phi = 2.39996322972865332 * i;
      (*model)->hrtfSpectrum(Vec3f(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)), 0, spectrum);
    }
    spectrumUs.push_back(msSince(t) * 1000.0 / (directions / 10));
  }
  const double b = median(binauralMs), m = median(omniMs), a1 = median(amb1Ms), a3 = median(amb3Ms);
  std::printf("synth scene=%s quality=%s ir_seconds=%.2f arrivals=%zu runs=%d threads=1 binaural_ms=%.2f omni_ms=%.2f "
              "ambisonic1_ms=%.2f ambisonic3_ms=%.2f hrtf_load_ms=%.0f hrtf_lookup_us=%.2f hrtf_spectrum_us=%.1f (per ear)\n",
              o.geometry.c_str(), o.quality.c_str(), o.seconds, arrivals.size(), o.runs, b, m, a1, a3, loadMs,
              median(lookupUs), median(spectrumUs));
  std::printf("synth per output channel: binaural_ms=%.2f omni_ms=%.2f ambisonic1_ms=%.2f ambisonic3_ms=%.2f\n", b / 2,
              m, a1 / 4, a3 / 16);
  return 0;
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<BenchSynthOptions>();
  CLI::App& bench = subcommandGroup(root, "bench", "Measure the speed of earshot's stages");
  CLI::App* cmd = bench.add_subcommand(
      "synth",
      "IR synthesis speed from traced data (binaural, omni, ambisonic orders 1 and 3; one thread; also per output "
      "channel) and HRTF lookup cost");
  cmd->add_option("geometry", o->geometry, "Scene geometry (glTF)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--material-map", o->materialMap, "JSON object mapping glTF material names to acoustic materials");
  cmd->add_option("--hrtf", o->hrtf, "HRTF set (SOFA); default: the shipped KU100 set")->check(CLI::ExistingFile);
  cmd->add_option("--quality", o->quality, "Preset of the traced data")
      ->check(CLI::IsMember({"draft", "balanced", "high", "reference"}))
      ->capture_default_str();
  addVec3Option(*cmd, "--source", o->source, "Source position in metres (default 2,3.5,1.5)");
  addVec3Option(*cmd, "--listener", o->listener, "Listener position in metres (default 7,3.5,1.5)");
  cmd->add_option("--seconds", o->seconds, "IR length")->check(CLI::Range(0.01, 60.0))->capture_default_str();
  cmd->add_option("--runs", o->runs, "Timed runs (median reported)")->check(CLI::Range(1, 10000))->capture_default_str();
  cmd->callback([o] { setExitCode(run(*o)); });
});

}  // namespace
}  // namespace earshot::cli
