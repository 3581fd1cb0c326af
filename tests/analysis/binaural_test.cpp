// Known-answer tests of the binaural cues (ITD, ILD, IACC) on synthetic
// two-channel IRs whose answer follows from how they were made.
#include "earshot/analysis/binaural.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

namespace earshot::analysis {
namespace {

constexpr double kFs = 48000.0;
constexpr double kPi = 3.14159265358979323846;

// Adds a band-limited click: a Ricker wavelet (second derivative of a
// Gaussian, no DC, spectrum peak at 1 / (sqrt(2) pi sigma) = 2.7 kHz for
// sigma = 4 samples at 48 kHz; -100 dB at Nyquist) centred at the fractional
// sample `center`. Sampling the continuous wavelet at shifted times is an
// exact fractional delay (no interpolation involved).
double ricker(double u) { return (1.0 - u * u) * std::exp(-0.5 * u * u); }
constexpr double kClickSigma = 4.0;

void addClick(std::vector<float>& x, double center, double amplitude) {
  for (size_t i = 0; i < x.size(); ++i) {
    const double u = (double(i) - center) / kClickSigma;
    if (std::abs(u) < 12.0) x[i] += float(amplitude * ricker(u));
  }
}

AudioBuffer clickPair(double rateHz, double leftAt, double rightAt, double rightGain, size_t frames = 4800) {
  AudioBuffer a(2, frames, rateHz);
  addClick(a.channels[0], leftAt, 1.0);
  addClick(a.channels[1], rightAt, rightGain);
  return a;
}

// White Gaussian noise from frame `start` on.
std::vector<float> whiteNoise(size_t frames, size_t start, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 0.3);
  std::vector<float> x(frames, 0.0f);
  for (size_t i = start; i < frames; ++i) x[i] = float(g(rng));
  return x;
}

// Shot noise that can be delayed by any fraction of a sample exactly: one
// Gaussian pulse (sigma 1 sample, -43 dB at Nyquist) per sample on average at
// uniformly random continuous times in [start, frames), random amplitudes,
// all shifted by `delaySamples`.
std::vector<float> shotNoise(size_t frames, size_t start, uint32_t seed, double delaySamples) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> when{double(start), double(frames)};
  std::normal_distribution<double> g(0.0, 0.3);
  std::vector<float> x(frames, 0.0f);
  for (size_t k = start; k < frames; ++k) {
    const double t = when(rng) + delaySamples, a = g(rng);
    const long lo = std::max(0L, long(std::ceil(t - 8))), hi = std::min(long(frames) - 1, long(std::floor(t + 8)));
    for (long i = lo; i <= hi; ++i) x[size_t(i)] += float(a * std::exp(-0.5 * (double(i) - t) * (double(i) - t)));
  }
  return x;
}

std::vector<float> delayed(const std::vector<float>& x, size_t samples) {
  std::vector<float> y(x.size(), 0.0f);
  for (size_t i = samples; i < x.size(); ++i) y[i] = x[i - samples];
  return y;
}

AudioBuffer pair(const std::vector<float>& left, const std::vector<float>& right, double rateHz = kFs) {
  AudioBuffer a;
  a.sampleRateHz = rateHz;
  a.channels = {left, right};
  return a;
}

// --- Theory for the IACC of noise --------------------------------------------
// Power response of the zero-phase octave filter (octave_filter.h: the
// squared response of 4th-order Butterworth high- and low-pass on the
// pre-warped axis, cut-offs widened by (sqrt 2 - 1)^(1/8)); 1 for broadband.
double octavePower(double fc, double f, double rateHz) {
  if (fc == 0.0) return 1.0;
  auto w = [&](double hz) { return std::tan(kPi * hz / rateHz); };
  const double k = std::pow(std::sqrt(2.0) - 1.0, 1.0 / 8);
  const double whp = w(fc / std::sqrt(2.0)) * k, wlp = w(fc * std::sqrt(2.0)) / k, wf = w(f);
  const double mag = 1.0 / (1.0 + std::pow(whp / wf, 8)) / (1.0 + std::pow(wf / wlp, 8));
  return mag * mag;
}

