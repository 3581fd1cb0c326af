// earshot's IRs against independent references, judged in JND of ISO 3382-1
// parameters (EDT/T20/T30 5 %, C50/C80 1 dB, D50 0.05, Ts 10 ms).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "earshot/analysis/compare.h"
#include "earshot/analysis/room_acoustics.h"
#include "earshot/core/random.h"
#include "earshot/core/thread_pool.h"
#include "earshot/io/wav.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/scene/ray_tracer.h"
#include "lattice_image_sources.h"

namespace earshot {
namespace {
using analysis::BandMetrics;
using analysis::Metric;

const std::string kRef = std::string(EARSHOT_TEST_DATA_DIR) + "/reference/";

// The suite runs twice: traced from the source (regression_tests) and by the
// shared, listener-centred trace (regression_shared_trace_tests, where
// EARSHOT_SHARED_TRACE is defined): by reciprocity the same energies, held to
// the same tolerances.
#ifdef EARSHOT_SHARED_TRACE
constexpr TraceMode kTraceMode = TraceMode::kShared;
#define Regression RegressionSharedTrace
#else
constexpr TraceMode kTraceMode = TraceMode::kPerSource;
#endif
const Vec3d kSource{2, 3.5, 1.5}, kListener{7, 3.5, 1.5};

nlohmann::json readJson(const std::string& path) {
  nlohmann::json j;
  std::ifstream(path) >> j;
  return j;
}

// Our omni IR of the 10x7x3 m shoebox with per-wall materials.
OmniIrResult shoeboxResult(const std::array<BandArray, 6>& alpha, float scattering, const AirConditions& air,
                           const Vec3d& source = kSource, const Vec3d& listener = kListener,
                           const OmniIrSettings& base = {}) {
  MaterialTable materials;
  std::array<uint32_t, 6> ids{};
  for (int w = 0; w < 6; ++w) {
    Material m;
    m.name = "wall" + std::to_string(w);
    m.absorption = alpha[w];
    m.scattering = filledBands(scattering);
    m.transmission = filledBands(0.0f);
    ids[w] = materials.add(m);
  }
  auto tracer = RayTracer::create(makeBox({0, 0, 0}, {10, 7, 3}, ids));
  EXPECT_TRUE(tracer.isOk());
  ThreadPool pool(2);
  OmniIrSettings s = base;
  s.air = air;
  IrRequest request;
  request.source = source;
  request.directivity = s.directivity;
  auto r = computeIrs(**tracer, materials, listener, {request}, s, kTraceMode, pool);
  EXPECT_TRUE(r.isOk()) << r.status().message();
  return std::move(r->front());
}

AudioBuffer shoeboxIr(const std::array<BandArray, 6>& alpha, float scattering, const AirConditions& air) {
  return shoeboxResult(alpha, scattering, air).ir;
}

void printRow(const char* name, int band, const BandMetrics& ours, const BandMetrics& ref) {
  std::printf("%-10s %5s  EDT %.3f/%.3f  T20 %.3f/%.3f  T30 %.3f/%.3f  C50 %.2f/%.2f  C80 %.2f/%.2f  D50 %.3f/%.3f  "
              "Ts %.4f/%.4f\n",
              name, analysis::bandLabel(band).c_str(), ours.edtS, ref.edtS, ours.t20S, ref.t20S, ours.t30S, ref.t30S,
              ours.c50Db, ref.c50Db, ours.c80Db, ref.c80Db, ours.d50, ref.d50, ours.tsS, ref.tsS);
}

// Checks `metrics` in `bands` within `jnd` JND; returns the number of failures.
int expectWithin(const std::vector<BandMetrics>& ours, const std::vector<BandMetrics>& ref, const std::vector<int>& bands,
                 const std::vector<Metric>& metrics, double jnd, const std::string& label) {
  int failures = 0;
  for (int b : bands) {
    printRow(label.c_str(), b, ours[size_t(b)], ref[size_t(b)]);
    for (Metric m : metrics) {
      const double want = ref[size_t(b)].value(m), got = ours[size_t(b)].value(m);
      const double d = analysis::differenceInJnd(m, got, want);
      EXPECT_LE(std::fabs(d), jnd) << label << " " << analysis::metricName(m) << " at " << analysis::bandLabel(b)
                                   << ": ours " << got << ", reference " << want << " (" << d << " JND)";
      failures += !(std::fabs(d) <= jnd);
    }
  }
  return failures;
}

}  // namespace

namespace {

// Metrics of an energy envelope (sqrt of 1 ms bin energies, see
// lattice_image_sources.h): no filtering, no noise treatment.
BandMetrics envelopeMetrics(const std::vector<float>& envelope, double binSeconds, double windowEndS) {
  std::vector<float> x(envelope.begin(), envelope.begin() + long(std::min(envelope.size(), size_t(windowEndS / binSeconds))));
  return analysis::analyzeBandSignal(x.data(), x.size(), 1.0 / binSeconds, -1, 0, analysis::NoiseTreatment::kNone);
}

std::vector<BandMetrics> oursPerBand(const AudioBuffer& ir, double windowEndS) {
  analysis::AnalysisOptions opt;
  opt.windowEndS = windowEndS;
  auto m = analysis::analyzeIr(ir.channels[0], ir.sampleRateHz, opt);
  EXPECT_TRUE(m.isOk());
  return *m;
}

const std::vector<int> kMidBands = {1, 2, 3, 4, 5};  // 250 Hz .. 4 kHz

struct PraCase {
  std::string alpha;
  double complete;
  nlohmann::json info;
};

std::vector<PraCase> praCases() {
  const auto summary = readJson(kRef + "pyroomacoustics/summary.json");
  std::vector<PraCase> cases;
  for (const char* a : {"0.3", "0.6"}) cases.push_back({a, summary["ism"][a]["t_complete_s"], summary["ism"][a]});
  return cases;
}

std::vector<reference::Image> praImages(float alpha, double seconds) {
  std::array<std::array<double, 7>, 6> a;
  for (auto& w : a) w.fill(alpha);
  return reference::latticeImages({10, 7, 3}, {2, 3.5, 1.5}, {7, 3.5, 1.5}, a, {}, 343.0, seconds);
}

}  // namespace

// The lattice generator (test code, Allen & Berkley) reproduces the metrics
// pyroomacoustics' authors computed from their own nearest-sample image-source
// reference (summary.json "metrics_ismref_nearest", broadband): the
// generator is an independent, validated reference.
TEST(Regression, LatticeImageSourcesReproducePyroomacousticsReferenceMetrics) {
  for (const PraCase& c : praCases()) {
    auto images = praImages(std::stof(c.alpha), c.complete);
    auto train = reference::coherentTrain(images, -1, 48000, c.complete);
    BandMetrics m = analysis::analyzeBandSignal(train.data(), train.size(), 48000, -1, 0, analysis::NoiseTreatment::kNone);
    const auto& ref = c.info["metrics_ismref_nearest"];
    for (Metric metric : {Metric::kEdt, Metric::kT30, Metric::kC50, Metric::kC80, Metric::kD50, Metric::kTs}) {
      const double want = ref[analysis::metricName(metric)];
      EXPECT_NEAR(analysis::differenceInJnd(metric, m.value(metric), want), 0.0, 0.1)
          << "alpha " << c.alpha << " " << analysis::metricName(metric);
    }
  }
}


// The ideal energy method's IR against one exact specular IR (see the next
// test): the exact images before t_c at their samples, after t_c Gaussian
// noise carrying exactly the images' energy per 1 ms.
namespace {
std::vector<float> idealHybrid(const std::vector<reference::Image>& images, double tc, uint64_t seed, double fs,
                               double complete) {
  std::vector<reference::Image> early, late;
  for (const auto& im : images) (im.delaySeconds < tc ? early : late).push_back(im);
  const auto lateEnvelope = reference::incoherentEnvelope(late, 3, 0.001, complete);
  std::vector<float> x = reference::coherentTrain(early, 3, fs, complete);
  Pcg32 rng(seed, 7);
  for (size_t i = 0; i < x.size(); ++i) {
    const size_t bin = size_t(double(i) / fs / 0.001);
    if (bin >= lateEnvelope.size()) break;
    const double u1 = 1.0 - rng.uniformDouble(), u2 = rng.uniformDouble();  // Box-Muller
    const double gauss = std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
    x[i] += float(double(lateEnvelope[bin]) * gauss / std::sqrt(0.001 * fs));
  }
  return x;
}
}  // namespace

// Known answers at the IR level, judged as an energy method is judged
// (issue 20's decision): no energy method, even an ideal one, reaches 1 JND
// of one exact specular IR, so earshot's IR is held to the ideal energy
// method's own distance from the exact IR (its floor) plus a margin of
// 1 JND. The ideal method: idealHybrid with t_c = 30 ms (where image sources
// to order 3 end, earshot's budget), 3 noise seeds. Both against the exact
// IR (the lattice images, coherent: what pyroomacoustics computes, see the
// test above), through the same ISO 3382-1 analysis up to where the exact
// IR is complete, 250 Hz - 4 kHz. Compared per metric on the worst band,
// as the floor is stated: with 3 seeds the ideal method's per-band spread
// is itself a sample (its worst band moves from 250 Hz to 4 kHz between
// seeds), and so is earshot's one IR. Measured (worst band, JND): symmetric
// positions, alpha 0.3: EDT 9.3 (ideal 4.9 - 9.3), C80 4.4 (3.0 - 3.9), D50
// 3.5 (3.0 - 3.3), T30 1.4 (0.7 - 1.7); alpha 0.6: EDT 3.7 (7.8 - 8.7), C80
// 4.4 (3.3 - 4.2), D50 0.5 (0.4 - 0.5), T30 4.5 (0.1 - 3.8). Band by band
// earshot is within its band's 3-seed floor + 1 JND in 35 of 40 cases; the
// exceptions are EDT at 1 - 4 kHz at alpha 0.3 (8.7 - 9.3 against 5.6 - 6.2)
// and C80 at 250 Hz, T30 at 4 kHz at alpha 0.6 (+0.5, +0.6 over the margin).
// Off the symmetry planes: alpha 0.3: EDT 4.9 (ideal up to 17.0), C80 1.7
// (3.5), D50 1.1 (1.9), T30 1.9 (2.0); alpha 0.6: EDT 4.0 (7.0), C80 3.1
// (5.3), D50 0.3 (0.3), T30 2.3 (2.6). These replace the two
// DISABLED_KnownGap tests that asked for 1 JND of the exact IR.
void expectWithinIdealEnergyFloor(const std::vector<reference::Image>& images, const AudioBuffer& oursIr,
                                  double complete, const std::string& label) {
  constexpr double kMarginJnd = 1.0;
  const double fs = 48000;
  const Metric metrics[4] = {Metric::kEdt, Metric::kC80, Metric::kD50, Metric::kT30};
  analysis::AnalysisOptions opt;
  opt.windowEndS = complete;
  const auto exact = analysis::analyzeIr(reference::coherentTrain(images, 3, fs, complete), fs, opt);
  ASSERT_TRUE(exact.isOk());
  const auto ours = oursPerBand(oursIr, complete);
  for (int k = 0; k < 4; ++k) {
    auto worstBand = [&](const std::vector<BandMetrics>& m) {
      double worst = 0;
      for (int b : kMidBands) {
        const double d = analysis::differenceInJnd(metrics[k], m[size_t(b)].value(metrics[k]),
                                                   (*exact)[size_t(b)].value(metrics[k]));
        if (std::isfinite(d)) worst = std::max(worst, std::fabs(d));
      }
      return worst;
    };
    double floor = 0;
    for (uint64_t seed = 1; seed <= 3; ++seed) {
      const auto m = analysis::analyzeIr(idealHybrid(images, 0.03, seed, fs, complete), fs, opt);
      ASSERT_TRUE(m.isOk());
      floor = std::max(floor, worstBand(*m));
    }
    const double mine = worstBand(ours);
    std::printf("%s %s, worst band: earshot %.1f JND, the ideal energy method up to %.1f JND\n", label.c_str(),
                analysis::metricName(metrics[k]), mine, floor);
    EXPECT_LE(mine, floor + kMarginJnd) << label << " " << analysis::metricName(metrics[k]);
  }
}

TEST(Regression, PyroomacousticsShoeboxIrsWithinTheIdealEnergyMethodFloor) {
  AirConditions noAir;
  noAir.enabled = false;
  for (const PraCase& c : praCases()) {
    const float alpha = std::stof(c.alpha);
    std::array<BandArray, 6> a;
    a.fill(filledBands(alpha));
    expectWithinIdealEnergyFloor(praImages(alpha, c.complete), shoeboxIr(a, 0.0f, noAir), c.complete,
                                 "pra a=" + c.alpha);
  }
}

// The same off the symmetry planes (no coincident images).
TEST(Regression, AsymmetricShoeboxIrWithinTheIdealEnergyMethodFloor) {
  AirConditions noAir;
  noAir.enabled = false;
  const Vec3d src{2.3, 3.1, 1.2}, rcv{6.6, 4.2, 1.7};
  for (const PraCase& c : praCases()) {
    const float alpha = std::stof(c.alpha);
    std::array<BandArray, 6> a;
    a.fill(filledBands(alpha));
    std::array<std::array<double, 7>, 6> aa;
    for (auto& w : aa) w.fill(alpha);
    auto images = reference::latticeImages({10, 7, 3}, {src.x, src.y, src.z}, {rcv.x, rcv.y, rcv.z}, aa, {}, 343.0,
                                           c.complete);
    expectWithinIdealEnergyFloor(images, shoeboxResult(a, 0.0f, noAir, src, rcv).ir, c.complete,
                                 "asym a=" + c.alpha);
  }
}

// What IR-level agreement with one exact specular IR takes, whatever the
// late-reverb method. An "ideal hybrid" IR: the exact images up to t_c at
// their samples (coherently), and after t_c Gaussian noise carrying exactly
// the images' energy per 1 ms (a perfect energy method with a perfect tail),
// analysed like ours against the exact IR at pyroomacoustics' positions.
// With t_c = 30 ms (about where image sources to order 3 end) some band's
// EDT misses by several JND for every noise seed although every energy is
// exact; with t_c = 0.25 s (images up to order ~25) EDT, C80 and D50 are
// within 1 JND. T30 at alpha 0.3 misses by several JND even then (the
// coherent late groups). So the IR-level criteria of the known gap above
// need exact specular paths to a quarter second; 16384 rays x 12 bounces
// reach about 0.12 s, and finding paths from those rays (the alternative to
// a receiver sized from the ray density) would not get there either.
// Measured, worst band per noise seed (seeds 1 - 3), alpha 0.3 / 0.6:
// t_c 30 ms: EDT 4.9 - 9.3 / 7.8 - 8.7 JND, C80 3.0 - 3.9 / 3.3 - 4.2;
// t_c 0.25 s: EDT <= 0.2 / 0.0, C80 <= 0.2 / 0.0, D50 0.0 / 0.0, T30
// 4.7 - 5.1 / 0.0.
TEST(Regression, IrLevelAgreementWithOneSpecularIrNeedsExactPathsToAQuarterSecond) {
  const double fs = 48000;
  for (const PraCase& c : praCases()) {
    const auto images = praImages(std::stof(c.alpha), c.complete);
    analysis::AnalysisOptions opt;
    opt.windowEndS = c.complete;
    const auto exact = analysis::analyzeIr(reference::coherentTrain(images, 3, fs, c.complete), fs, opt);
    ASSERT_TRUE(exact.isOk());
    for (double tc : {0.03, 0.25}) {
      double bestEdt = 1e9;  // over seeds, of the worst band
      for (uint64_t seed = 1; seed <= 3; ++seed) {
        const auto m = analysis::analyzeIr(idealHybrid(images, tc, seed, fs, c.complete), fs, opt);
        ASSERT_TRUE(m.isOk());
        double worst[4] = {0, 0, 0, 0};
        const Metric metrics[4] = {Metric::kEdt, Metric::kC80, Metric::kD50, Metric::kT30};
        for (int k = 0; k < 4; ++k)
          for (int b : kMidBands) {
            const double d = analysis::differenceInJnd(metrics[k], (*m)[size_t(b)].value(metrics[k]),
                                                       (*exact)[size_t(b)].value(metrics[k]));
            if (std::isfinite(d)) worst[k] = std::max(worst[k], std::fabs(d));
          }
        std::printf("ideal hybrid a=%s t_c %.2f s seed %d, worst band: EDT %.1f C80 %.1f D50 %.1f T30 %.1f JND\n",
                    c.alpha.c_str(), tc, int(seed), worst[0], worst[1], worst[2], worst[3]);
        bestEdt = std::min(bestEdt, worst[0]);
        if (tc > 0.2) {
          EXPECT_LE(worst[0], 1.0) << "EDT, alpha " << c.alpha;
          EXPECT_LE(worst[1], 1.0) << "C80, alpha " << c.alpha;
          EXPECT_LE(worst[2], 1.0) << "D50, alpha " << c.alpha;
        }
      }
      if (tc < 0.1) {
        EXPECT_GT(bestEdt, 3.0) << "alpha " << c.alpha << ": exact energies would have been enough";
      }
    }
  }
}

// Our propagated energy per band in 1 ms bins: direct + image sources (as
// energies) + the completed late histogram, as an envelope (see
// envelopeMetrics).
std::vector<float> ourEnergyEnvelope(const OmniIrResult& r, int band, double seconds) {
  std::vector<double> e(size_t(seconds / 0.001) + 1, 0.0);
  auto add = [&](double t, double energy) {
    const size_t i = size_t(t / 0.001);
    if (i < e.size()) e[i] += energy;
  };
  add(r.direct.delaySeconds, std::pow(r.direct.spreadingGain * r.direct.bandGain[size_t(band)], 2));
  for (const auto& p : r.early) add(p.delaySeconds, std::pow(p.spreadingGain * p.bandGain[size_t(band)], 2));
  for (size_t i = 0; i < r.late.binCount(); ++i) add((double(i) + 0.5) * r.late.binSeconds(), r.late.energy(i, band));
  std::vector<float> out(e.size());
  for (size_t i = 0; i < e.size(); ++i) out[i] = float(std::sqrt(e[i]));
  return out;
}

// The reference shoebox with six different wall materials and air (specular):
// its exact energy per band in 1 ms bins (energy_hist_1ms.csv) against the
// energy earshot propagates at the default budget, through the same ISO
// 3382-1 metrics: EDT, C50, C80, D50, Ts within 1 JND in 250 Hz - 4 kHz;
// T20/T30 where meta.json marks them converged. (Energies, not IRs: at these
// symmetric positions coincident image sources add coherently in any IR,
// exact or ours; the histogram is what the propagation model computes.)
struct MultibandCase {
  std::vector<BandMetrics> mine, exact;
  nlohmann::json meta;
};

MultibandCase multibandCase(const OmniIrSettings& settings = {}) {
  MultibandCase c;
  c.meta = readJson(kRef + "shoebox_multiband/meta.json");
  std::array<BandArray, 6> alpha;
  for (int w = 0; w < 6; ++w)
    for (int b = 0; b < kNumBands; ++b) alpha[w][b] = c.meta["alpha"][w][b].get<float>();
  const OmniIrResult ours = shoeboxResult(alpha, 0.0f, AirConditions{}, kSource, kListener, settings);
  const double complete = c.meta["t_complete_s"];
  std::ifstream csv(kRef + "shoebox_multiband/energy_hist_1ms.csv");
  std::string line;
  std::getline(csv, line);
  std::vector<std::array<double, 7>> hist;
  while (std::getline(csv, line)) {
    std::stringstream ss(line);
    std::string cell;
    std::getline(ss, cell, ',');
    std::array<double, 7> e;
    for (int b = 0; b < 7; ++b) {
      std::getline(ss, cell, ',');
      e[size_t(b)] = std::stod(cell);
    }
    hist.push_back(e);
  }
  EXPECT_GT(hist.size(), 1000u);
  c.exact.resize(analysis::kAnalysisBandCount);
  c.mine.resize(analysis::kAnalysisBandCount);
  for (int b : kMidBands) {
    std::vector<float> env(hist.size());
    for (size_t i = 0; i < hist.size(); ++i) env[i] = float(std::sqrt(hist[i][size_t(b)]));
    c.exact[size_t(b)] = envelopeMetrics(env, 0.001, complete);
    c.mine[size_t(b)] = envelopeMetrics(ourEnergyEnvelope(ours, b, complete), 0.001, complete);
  }
  return c;
}

// T20/T30 where meta.json marks them converged (the exact decay is not
// truncated by the reference's 2 s).
void expectConvergedDecayTimesWithin(const MultibandCase& c, double jnd) {
  for (int b : kMidBands) {
    const auto& bm = c.meta["band_metrics"][std::to_string(int(kBandCentersHz[size_t(b)]))];
    for (auto [m, key] : {std::pair{Metric::kT20, "T20"}, std::pair{Metric::kT30, "T30"}})
      if (bm[std::string(key) + "_converged"].get<bool>()) {
        const double d = analysis::differenceInJnd(m, c.mine[size_t(b)].value(m), c.exact[size_t(b)].value(m));
        EXPECT_LE(std::fabs(d), jnd) << key << " at " << analysis::bandLabel(b) << ": " << d << " JND";
      }
  }
}

TEST(Regression, MultibandShoeboxEnergyMatchesExactEnergyHistogram) {
  MultibandCase c = multibandCase();
  expectWithin(c.mine, c.exact, kMidBands, {Metric::kC50, Metric::kC80, Metric::kD50}, 1.0, "multiband");
}

// EDT and Ts within 1 JND, and T20/T30 where converged. This box's late
// decay is flutter between its reflective west, east and south walls, a
// specular decay much slower late than any single rate, carried by the few
// rays that leave near the x axis: flutter cones sample those directions
// densely, and every ray carries on as a tail probe whose deposits in the
// receiver sphere are the tail (tail_completion.h). Measured at seed 1: EDT
// +0.39, +0.17, +0.79, +0.16, +0.12 JND (250 Hz - 4 kHz), T20 at 250 Hz
// +0.34, T20/T30 at 4 kHz +0.45 / +0.35; over seeds 1 - 16, 14 meet every
// criterion (RMS over seeds: EDT 0.44, converged T20 0.30, T30 at 4 kHz
// 0.33 JND).
// Before (one extrapolated rate, then undetected probes x one
// detections-per-energy ratio, uniform directions): EDT at 1 kHz -2.4, T20
// /T30 at 4 kHz -2.1 / -3.0 at seed 1, and T30 at 4 kHz -3.0 .. +7.6 JND
// over seeds 1 - 6.
TEST(Regression, MultibandShoeboxEdtAndConvergedDecayTimes) {
  MultibandCase c = multibandCase();
  expectWithin(c.mine, c.exact, kMidBands, {Metric::kEdt, Metric::kTs}, 1.0, "multiband");
  expectConvergedDecayTimesWithin(c, 1.0);
}

// Every criterion at the `reference` preset (262144 rays x 64 bounces, 0.5 ms
// bins) too: the method converges to the exact answer. Measured at seed 1:
// EDT -0.5 .. -0.2 JND, T20 at 250 Hz -0.1, T20/T30 at 4 kHz -0.1 / 0.0.
TEST(Regression, MultibandShoeboxMeetsEveryCriterionAtTheReferencePreset) {
  OmniIrSettings s;
  apply(*qualityPreset("reference"), s);
  MultibandCase c = multibandCase(s);
  expectWithin(c.mine, c.exact, kMidBands, {Metric::kEdt, Metric::kC50, Metric::kC80, Metric::kD50, Metric::kTs}, 1.0,
               "multiband reference");
  expectConvergedDecayTimesWithin(c, 1.0);
}

// The same, uniform alpha 0.3 and 0.6 (pyroomacoustics' rooms, no air),
// against the exact incoherent energy of the lattice image sources: EDT, C50,
// C80, D50, Ts within 1 JND; T30 is a known gap (below).
std::vector<BandMetrics> uniformEnergyMetrics(float alpha, double complete, std::vector<BandMetrics>& exact) {
  AirConditions noAir;
  noAir.enabled = false;
  std::array<BandArray, 6> a;
  a.fill(filledBands(alpha));
  const OmniIrResult ours = shoeboxResult(a, 0.0f, noAir);
  auto images = praImages(alpha, complete);
  std::vector<BandMetrics> mine(analysis::kAnalysisBandCount);
  exact.assign(analysis::kAnalysisBandCount, BandMetrics{});
  for (int b : kMidBands) {
    exact[size_t(b)] = envelopeMetrics(reference::incoherentEnvelope(images, b, 0.001, complete), 0.001, complete);
    mine[size_t(b)] = envelopeMetrics(ourEnergyEnvelope(ours, b, complete), 0.001, complete);
  }
  return mine;
}

TEST(Regression, UniformShoeboxEnergyMatchesExactImageSourceEnergy) {
  for (const PraCase& c : praCases()) {
    std::vector<BandMetrics> exact;
    auto mine = uniformEnergyMetrics(std::stof(c.alpha), c.complete, exact);
    expectWithin(mine, exact, kMidBands, {Metric::kEdt, Metric::kC50, Metric::kC80, Metric::kD50, Metric::kTs}, 1.0,
                 "energy a=" + c.alpha);
  }
}

// T30 of the same energies: a specular box decays as a mixture of
// exponentials, slower late than one extrapolated rate (which gave -2.5 JND
// at alpha 0.3): the tail probes follow it. At alpha 0.6 the late detections
// of orders 6 - 12 set T30; a receiver sized from the ray density (1.0 m
// here) keeps their shot noise down (a fixed 0.5 m gave -1.4 .. -0.2 JND
// over seeds). Measured: +0.16 JND at 0.3, -0.15 at 0.6 (with undetected
// probes x one ratio it was +0.57 and -0.1; seeds 1 - 4 then +0.49 .. +0.58
// and -0.14 .. +0.03).
TEST(Regression, UniformShoeboxEnergyT30MatchesExactImageSourceEnergy) {
  for (const PraCase& c : praCases()) {
    std::vector<BandMetrics> exact;
    auto mine = uniformEnergyMetrics(std::stof(c.alpha), c.complete, exact);
    expectWithin(mine, exact, kMidBands, {Metric::kT30}, 1.0, "energy a=" + c.alpha);
  }
}

}  // namespace earshot
