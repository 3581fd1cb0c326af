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
//
// Speed: a measurement's two ears go through one complex FFT (a + ib; the
// spectra of a and b are the Hermitian and anti-Hermitian parts), and every
// spectrum in the chain (log magnitude, folded cepstrum, minimum phase,
// cross-spectrum) is Hermitian, so logs and exponentials are taken on bins
// 0..N/2 only and mirrored (two real sequences in one complex FFT: W. H.
// Press et al., Numerical Recipes, 3rd ed., section 12.3). Same values as one
// ear at a time up to double rounding.
#include "hrir_dsp.h"

#include <algorithm>
#include <cmath>
#include <complex>

#include "earshot/core/math.h"

namespace earshot::hrtf::detail {

namespace {

std::size_t nextPow2(std::size_t n) {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

// FFT length for an impulse response of `irLength` taps: 4x zero padding, at least 256.
std::size_t paddedFftLength(std::size_t irLength) { return std::max<std::size_t>(256, 4 * nextPow2(irLength)); }

// Loads a (real part) and b (imaginary part), zero-padded to the FFT length.
void loadPair(const float* a, const float* b, std::size_t length, std::vector<double>& re, std::vector<double>& im) {
  std::fill(re.begin(), re.end(), 0.0);
  std::fill(im.begin(), im.end(), 0.0);
  for (std::size_t i = 0; i < length; ++i) {
    re[i] = a[i];
    im[i] = b[i];
  }
}

// Z = A + iB with A, B the spectra of two real sequences: A[k] = (Z[k] +
// conj(Z[N-k])) / 2, B[k] = (Z[k] - conj(Z[N-k])) / 2i.
struct Split {
  double ar, ai, br, bi;
};
inline Split split(const double* re, const double* im, std::size_t k, std::size_t n) {
  const std::size_t m = (n - k) & (n - 1);
  return {0.5 * (re[k] + re[m]), 0.5 * (im[k] - im[m]), 0.5 * (im[k] + im[m]), 0.5 * (re[m] - re[k])};
}

// Writes Z = A + iB for all bins from Hermitian A, B given on bins 0..N/2
// (A[N-k] = conj(A[k])); bins k and N-k may be written in any order.
inline void joinHermitian(double* re, double* im, std::size_t k, std::size_t n, double ar, double ai, double br,
                          double bi) {
  re[k] = ar - bi;
  im[k] = ai + br;
  if (k != 0 && 2 * k != n) {
    re[n - k] = ar + bi;
    im[n - k] = br - ai;
  }
}

// Folds the real cepstra in re and im (length n, even) onto positive
// quefrencies: the cepstra of the minimum-phase signals with the same magnitude.
void foldToMinimumPhaseCepstrum(std::vector<double>& re, std::vector<double>& im) {
  const std::size_t n = re.size();
  for (std::size_t i = 1; i < n / 2; ++i) {
    re[i] *= 2.0;
    im[i] *= 2.0;
  }
  for (std::size_t i = n / 2 + 1; i < n; ++i) re[i] = im[i] = 0.0;
}

// e^z for z = (r, i).
inline std::complex<double> expOf(double r, double i) {
  const double m = std::exp(r);
  return {m * std::cos(i), m * std::sin(i)};
}

}  // namespace

Fft::Fft(std::size_t n) : mN(n), mForward(n, false), mInverse(n, true) {}

namespace {

void minimumPhaseLogSpectra(const Fft& fft, std::vector<double>& re, std::vector<double>& im,
                            std::vector<double>& logA, std::vector<double>& logB, double peakA, double peakB,
                            bool liveA, bool liveB, double floorRatio) {
  const std::size_t n = fft.size(), half = n / 2;
  const double floorA = peakA * floorRatio, floorB = peakB * floorRatio;
  for (std::size_t k = 0; k <= half; ++k) {
    logA[k] = liveA ? 0.5 * std::log(std::max(logA[k], floorA)) : 0.0;
    logB[k] = liveB ? 0.5 * std::log(std::max(logB[k], floorB)) : 0.0;
    joinHermitian(re.data(), im.data(), k, n, logA[k], 0.0, logB[k], 0.0);
  }
  fft.inverse(re.data(), im.data());
  foldToMinimumPhaseCepstrum(re, im);
  fft.forward(re.data(), im.data());
}

}  // namespace

void Fft::transform(const kissfft<double>& plan, double* re, double* im) const {
  // KissFFT works on interleaved complex numbers; the callers keep split
  // arrays (two real signals packed as one complex FFT).
  std::vector<std::complex<double>> in(mN), out(mN);
  for (std::size_t i = 0; i < mN; ++i) in[i] = {re[i], im[i]};
  plan.transform(in.data(), out.data());
  for (std::size_t i = 0; i < mN; ++i) {
    re[i] = out[i].real();
    im[i] = out[i].imag();
  }
}

void Fft::inverse(double* re, double* im) const {
  transform(mInverse, re, im);
  const double s = 1.0 / double(mN);
  for (std::size_t i = 0; i < mN; ++i) {
    re[i] *= s;
    im[i] *= s;
  }
}

MinimumPhase::MinimumPhase(std::size_t irLength)
    : mLength(irLength),
      mFft(paddedFftLength(irLength)),
      mRe(mFft.size()),
      mIm(mFft.size()),
      mLogA(mFft.size() / 2 + 1),
      mLogB(mFft.size() / 2 + 1) {}

void MinimumPhase::computePair(const float* a, const float* b, float* outA, float* outB, std::size_t outLength) {
  const std::size_t n = mFft.size(), half = n / 2;
  loadPair(a, b, mLength, mRe, mIm);
  mFft.forward(mRe.data(), mIm.data());
  // Squared magnitudes of both spectra (bins 0..N/2) and their peaks.
  double peakA = 0.0, peakB = 0.0;
  for (std::size_t k = 0; k <= half; ++k) {
    const Split z = split(mRe.data(), mIm.data(), k, n);
    mLogA[k] = z.ar * z.ar + z.ai * z.ai;
    mLogB[k] = z.br * z.br + z.bi * z.bi;
    peakA = std::max(peakA, mLogA[k]);
    peakB = std::max(peakB, mLogB[k]);
  }
  const bool liveA = peakA > 0.0, liveB = peakB > 0.0;
  // Floor 100 dB below the peak.
  minimumPhaseLogSpectra(mFft, mRe, mIm, mLogA, mLogB, peakA, peakB, liveA, liveB, 1e-10);
  // Minimum-phase spectra exp(FFT(folded cepstrum)), Hermitian like the cepstra are real.
  for (std::size_t k = 0; k <= half; ++k) {
    const Split z = split(mRe.data(), mIm.data(), k, n);
    const std::complex<double> ea = expOf(z.ar, z.ai), eb = expOf(z.br, z.bi);
    joinHermitian(mRe.data(), mIm.data(), k, n, ea.real(), ea.imag(), eb.real(), eb.imag());
  }
  mFft.inverse(mRe.data(), mIm.data());
  for (std::size_t i = 0; i < outLength; ++i) {
    outA[i] = liveA && i < n ? static_cast<float>(mRe[i]) : 0.0f;
    outB[i] = liveB && i < n ? static_cast<float>(mIm[i]) : 0.0f;
  }
}

OnsetEstimator::OnsetEstimator(std::size_t irLength, double lowpassFraction)
    : mLength(irLength),
      mFft(paddedFftLength(irLength)),
      mWeight(mFft.size() / 2 + 1),
      mRe(mFft.size()),
      mIm(mFft.size()),
      mSpecA(2 * (mFft.size() / 2 + 1)),
      mSpecB(2 * (mFft.size() / 2 + 1)),
      mLogA(mFft.size() / 2 + 1),
      mLogB(mFft.size() / 2 + 1),
      mCorr(irLength + 2 * (SincKernel::kZeroCrossings + 2)) {
  // A Gaussian low-pass weight favours the low-frequency excess-phase delay,
  // which is stable where the high-frequency first arrival is ambiguous
  // (contralateral ear); it is symmetric, so a unit pulse still peaks exactly.
  for (std::size_t k = 0; k < mWeight.size(); ++k) {
    const double f = double(k) / double(mFft.size());
    mWeight[k] = lowpassFraction > 0.0 ? std::exp(-(f / lowpassFraction) * (f / lowpassFraction)) : 1.0;
  }
}

void OnsetEstimator::onsetPair(const float* a, const float* b, double* onsetA, double* onsetB) {
  const std::size_t n = mFft.size(), half = n / 2;
  double energyA = 0.0, energyB = 0.0;
  for (std::size_t i = 0; i < mLength; ++i) {
    energyA += double(a[i]) * a[i];
    energyB += double(b[i]) * b[i];
  }
  loadPair(a, b, mLength, mRe, mIm);
  mFft.forward(mRe.data(), mIm.data());
  double peakA = 0.0, peakB = 0.0;
  for (std::size_t k = 0; k <= half; ++k) {
    const Split z = split(mRe.data(), mIm.data(), k, n);
    mSpecA[2 * k] = z.ar;
    mSpecA[2 * k + 1] = z.ai;
    mSpecB[2 * k] = z.br;
    mSpecB[2 * k + 1] = z.bi;
    mLogA[k] = z.ar * z.ar + z.ai * z.ai;
    mLogB[k] = z.br * z.br + z.bi * z.bi;
    peakA = std::max(peakA, mLogA[k]);
    peakB = std::max(peakB, mLogB[k]);
  }
  const bool liveA = energyA > 0.0 && peakA > 0.0, liveB = energyB > 0.0 && peakB > 0.0;

  // log Hmin from the real cepstrum of log|X|, floor 120 dB below the peak.
  minimumPhaseLogSpectra(mFft, mRe, mIm, mLogA, mLogB, peakA, peakB, liveA, liveB, 1e-12);
  // Cross-spectra w X conj(Hmin) = w |X|^2 e^{i(excess phase)}, Gaussian-weighted.
  for (std::size_t k = 0; k <= half; ++k) {
    const Split z = split(mRe.data(), mIm.data(), k, n);
    const std::complex<double> ha = expOf(z.ar, z.ai), hb = expOf(z.br, z.bi);
    const double w = mWeight[k];
    const double xar = w * mSpecA[2 * k], xai = w * mSpecA[2 * k + 1];
    const double xbr = w * mSpecB[2 * k], xbi = w * mSpecB[2 * k + 1];
    joinHermitian(mRe.data(), mIm.data(), k, n, xar * ha.real() + xai * ha.imag(), xai * ha.real() - xar * ha.imag(),
                  xbr * hb.real() + xbi * hb.imag(), xbi * hb.real() - xbr * hb.imag());
  }
  mFft.inverse(mRe.data(), mIm.data());
  *onsetA = liveA ? peakLag(mRe.data()) : 0.0;
  *onsetB = liveB ? peakLag(mIm.data()) : 0.0;
}

double OnsetEstimator::peakLag(const double* circular) {
  const std::size_t n = mFft.size();
  // Correlation at lags -pad .. mLength + pad - 1 (circular indices).
  const long pad = SincKernel::kZeroCrossings + 2;
  for (std::size_t j = 0; j < mCorr.size(); ++j) {
    long lag = long(j) - pad;
    mCorr[j] = circular[std::size_t((lag + long(n)) % long(n))];
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