// White noise through the band: its normalised autocorrelation rho(tau) =
// int S cos(2 pi f tau) df / int S df and its statistical bandwidth
// (int S)^2 / int S^2 (Hz), by the midpoint rule on a fine grid.
struct BandNoiseTheory {
  double fc, rateHz;
  std::vector<double> f, s;
  double sum = 0.0, sum2 = 0.0;
  BandNoiseTheory(double centerHz, double rate) : fc(centerHz), rateHz(rate) {
    const double lo = fc == 0.0 ? 0.0 : fc / 8, hi = fc == 0.0 ? rate / 2 : std::min(rate / 2, fc * 8);
    const int n = 2000;
    for (int i = 0; i < n; ++i) {
      f.push_back(lo + (hi - lo) * (i + 0.5) / n);
      s.push_back(octavePower(fc, f.back(), rate));
      sum += s.back();
      sum2 += s.back() * s.back();
    }
    bandwidthHz = sum * sum / sum2 * (hi - lo) / n;
  }
  double bandwidthHz = 0.0;
  double rho(double tauS) const {
    double r = 0.0;
    for (size_t i = 0; i < f.size(); ++i) r += s[i] * std::cos(2 * kPi * f[i] * tauS);
    return r / sum;
  }
  // Largest |rho| for tau in [from, to] (0.2-sample steps: at most 2 % low
  // at the 8 kHz band's upper edge, 11.3 kHz at 48 kHz).
  double maxAbsRho(double fromS, double toS) const {
    double m = 0.0;
    for (double t = fromS; t <= toS; t += 0.2 / rateHz) m = std::max(m, std::abs(rho(t)));
    return m;
  }
  // Bound on the IACC of two independent such noises over a window of
  // `seconds`, exceeded with probability < 1e-6: the correlation at one lag
  // has variance 1 / (2 B T) (B the statistical bandwidth); the envelope of
  // a band-pass Gaussian process exceeds a with probability
  // exp(-a^2 / (2 sigma^2)) (Rayleigh; a Chernoff bound for the broadband
  // two-sided Gaussian too); union over 1 + 2 (2 maxLag) B independent lags.
  double independentBound(double seconds, double maxLagS = 0.001) const {
    const double sigma = 1.0 / std::sqrt(2.0 * bandwidthHz * seconds);
    const double lags = 1.0 + 4.0 * maxLagS * bandwidthHz;
    return sigma * std::sqrt(2.0 * std::log(lags / 1e-6));
  }
};

// --- Direct sound: ITD and ILD -----------------------------------------------

TEST(Binaural, FractionalDelayAndHalfAmplitudeGiveItdAndIld) {
  // Right = left delayed by 7.3 samples and scaled by 0.5: the source is on
  // the left, ITD = 7.3 / fs = 152.08 us, ILD = 20 log10(2) = 6.02 dB.
  auto r = analyzeBinaural(clickPair(kFs, 480.0, 487.3, 0.5));
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const double itd = 7.3 / kFs;
  EXPECT_NEAR(r->itdS, itd, 5e-6);
  EXPECT_NEAR(r->ildDb, 20 * std::log10(2.0), 0.05);
  EXPECT_FALSE(r->itdAtSearchLimit);
  EXPECT_GT(r->itdPeakCorrelation, 0.99);  // the same waveform in both ears
  // ISO onset: the first sample within 20 dB of the peak (the left click's
  // centre, amplitude 1): |ricker| >= 0.1 on its leading side lobe.
  size_t onset = 0;
  while (std::abs(ricker((double(onset) - 480.0) / kClickSigma)) < 0.1) ++onset;
  EXPECT_NEAR(r->onsetS, double(onset) / kFs, 1e-12);
  EXPECT_NEAR(r->directStartS, r->onsetS - 0.001, 1e-12);
  EXPECT_NEAR(r->directEndS, r->onsetS + 0.0025, 1e-12);
  std::printf("ITD error %.4f us, ILD error %.5f dB\n", (r->itdS - itd) * 1e6, r->ildDb - 20 * std::log10(2.0));
}

