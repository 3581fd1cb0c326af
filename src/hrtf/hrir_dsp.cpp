// HRIR preparation numerics.
//
// Resampling and fractional interpolation: earshot/dsp/resample.h (a
// tabulated Kaiser-windowed sinc, shared with dry-audio loading).
//
// Onset (time-of-arrival) estimation: the lag that maximises the
// cross-correlation between an HRIR and its minimum-phase version, i.e. the
// linear part of its excess phase (J. Nam, M. A. Kolar and J. S. Abel, "On the
// minimum-phase nature of head-related transfer functions", AES 125th
// Convention, 2008; compared with threshold methods in B. F. G. Katz and
// M. Noisternig, "A comparative study of interaural time delay estimation
// methods", JASA 135(6), 2014). The minimum-phase version comes from the
// folded real cepstrum (Oppenheim & Schafer, Discrete-Time Signal Processing,
// ch. 13) on a 4x zero-padded FFT; the peak is refined to a fraction of a
// sample by golden-section search on the sinc-interpolated correlation. A
// unit pulse at sample k gives exactly k. The cross-spectrum is weighted by a
// Gaussian low-pass (see kOnsetLowpassHz in hrtf_set.cpp) so the estimate is
// the low-frequency excess-phase delay, the one that makes minimum phase plus
// delay perceptually transparent (Kulkarni, Isabelle & Colburn, JASA 105(5),
// 1999). The stored HRIRs are the minimum-phase versions (same cepstral
// method, applied after resampling).
#include "hrir_dsp.h"

#include <algorithm>
#include <cmath>

#include "earshot/core/math.h"

