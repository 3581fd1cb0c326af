// Binaural IRs (issue 4): identity HRTF = omni, direction and interpolation
// of the direct sound, listener orientation, diffuse late field.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <memory>
#include <string>
#include <vector>

#include "../propagation/shoebox_fixture.h"
#include "earshot/core/math.h"
#include "earshot/core/thread_pool.h"
#include "earshot/hrtf/coordinates.h"
#include "earshot/ir/binaural_synthesis.h"
#include "earshot/ir/ir_pipeline.h"

namespace earshot {
namespace {

const std::string kPulse = std::string(EARSHOT_TEST_DATA_DIR) + "/hrtf/Pulse.sofa";
const std::string kKu100 = std::string(EARSHOT_SOURCE_DIR) + "/hrtf/FHK_HRIR_L2354.sofa";

std::shared_ptr<const BinauralModel> model(const std::string& path, double fs = 48000.0) {
  auto m = loadBinauralModel(path, fs);
  EXPECT_TRUE(m.isOk()) << m.status().message();
  return m.isOk() ? *m : nullptr;
}

std::unique_ptr<RayTracer> freeField() {
  auto rt = RayTracer::create(TriangleMesh{});
  EXPECT_TRUE(rt.isOk());
  return std::move(rt.value());
}

double peakOf(const std::vector<float>& x) {
  double p = 0;
  for (float v : x) p = std::max(p, double(std::fabs(v)));
  return p;
}

double maxDifference(const std::vector<float>& a, const std::vector<float>& b) {
  EXPECT_EQ(a.size(), b.size());
  double d = 0;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) d = std::max(d, double(std::fabs(a[i] - b[i])));
  return d;
}

// The omni and the binaural IR of one pair with the same settings.
struct IrPair {
  AudioBuffer omni, binaural;
};
IrPair render(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& source, const Vec3d& listener,
              const OmniIrSettings& s, const BinauralReceiver& receiver) {
  ThreadPool pool(2);
  auto omni = computeIr(tracer, materials, source, listener, s, pool, nullptr);
  auto bin = computeIr(tracer, materials, source, listener, s, pool, &receiver);
  EXPECT_TRUE(omni.isOk()) << omni.status().message();
  EXPECT_TRUE(bin.isOk()) << bin.status().message();
  if (!omni.isOk() || !bin.isOk()) return {};
  return {std::move(omni->ir), std::move(bin->ir)};
}

// |X(f)|^2 of x (rate fs) summed over f = lo, lo + 10 Hz, ... < hi (direct DFT).
double bandEnergy(const float* x, size_t n, double fs, double lo, double hi) {
  double e = 0;
  for (double f = lo; f < hi; f += 10.0) {
    std::complex<double> acc = 0;
    const std::complex<double> step = std::polar(1.0, -2.0 * kPi * f / fs);
    std::complex<double> ph = 1.0;
    for (size_t i = 0; i < n; ++i, ph *= step) acc += double(x[i]) * ph;
    e += std::norm(acc);
  }
  return e;
}

}  // namespace

// Issue 4: with the identity set Pulse.sofa the binaural IR of a free-field
// source equals the omni IR in both ears (to 1e-5 of the peak), whatever the
// direction and orientation.
TEST(BinauralIr, PulseSetGivesTheOmniIrInBothEarsInFreeField) {
  auto pulse = model(kPulse);
  ASSERT_TRUE(pulse);
  auto tracer = freeField();
  MaterialTable materials;
  OmniIrSettings s;
  for (const Vec3d& source : {Vec3d(0, 0, -3), Vec3d(-2, 0.5, 0), Vec3d(1, 4, 2), Vec3d(0.3, -1, 7)}) {
    BinauralReceiver receiver{pulse, {}};
    receiver.orientation.forward = {0.2, 0.1, -1.0};
    IrPair r = render(*tracer, materials, source, {0, 0, 0}, s, receiver);
    ASSERT_EQ(r.binaural.channelCount(), 2u);
    const double peak = peakOf(r.omni.channels[0]);
    ASSERT_GT(peak, 0.0);
    for (int ear = 0; ear < 2; ++ear)
      EXPECT_LE(maxDifference(r.binaural.channels[ear], r.omni.channels[0]), 1e-5 * peak) << "ear " << ear;
  }
}

// The same holds in a room: image sources through the identity HRTF and the
// late field's diffuse-field mixing of an identity set reduce to the omni IR.
TEST(BinauralIr, PulseSetGivesTheOmniIrInBothEarsInARoom) {
  auto pulse = model(kPulse);
  ASSERT_TRUE(pulse);
  testing::Shoebox room(0.2f, 0.5f);
  OmniIrSettings s;
  s.rays = 2000;
  s.bounces = 8;
  BinauralReceiver receiver{pulse, {}};
  IrPair r = render(*room.tracer, room.materials, {2, 3, 1.5}, {7, 4, 1.6}, s, receiver);
  ASSERT_EQ(r.binaural.channelCount(), 2u);
  const double peak = peakOf(r.omni.channels[0]);
  for (int ear = 0; ear < 2; ++ear)
    EXPECT_LE(maxDifference(r.binaural.channels[ear], r.omni.channels[0]), 1e-5 * peak) << "ear " << ear;
}