TEST(Binaural, SwappingTheEarsNegatesItdAndIld) {
  auto r = analyzeBinaural(clickPair(kFs, 480.0, 487.3, 0.5));
  ASSERT_TRUE(r.isOk());
  AudioBuffer swapped = clickPair(kFs, 480.0, 487.3, 0.5);
  std::swap(swapped.channels[0], swapped.channels[1]);
  auto w = analyzeBinaural(swapped);
  ASSERT_TRUE(w.isOk());
  EXPECT_NEAR(w->itdS, -r->itdS, 1e-9);
  EXPECT_NEAR(w->ildDb, -r->ildDb, 1e-9);
  EXPECT_LT(w->itdS, 0.0) << "the source is now on the right: the right ear leads";
}

TEST(Binaural, ItdResolvesEveryFractionOfASampleAt48And44kHz) {
  for (double fs : {48000.0, 44100.0}) {
    double worst = 0.0;
    for (double delay = -30.0; delay <= 30.0; delay += 1.37) {  // +-0.63 ms, every fraction visited
      auto r = analyzeBinaural(clickPair(fs, 480.0, 480.0 + delay, 0.7));
      ASSERT_TRUE(r.isOk()) << r.status().message();
      worst = std::max(worst, std::abs(r->itdS - delay / fs));
      EXPECT_NEAR(r->itdS, delay / fs, 5e-6) << fs << " Hz, delay " << delay;
      EXPECT_NEAR(r->ildDb, -20 * std::log10(0.7), 0.05);
    }
    std::printf("%.0f Hz: worst ITD error %.4f us\n", fs, worst * 1e6);
  }
}

TEST(Binaural, BelowThreeKilohertzTheItdNeedsNoLowPass) {
  // At 3 kHz the 1.5 kHz low-pass would sit at Nyquist: the window is used
  // as is, and the fractional delay still comes out (2.3 samples, 767 us).
  // The window is widened to hold the click (+-48 samples = +-16 ms here).
  const double fs = 3000.0;
  BinauralAnalysisSettings s;
  s.directBeforeS = 0.020;
  s.directAfterS = 0.040;
  auto r = analyzeBinaural(clickPair(fs, 100.0, 102.3, 0.5, 3000), s);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_NEAR(r->itdS, 2.3 / fs, 5e-6);
  EXPECT_NEAR(r->ildDb, 20 * std::log10(2.0), 0.05);
}

TEST(Binaural, ItdBeyondTheSearchRangeIsFlaggedAtItsLimit) {
  // Gaussian pulses (sigma 8 samples: a correlation without side lobes) 1.2
  // ms apart: no head is that wide; the correlation still rises at +1 ms, so
  // the maximum sits on the limit and says so.
  AudioBuffer a(2, 4800, kFs);
  for (size_t i = 0; i < a.frameCount(); ++i) {
    const double u = (double(i) - 480.0) / 8.0, v = (double(i) - 480.0 - 0.0012 * kFs) / 8.0;
    a.channels[0][i] = float(std::exp(-0.5 * u * u));
    a.channels[1][i] = float(std::exp(-0.5 * v * v));
  }
  auto r = analyzeBinaural(a);
  ASSERT_TRUE(r.isOk());
  EXPECT_TRUE(r->itdAtSearchLimit);
  EXPECT_NEAR(std::abs(r->itdS), 0.001, 1e-9);
}

// --- IACC ----------------------------------------------------------------------