namespace earshot::hrtf::detail {

namespace {

std::size_t nextPow2(std::size_t n) {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

}  // namespace

Fft::Fft(std::size_t n) : mN(n), mTwiddle(n / 2), mBitReverse(n) {
  for (std::size_t k = 0; k < n / 2; ++k) mTwiddle[k] = std::polar(1.0, -2.0 * kPi * double(k) / double(n));
  int bits = 0;
  while ((std::size_t(1) << bits) < n) ++bits;
  for (std::size_t i = 0; i < n; ++i) {
    std::size_t r = 0;
    for (int b = 0; b < bits; ++b)
      if (i & (std::size_t(1) << b)) r |= std::size_t(1) << (bits - 1 - b);
    mBitReverse[i] = r;
  }
}

void Fft::run(std::vector<std::complex<double>>& x, bool inverse) const {
  for (std::size_t i = 0; i < mN; ++i)
    if (i < mBitReverse[i]) std::swap(x[i], x[mBitReverse[i]]);
  for (std::size_t len = 2; len <= mN; len <<= 1) {
    std::size_t half = len / 2, step = mN / len;
    for (std::size_t s = 0; s < mN; s += len) {
      for (std::size_t j = 0; j < half; ++j) {
        std::complex<double> w = mTwiddle[j * step];
        if (inverse) w = std::conj(w);
        std::complex<double> a = x[s + j], b = x[s + j + half] * w;
        x[s + j] = a + b;
        x[s + j + half] = a - b;
      }
    }
  }
}

void Fft::inverse(std::vector<std::complex<double>>& x) const {
  run(x, true);
  double s = 1.0 / double(mN);
  for (auto& v : x) v *= s;
}

// Folds a real cepstrum (length n, even) onto positive quefrencies: the
// cepstrum of the minimum-phase signal with the same magnitude.
static void foldToMinimumPhaseCepstrum(std::vector<std::complex<double>>& c) {
  const std::size_t n = c.size();
  for (std::size_t i = 1; i < n / 2; ++i) c[i] = 2.0 * c[i].real();
  c[0] = c[0].real();
  c[n / 2] = c[n / 2].real();
  for (std::size_t i = n / 2 + 1; i < n; ++i) c[i] = 0.0;
}


MinimumPhase::MinimumPhase(std::size_t irLength)
    : mLength(irLength), mFft(std::max<std::size_t>(256, 4 * nextPow2(irLength))), mWork(mFft.size()) {}

void MinimumPhase::compute(const float* x, float* out, std::size_t outLength) {
  const std::size_t n = mFft.size();
  std::fill(mWork.begin(), mWork.end(), std::complex<double>(0.0));
  for (std::size_t i = 0; i < mLength; ++i) mWork[i] = x[i];
  mFft.forward(mWork);
  double peak = 0.0;
  for (const auto& v : mWork) peak = std::max(peak, std::abs(v));
  if (!(peak > 0.0)) {
    std::fill(out, out + outLength, 0.0f);
    return;
  }
  const double floorMag = peak * 1e-5;  // -100 dB: keeps log finite at spectral zeros
  for (auto& v : mWork) v = std::log(std::max(std::abs(v), floorMag));
  mFft.inverse(mWork);
  foldToMinimumPhaseCepstrum(mWork);
  mFft.forward(mWork);
  for (auto& v : mWork) v = std::exp(v);
  mFft.inverse(mWork);
  for (std::size_t i = 0; i < outLength; ++i) out[i] = i < n ? static_cast<float>(mWork[i].real()) : 0.0f;
}

OnsetEstimator::OnsetEstimator(std::size_t irLength, double lowpassFraction)
    : mLength(irLength),
      mLowpassFraction(lowpassFraction),
      mFft(std::max<std::size_t>(256, 4 * nextPow2(irLength))),
      mSpec(mFft.size()),
      mWork(mFft.size()),
      mCorr(irLength + 2 * (SincKernel::kZeroCrossings + 2)) {}

double OnsetEstimator::onsetSamples(const float* x) {
  const std::size_t n = mFft.size();
  std::fill(mSpec.begin(), mSpec.end(), std::complex<double>(0.0));
  double energy = 0.0;
  for (std::size_t i = 0; i < mLength; ++i) {
    mSpec[i] = x[i];
    energy += double(x[i]) * x[i];
  }
  if (!(energy > 0.0)) return 0.0;
  mFft.forward(mSpec);

  // Real cepstrum of log|X|, with a floor 120 dB below the peak so that
  // spectral zeros do not produce -inf.
  double peak = 0.0;
  for (const auto& v : mSpec) peak = std::max(peak, std::abs(v));
  const double floorMag = peak * 1e-6;
  for (std::size_t i = 0; i < n; ++i) mWork[i] = std::log(std::max(std::abs(mSpec[i]), floorMag));
  mFft.inverse(mWork);
  foldToMinimumPhaseCepstrum(mWork);
  mFft.forward(mWork);
  // Cross-spectrum X * conj(Hmin) = |X|^2 e^{i(excess phase)}.
  // A Gaussian low-pass weight favours the low-frequency excess-phase delay,
  // which is stable where the high-frequency first arrival is ambiguous
  // (contralateral ear); it is symmetric, so a unit pulse still peaks exactly.
  const double lpFraction = mLowpassFraction;  // cutoff as a fraction of the sampling rate
  for (std::size_t i = 0; i < n; ++i) {
    double f = double(std::min(i, n - i)) / double(n);
    double wlp = lpFraction > 0.0 ? std::exp(-(f / lpFraction) * (f / lpFraction)) : 1.0;
    mWork[i] = wlp * mSpec[i] * std::conj(std::exp(mWork[i]));
  }
  mFft.inverse(mWork);

  // Correlation at lags -pad .. mLength + pad - 1 (circular indices).
  const long pad = SincKernel::kZeroCrossings + 2;
  for (std::size_t j = 0; j < mCorr.size(); ++j) {
    long lag = long(j) - pad;
    mCorr[j] = mWork[std::size_t((lag + long(n)) % long(n))].real();
  }
  // Integer peak over non-negative lags (the excess-phase delay is causal).
  std::size_t best = std::size_t(pad);
  for (std::size_t j = std::size_t(pad); j < std::size_t(pad) + mLength; ++j)
    if (mCorr[j] > mCorr[best]) best = j;
  // Golden-section search on the band-limited correlation around the peak.
  auto f = [&](double t) { return interpolateAt(mCorr.data(), mCorr.size(), t); };
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double a = double(best) - 1.0, b = double(best) + 1.0;
  double c = b - g * (b - a), d = a + g * (b - a);
  double fc = f(c), fd = f(d);
  for (int it = 0; it < 48; ++it) {
    if (fc > fd) {
      b = d; d = c; fd = fc;
      c = b - g * (b - a); fc = f(c);
    } else {
      a = c; c = d; fc = fd;
      d = a + g * (b - a); fd = f(d);
    }
  }
  double t = 0.5 * (a + b);
  // Keep the exact integer when it is at least as good (unit pulses).
  if (f(double(best)) >= f(t)) t = double(best);
  return t - double(pad);
}

}  // namespace earshot::hrtf::detail
