// SpectralSynth::addWeightedArrivals (src/ir/spectral_synth.h): every
// arrival into every channel's spectrum a block of bins at a time gives the
// sums of addArrival into one spectrum, added to each channel with its
// weight, arrival by arrival (what the ambisonic synthesis did before).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "spectral_synth.h"

namespace earshot::detail {
namespace {

TEST(SpectralSynth, WeightedArrivalsEqualArrivalByArrivalSums) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Arrival> arrivals(40);
  for (size_t i = 0; i < arrivals.size(); ++i) {
    Arrival& a = arrivals[i];
    a.delaySeconds = 0.002 + 0.12 * u(rng);
    a.gain = i == 5 ? 0.0 : 0.05 + u(rng);  // one silent arrival: skipped by both
    for (int b = 0; b < kNumBands; ++b) a.bandGain[size_t(b)] = u(rng);
  }
  constexpr size_t kChannels = 5;
  std::vector<float> weights(arrivals.size() * kChannels);
  for (size_t i = 0; i < weights.size(); ++i) weights[i] = i % 7 == 3 ? 0.0f : float(2 * u(rng) - 1);
  auto synth = SpectralSynth::create(48000 / 4, 48000.0, 48000 / 8);
  ASSERT_TRUE(synth.isOk());
  SpectralSynth& plan = synth.value();
  ASSERT_GT(plan.bins(), 1000u);  // many blocks of bins, and a last partial one

  std::vector<Spectrum> expected(kChannels, plan.emptySpectrum());
  Spectrum one = plan.emptySpectrum();
  for (size_t i = 0; i < arrivals.size(); ++i) {
    one = plan.emptySpectrum();
    plan.addArrival(arrivals[i], arrivals[i].delaySeconds, {}, one);
    for (size_t c = 0; c < kChannels; ++c)
      for (size_t k = 0; k < plan.bins(); ++k) {
        expected[c].re[k] += weights[i * kChannels + c] * one.re[k];
        expected[c].im[k] += weights[i * kChannels + c] * one.im[k];
      }
  }
  std::vector<Spectrum> got(kChannels, plan.emptySpectrum());
  plan.addWeightedArrivals(arrivals, weights.data(), kChannels, got.data());

  for (size_t c = 0; c < kChannels; ++c) {
    double err = 0, ref = 0;
    for (size_t k = 0; k < plan.bins(); ++k) {
      err = std::max(err, double(std::hypot(got[c].re[k] - expected[c].re[k], got[c].im[k] - expected[c].im[k])));
      ref = std::max(ref, double(std::hypot(expected[c].re[k], expected[c].im[k])));
    }
    EXPECT_GT(ref, 0.1) << "channel " << c;
    // Float rounding only (a fused multiply-add where the compiler makes one): measured 1.6e-7 to 2.1e-7.
    EXPECT_LT(err, 1e-6 * ref) << "channel " << c;
    EXPECT_EQ(got[c].im[plan.bins() - 1], 0.0f) << "the Nyquist bin stays real";
  }
}

}  // namespace
}  // namespace earshot::detail