// Issue 4 interpolation: for a direction between two neighbouring
// measurements, the direct sound's magnitude response in each one-third
// octave band up to 8 kHz is within 1 dB of the neighbours' average, in both
// ears (the ear facing the source and the shadowed one). Measured on the
// rendered IR against the set's measured HRIRs (whose magnitude the stored
// minimum-phase HRIRs keep).
TEST(BinauralIr, DirectSoundBetweenMeasurementsHasTheNeighboursAverageMagnitude) {
  auto ku100 = model(kKu100);
  ASSERT_TRUE(ku100);
  const hrtf::HrtfSet& set = ku100->hrtf();
  const double fs = set.sampleRateHz(), r = 2.0;
  auto tracer = freeField();
  MaterialTable materials;
  OmniIrSettings s;
  s.air.enabled = false;
  const size_t n = set.measurementCount(), taps = set.hrirLength();
  double worst = 0;
  int checked = 0;
  for (size_t i = 0; i < n; i += 97) {
    const Vec3f a = set.measurement(i).headDirection;
    size_t j = i == 0 ? 1 : 0;
    for (size_t k = 0; k < n; ++k)
      if (k != i && length(set.measurement(k).headDirection - a) < length(set.measurement(j).headDirection - a)) j = k;
    const Vec3f b = set.measurement(j).headDirection;
    if (length(b - a) < 1e-4f) continue;  // a duplicated direction
    const Vec3d mid = normalize(Vec3d(a + b));
    // Head frame = world frame for the default orientation.
    ThreadPool pool(1);
    BinauralReceiver receiver{ku100, {}};
    auto ir = computeIr(*tracer, materials, mid * r, {0, 0, 0}, s, pool, &receiver);
    ASSERT_TRUE(ir.isOk()) << ir.status().message();
    const size_t start = size_t(std::max(0.0, (r / 343.0 - 0.004) * fs));
    const size_t len = std::min<size_t>(1024, ir->ir.frameCount() - start);
    for (int ear = 0; ear < 2; ++ear) {
      const float* got = ir->ir.channels[ear].data() + start;
      const hrtf::HrtfMeasurement mi = set.measurement(i), mj = set.measurement(j);
      for (int band = -10; band <= 9; ++band) {
        const double fc = 1000.0 * std::pow(2.0, band / 3.0);
        const double lo = fc * std::pow(2.0, -1.0 / 6.0), hi = fc * std::pow(2.0, 1.0 / 6.0);
        const double ei = bandEnergy(ear ? mi.right : mi.left, taps, fs, lo, hi);
        const double ej = bandEnergy(ear ? mj.right : mj.left, taps, fs, lo, hi);
        const double eg = bandEnergy(got, len, fs, lo, hi) * r * r;
        const double diff = energyToDb(eg) - energyToDb(0.5 * (ei + ej));
        worst = std::max(worst, std::fabs(diff));
        EXPECT_NEAR(diff, 0.0, 1.0) << "measurements " << i << ", " << j << " ear " << ear << " " << fc << " Hz";
      }
    }
    ++checked;
  }
  ::testing::Test::RecordProperty("worst_db", std::to_string(worst));
  std::printf("interpolated direct sound: worst third-octave deviation %.2f dB\n", worst);
  EXPECT_GE(checked, 20);
}

TEST(BinauralIr, BadInputsAreErrors) {
  auto pulse = model(kPulse);
  ASSERT_TRUE(pulse);
  ListenerOrientation parallel{{0, 0, -1}, {0, 0, 2}};
  EXPECT_FALSE(validate(parallel).isOk());
  ListenerOrientation zero{{0, 0, 0}, {0, 1, 0}};
  EXPECT_FALSE(validate(zero).isOk());
  ListenerOrientation nan{{0, std::nan(""), -1}, {0, 1, 0}};
  EXPECT_FALSE(validate(nan).isOk());
  IrSynthesisSettings s;
  EXPECT_FALSE(synthesizeBinauralIr({}, nullptr, s, *pulse, parallel).isOk());
  s.sampleRateHz = 44100;  // the model is at 48 kHz
  auto wrongRate = synthesizeBinauralIr({}, nullptr, s, *pulse, {});
  ASSERT_FALSE(wrongRate.isOk());
  EXPECT_NE(wrongRate.status().message().find("44100"), std::string::npos) << wrongRate.status().message();
  auto missing = loadBinauralModel("/nonexistent/set.sofa", 48000.0);
  ASSERT_FALSE(missing.isOk());
  EXPECT_NE(missing.status().message().find("/nonexistent/set.sofa"), std::string::npos);
}

}  // namespace earshot