TEST(Binaural, IdenticalNoiseInBothEarsGivesIaccOneInEveryBand) {
  const auto x = whiteNoise(size_t(1.0 * kFs), 480, 5);
  auto r = analyzeBinaural(pair(x, x));
  ASSERT_TRUE(r.isOk()) << r.status().message();
  for (const IaccBand& b : r->iacc) {
    EXPECT_NEAR(b.early, 1.0, 1e-9) << b.bandCenterHz << " Hz " << b.earlyReason;
    EXPECT_NEAR(b.late, 1.0, 1e-9) << b.bandCenterHz << " Hz " << b.lateReason;
    EXPECT_NEAR(b.lateLagS, 0.0, 1e-3 / kFs);
  }
  EXPECT_NEAR(r->iaccE3, 1.0, 1e-9);
  EXPECT_NEAR(r->iaccL3, 1.0, 1e-9);
  EXPECT_NEAR(r->itdS, 0.0, 1e-3 / kFs);
  EXPECT_NEAR(r->ildDb, 0.0, 1e-12);
}

TEST(Binaural, IndependentNoisesGiveIaccWithinTheStatisticalBound) {
  const size_t n = size_t(3.0 * kFs), start = 480;
  auto r = analyzeBinaural(pair(whiteNoise(n, start, 1), whiteNoise(n, start, 2)));
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const double lateS = double(n) / kFs - r->onsetS - 0.080;
  for (int b = 0; b < kAnalysisBandCount; ++b) {
    const IaccBand& band = r->iacc[size_t(b)];
    const BandNoiseTheory theory(band.bandCenterHz, kFs);
    const double bound = theory.independentBound(lateS);
    std::printf("%6.0f Hz: IACC_L %.4f, bound %.4f (B %.0f Hz)\n", band.bandCenterHz, band.late, bound,
                theory.bandwidthHz);
    EXPECT_LT(band.late, bound) << band.bandCenterHz << " Hz";
    // The bound itself is small wherever the window holds enough of the
    // band's independent samples (all bands but 125 Hz in 2.9 s).
    if (band.bandCenterHz == 0.0 || band.bandCenterHz >= 250.0) {
      EXPECT_LT(bound, 0.2) << band.bandCenterHz;
    }
  }
  const BandNoiseTheory white(0.0, kFs);
  EXPECT_LT(r->iacc[kBroadbandIndex].early, white.independentBound(0.080));
}

TEST(Binaural, NoiseAndItsCopyHalfAMillisecondLaterGiveIaccNearOne) {
  // Within the +-1 ms lag range: the maximum finds the delay in every band.
  const auto x = whiteNoise(size_t(2.0 * kFs), 480, 7);
  auto r = analyzeBinaural(pair(x, delayed(x, 24)));  // 0.5 ms at 48 kHz
  ASSERT_TRUE(r.isOk()) << r.status().message();
  for (const IaccBand& b : r->iacc) {
    std::printf("%6.0f Hz: IACC_L %.5f at %.2f us\n", b.bandCenterHz, b.late, b.lateLagS * 1e6);
    EXPECT_GT(b.late, 0.99) << b.bandCenterHz << " Hz";
    EXPECT_NEAR(b.lateLagS, 0.0005, 1.0 / kFs) << b.bandCenterHz << " Hz";
  }
}

TEST(Binaural, FractionallyDelayedCopyKeepsIaccNearOneUpTo8kHz) {
  // 24.5 samples: an integer-lag search would miss the 8 kHz band's peak by
  // half a sample, cos(2 pi 8000 / 96000) = 0.87; the refinement finds it.
  const size_t n = size_t(1.5 * kFs);
  auto r = analyzeBinaural(pair(shotNoise(n, 480, 9, 0.0), shotNoise(n, 480, 9, 24.5)));
  ASSERT_TRUE(r.isOk()) << r.status().message();
  for (const IaccBand& b : r->iacc) {
    std::printf("%6.0f Hz: IACC_L %.5f at %.3f samples\n", b.bandCenterHz, b.late, b.lateLagS * kFs);
    EXPECT_GT(b.late, 0.99) << b.bandCenterHz << " Hz";
  }
}

