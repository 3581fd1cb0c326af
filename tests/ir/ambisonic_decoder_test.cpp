// The binaural decoder of ambisonic signals (issue 15): a decoded plane wave
// against the HRTF of its direction, a decoded diffuse field against the
// head's diffuse-field coherence.
#include "earshot/ir/ambisonic_decoder.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>

#include "earshot/core/math.h"
#include "earshot/hrtf/coordinates.h"
#include "earshot/ir/spherical_harmonics.h"

namespace earshot {
namespace {

const std::string kKu100 = std::string(EARSHOT_SOURCE_DIR) + "/hrtf/FHK_HRIR_L2354.sofa";

std::shared_ptr<const BinauralModel> ku100() {
  static auto m = loadBinauralModel(kKu100, 48000.0);
  EXPECT_TRUE(m.isOk()) << m.status().message();
  return m.isOk() ? *m : nullptr;
}

// Energy of x in the octave around fc (direct DFT at 10 Hz steps).
double octaveEnergy(const std::vector<float>& x, double fs, double fc) {
  double e = 0;
  for (double f = fc / std::sqrt(2.0); f < fc * std::sqrt(2.0); f += 10.0) {
    std::complex<double> acc = 0;
    const std::complex<double> step = std::polar(1.0, -2.0 * kPi * f / fs);
    std::complex<double> p = 1;
    for (float v : x) {
      acc += double(v) * p;
      p *= step;
    }
    e += std::norm(acc);
  }
  return e;
}

// ILD (dB) per octave 250 Hz - 4 kHz of a decoded plane wave against the
// HRTF's, over directions around the horizon and above; the mean error of
// each order falls with the order.
TEST(AmbisonicDecoder, DecodedPlaneWavesKeepTheHrtfsInterauralLevels) {
  auto model = ku100();
  ASSERT_TRUE(model);
  const double fs = 48000;
  const double centres[] = {250, 500, 1000, 2000, 4000};
  double meanError[4] = {};
  for (int order = 1; order <= 3; ++order) {
    AmbisonicDecoderSettings s;
    s.order = order;
    auto dec = AmbisonicDecoder::create(*model, s);
    ASSERT_TRUE(dec.isOk()) << dec.status().message();
    int count = 0;
    double worst = 0;
    for (int az = 0; az < 360; az += 30)
      for (int el : {0, 30}) {
        const Vec3d head = hrtf::sofaAnglesToHeadDirection(az, el);
        const Vec3d amb(hrtf::headToSofa(head));
        double yv[16];
        realSphericalHarmonics(amb, order, yv);
        AudioBuffer in(size_t((order + 1) * (order + 1)), 1, fs);
        for (int c = 0; c < (order + 1) * (order + 1); ++c) in.channels[size_t(c)][0] = float(yv[c]);
        auto ears = (*dec)->decode(in);
        ASSERT_TRUE(ears.isOk());
        hrtf::HrirPair ref;
        model->hrtf().lookup(Vec3f(head), ref);
        const std::vector<float> refL(ref.left.begin(), ref.left.begin() + long(ref.length)),
            refR(ref.right.begin(), ref.right.begin() + long(ref.length));
        for (double fc : centres) {
          const double ild = 10 * std::log10(octaveEnergy(ears->channels[0], fs, fc) /
                                             octaveEnergy(ears->channels[1], fs, fc));
          const double want = 10 * std::log10(octaveEnergy(refL, fs, fc) / octaveEnergy(refR, fs, fc));
          meanError[order] += std::fabs(ild - want);
          worst = std::max(worst, std::fabs(ild - want));
          ++count;
        }
      }
    meanError[order] /= count;
    std::printf("order %d: ILD error mean %.2f dB, worst %.2f dB\n", order, meanError[order], worst);
  }
  EXPECT_LT(meanError[3], meanError[1]);
  EXPECT_LT(meanError[3], 2.0);
}

// A diffuse field (independent noise per channel, SN3D energy 1/(2n+1))
// decodes to two ears whose per-octave coherence is the head's
// diffuse-field coherence (the covariance constraint; without it a
// first-order decoder gives 0.3 at 2 and 4 kHz where the head gives 0).
TEST(AmbisonicDecoder, DiffuseFieldDecodesToTheHeadsCoherence) {
  auto model = ku100();
  ASSERT_TRUE(model);
  const double fs = 48000;
  const size_t n = size_t(fs);  // 1 s of noise
  std::mt19937_64 rng(7);
  std::normal_distribution<float> g;
  AudioBuffer in(16, n, fs);
  for (int c = 0; c < 16; ++c)
    for (float& v : in.channels[size_t(c)]) v = g(rng) * float(std::sqrt(1.0 / (2 * ambisonicOrderOf(c) + 1)));
  // Target coherence per octave from the model's diffuse-field spectra.
  const size_t grid = model->gridSize();
  auto coherence = [&](double fc) {
    std::complex<double> x = 0;
    double pl = 0, pr = 0;
    for (size_t k = 0; k <= grid / 2; ++k) {
      const double f = double(k) * fs / double(grid);
      if (f < fc / std::sqrt(2.0) || f >= fc * std::sqrt(2.0)) continue;
      x += model->diffuseCrossSpectrum()[k];
      pl += model->diffusePower(0)[k];
      pr += model->diffusePower(1)[k];
    }
    return x.real() / std::sqrt(pl * pr);
  };
  auto measured = [&](const AudioBuffer& ears, double fc) {
    // Real part of the octave's normalised cross-spectrum, by DFT of 4096-sample frames.
    std::complex<double> x = 0;
    double pl = 0, pr = 0;
    const size_t frame = 4096;
    for (size_t start = 0; start + frame <= n; start += frame)
      for (double f = fc / std::sqrt(2.0); f < fc * std::sqrt(2.0); f += fs / frame) {
        std::complex<double> a = 0, b = 0, p = 1;
        const std::complex<double> step = std::polar(1.0, -2.0 * kPi * f / fs);
        for (size_t i = 0; i < frame; ++i) {
          a += double(ears.channels[0][start + i]) * p;
          b += double(ears.channels[1][start + i]) * p;
          p *= step;
        }
        x += a * std::conj(b);
        pl += std::norm(a);
        pr += std::norm(b);
      }
    return x.real() / std::sqrt(pl * pr);
  };
  for (int order : {1, 3}) {
    AmbisonicDecoderSettings s;
    s.order = order;
    auto dec = AmbisonicDecoder::create(*model, s);
    ASSERT_TRUE(dec.isOk());
    AudioBuffer sub(size_t((order + 1) * (order + 1)), 0, fs);
    for (size_t c = 0; c < sub.channelCount(); ++c) sub.channels[c] = in.channels[c];
    auto ears = (*dec)->decode(sub);
    ASSERT_TRUE(ears.isOk());
    for (double fc : {500.0, 1000.0, 2000.0, 4000.0}) {
      const double want = coherence(fc), got = measured(*ears, fc);
      std::printf("order %d %5.0f Hz: coherence %.3f (head %.3f)\n", order, fc, got, want);
      EXPECT_NEAR(got, want, 0.1) << "order " << order << " at " << fc << " Hz";
    }
  }
}

TEST(AmbisonicDecoder, RefusesBadSettings) {
  auto model = ku100();
  ASSERT_TRUE(model);
  AmbisonicDecoderSettings s;
  s.order = 4;
  EXPECT_FALSE(AmbisonicDecoder::create(*model, s).isOk());
  s.order = 1;
  s.taps = 300;
  EXPECT_FALSE(AmbisonicDecoder::create(*model, s).isOk());
  s.taps = 512;
  s.alignedAboveHz = std::nan("");
  EXPECT_FALSE(AmbisonicDecoder::create(*model, s).isOk());
  s.alignedAboveHz = 1500;
  auto dec = AmbisonicDecoder::create(*model, s);
  ASSERT_TRUE(dec.isOk());
  EXPECT_FALSE((*dec)->decode(AudioBuffer(9, 10, 48000)).isOk());
}

}  // namespace
}  // namespace earshot
