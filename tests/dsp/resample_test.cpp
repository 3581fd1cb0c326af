// Known answers for whole-signal resampling (earshot/dsp/resample.h): sines
// keep their frequency and amplitude in the passband, content above the
// output Nyquist frequency is rejected, and a band-limited signal survives a
// round trip.
#include "earshot/dsp/resample.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "earshot/core/math.h"

namespace earshot {
namespace {

std::vector<float> sine(double hz, double rateHz, double seconds, double amplitude = 1.0) {
  std::vector<float> v(size_t(std::llround(seconds * rateHz)));
  for (size_t i = 0; i < v.size(); ++i) v[i] = float(amplitude * std::sin(2.0 * kPi * hz * double(i) / rateHz));
  return v;
}

struct SineFit {
  double amplitude;    // of the least-squares sine at the given frequency
  double phase;        // radians, at sample 0
  double residualRms;  // what the fit leaves
};

// Least-squares fit of a*sin + b*cos at `hz` over samples [begin, end).
SineFit fitSine(const std::vector<float>& x, double hz, double rateHz, size_t begin, size_t end) {
  double ss = 0, cc = 0, sc = 0, xs = 0, xc = 0;
  for (size_t i = begin; i < end; ++i) {
    double w = 2.0 * kPi * hz * double(i) / rateHz;
    double s = std::sin(w), c = std::cos(w);
    ss += s * s; cc += c * c; sc += s * c; xs += x[i] * s; xc += x[i] * c;
  }
  double det = ss * cc - sc * sc;
  double a = (xs * cc - xc * sc) / det, b = (xc * ss - xs * sc) / det;
  double r = 0;
  for (size_t i = begin; i < end; ++i) {
    double w = 2.0 * kPi * hz * double(i) / rateHz;
    double e = x[i] - (a * std::sin(w) + b * std::cos(w));
    r += e * e;
  }
  return {std::hypot(a, b), std::atan2(b, a), std::sqrt(r / double(end - begin))};
}

// Rate conversion of a sine: the output is the same sine (frequency, phase,
// amplitude) sampled at the new rate. Edges (within the kernel's reach of
// the signal's ends) are left out.
void expectSameSine(double hz, double fsIn, double fsOut, double toleranceDb) {
  const double seconds = 0.25;
  auto in = sine(hz, fsIn, seconds);
  auto out = resample(in.data(), in.size(), fsIn, fsOut);
  ASSERT_EQ(out.size(), resampledLength(in.size(), fsIn, fsOut));
  ASSERT_EQ(out.size(), size_t(std::llround(seconds * fsOut)));
  const size_t edge = size_t(0.01 * fsOut);
  SineFit f = fitSine(out, hz, fsOut, edge, out.size() - edge);
  EXPECT_NEAR(gainToDb(f.amplitude), 0.0, toleranceDb) << hz << " Hz, " << fsIn << " -> " << fsOut;
  EXPECT_NEAR(f.phase, 0.0, 1e-4) << hz << " Hz: no delay";
  // A wrong frequency would leave most of the signal in the residual.
  EXPECT_LT(f.residualRms, 1e-4) << hz << " Hz, " << fsIn << " -> " << fsOut;
}

TEST(Resample, OneKilohertzSine44100To48000KeepsFrequencyAndAmplitude) {
  expectSameSine(1000.0, 44100.0, 48000.0, 0.01);
}

TEST(Resample, PassbandIsFlatWithinOneHundredthDb) {
  for (double hz : {50.0, 440.0, 5000.0, 12000.0, 18000.0}) expectSameSine(hz, 44100.0, 48000.0, 0.01);
  for (double hz : {50.0, 1000.0, 5000.0, 15000.0}) expectSameSine(hz, 48000.0, 44100.0, 0.01);
  for (double hz : {100.0, 1000.0, 3000.0}) expectSameSine(hz, 48000.0, 8000.0, 0.01);
}

TEST(Resample, RejectsContentAboveTheOutputNyquistFrequency) {
  // 6 kHz cannot exist at 8 kHz: it would alias to 2 kHz. It must vanish.
  auto in = sine(6000.0, 48000.0, 0.25);
  auto out = resample(in.data(), in.size(), 48000.0, 8000.0);
  const size_t edge = 80;
  double e = 0;
  for (size_t i = edge; i < out.size() - edge; ++i) e += double(out[i]) * out[i];
  double rms = std::sqrt(e / double(out.size() - 2 * edge));
  EXPECT_LT(gainToDb(rms * std::sqrt(2.0)), -80.0);
}

TEST(Resample, RoundTrip8000To48000To8000ReturnsTheSignal) {
  // Band-limited test signal: a few partials well inside 8 kHz's passband.
  const double fs = 8000.0;
  std::vector<float> x(4000);
  for (size_t i = 0; i < x.size(); ++i) {
    double t = double(i) / fs;
    x[i] = float(0.4 * std::sin(2 * kPi * 220.0 * t) + 0.3 * std::sin(2 * kPi * 1234.5 * t + 1.0) +
                 0.2 * std::sin(2 * kPi * 3100.0 * t + 2.0));
  }
  auto up = resample(x.data(), x.size(), fs, 48000.0);
  ASSERT_EQ(up.size(), 6 * x.size());
  auto back = resample(up.data(), up.size(), 48000.0, fs);
  ASSERT_EQ(back.size(), x.size());
  // Upsampling by an integer factor reproduces the input samples, away from
  // the ends by more than the filter's reach (libsoxr's very-high-quality
  // filter: 84 input samples here, measured; the signal is zero outside).
  for (size_t i = 100; i < x.size() - 100; i += 97) EXPECT_NEAR(up[6 * i], x[i], 1e-5) << i;
  double err = 0, ref = 0;
  for (size_t i = 100; i < x.size() - 100; ++i) {
    err += (double(back[i]) - x[i]) * (double(back[i]) - x[i]);
    ref += double(x[i]) * x[i];
  }
  EXPECT_LT(energyToDb(err / ref), -80.0);
}

TEST(Resample, EqualRatesCopyAndLengthsKeepTheDuration) {
  std::vector<float> x = {1.0f, -2.0f, 3.0f};
  EXPECT_EQ(resample(x.data(), x.size(), 44100.0, 44100.0), x);
  EXPECT_EQ(resampledLength(44100, 44100.0, 48000.0), 48000u);
  EXPECT_EQ(resampledLength(3, 44100.0, 48000.0), 3u);
  EXPECT_EQ(resampledLength(0, 44100.0, 48000.0), 0u);
  EXPECT_TRUE(resample(x.data(), 0, 44100.0, 48000.0).empty());
}

TEST(Resample, FilterTapsKeepTheirDcGain) {
  // resampleShifted scales taps by the rate ratio: the sum of an impulse
  // response's taps (its DC gain) is the same at both rates.
  std::vector<float> ir(64, 0.0f);
  ir[20] = 1.0f;
  ir[21] = 0.5f;
  std::vector<float> out(200);
  resampleShifted(ir.data(), ir.size(), 44100.0, 96000.0, 0.0, out.data(), out.size());
  double sum = 0;
  for (float v : out) sum += v;
  EXPECT_NEAR(sum, 1.5, 1e-3);
}

}  // namespace
}  // namespace earshot