TEST(Binaural, CopyTwoMillisecondsLaterIsOutsideTheLagRange) {
  // The true lag (2 ms) is outside +-1 ms, so the IACC is what the band's
  // own autocorrelation reaches over lags 1 .. 3 ms: near zero for the
  // broadband and high bands, large at 125 Hz (whose period is 8 ms), within
  // the estimation error of a finite window (the lag correlation's variance
  // is at most twice that of independent noises, Bartlett 1946).
  const size_t n = size_t(3.0 * kFs);
  const auto x = whiteNoise(n, 480, 11);
  auto r = analyzeBinaural(pair(x, delayed(x, 96)));
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const double lateS = double(n) / kFs - r->onsetS - 0.080;
  for (const IaccBand& b : r->iacc) {
    const BandNoiseTheory theory(b.bandCenterHz, kFs);
    const double expected = theory.maxAbsRho(0.001, 0.003);
    const double tolerance = std::sqrt(2.0) * theory.independentBound(lateS);
    std::printf("%6.0f Hz: IACC_L %.4f, expected %.4f +- %.4f\n", b.bandCenterHz, b.late, expected, tolerance);
    EXPECT_NEAR(b.late, expected, tolerance) << b.bandCenterHz << " Hz";
  }
}

TEST(Binaural, BandsAboveTheSampleRateLimitAreNaNWithAReason) {
  const double fs = 16000.0;  // 8 kHz octave (upper edge 11.3 kHz) unavailable
  const auto x = whiteNoise(size_t(0.5 * fs), 160, 3);
  auto r = analyzeBinaural(pair(x, x, fs));
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const IaccBand& top = r->iacc[kNumBands - 1];
  EXPECT_TRUE(std::isnan(top.early) && std::isnan(top.late));
  EXPECT_NE(top.lateReason.find("sample rate"), std::string::npos) << top.lateReason;
  EXPECT_NEAR(r->iacc[kNumBands - 2].late, 1.0, 1e-9);  // 4 kHz is fine
}

TEST(Binaural, AnAnechoicPairHasNoLateIacc) {
  // Two clicks and nothing after: the late window holds only the octave
  // filters' ringing (or nothing, broadband): n/a with a reason.
  auto r = analyzeBinaural(clickPair(kFs, 480.0, 490.0, 0.5, size_t(0.5 * kFs)));
  ASSERT_TRUE(r.isOk());
  for (const IaccBand& b : r->iacc) {
    EXPECT_TRUE(std::isnan(b.late)) << b.bandCenterHz << " Hz: " << b.late;
    EXPECT_FALSE(b.lateReason.empty());
    EXPECT_FALSE(std::isnan(b.early)) << b.bandCenterHz << " Hz: " << b.earlyReason;
  }
}

// --- Errors -------------------------------------------------------------------

TEST(Binaural, RejectsAnythingButTwoFiniteEqualChannels) {
  AudioBuffer mono(1, 1000, kFs);
  mono.channels[0][10] = 1.0f;
  auto one = analyzeBinaural(mono);
  ASSERT_FALSE(one.isOk());
  EXPECT_NE(one.status().message().find("exactly 2 channels"), std::string::npos) << one.status().message();

  AudioBuffer nan = clickPair(kFs, 480.0, 490.0, 0.5);
  nan.channels[1][17] = std::nanf("");
  auto n = analyzeBinaural(nan);
  ASSERT_FALSE(n.isOk());
  EXPECT_NE(n.status().message().find("right channel sample 17"), std::string::npos) << n.status().message();

  AudioBuffer ragged = clickPair(kFs, 480.0, 490.0, 0.5);
  ragged.channels[1].pop_back();
  EXPECT_FALSE(analyzeBinaural(ragged).isOk());

  auto silent = analyzeBinaural(AudioBuffer(2, 100, kFs));
  ASSERT_FALSE(silent.isOk());
  EXPECT_NE(silent.status().message().find("silent"), std::string::npos);

  BinauralAnalysisSettings bad;
  bad.maxLagS = 0.0;
  auto s = analyzeBinaural(clickPair(kFs, 480.0, 490.0, 0.5), bad);
  ASSERT_FALSE(s.isOk());
  EXPECT_NE(s.status().message().find("maxLagS"), std::string::npos) << s.status().message();
}

}  // namespace
}  // namespace earshot::analysis
