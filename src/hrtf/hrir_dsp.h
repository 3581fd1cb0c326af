#pragma once
// Internal DSP for HRIR preparation: a radix-2 FFT, a Kaiser-windowed sinc
// kernel (resampling and band-limited interpolation) and the onset (excess
// phase delay) estimator. See hrir_dsp.cpp for methods and references.
#include <complex>
#include <cstddef>
#include <vector>

namespace earshot::hrtf::detail {

/** In-place iterative radix-2 FFT of a power-of-two length; inverse includes 1/N. */
class Fft {
 public:
  explicit Fft(std::size_t n);
  std::size_t size() const { return mN; }
  void forward(std::vector<std::complex<double>>& x) const { run(x, false); }
  void inverse(std::vector<std::complex<double>>& x) const;

 private:
  void run(std::vector<std::complex<double>>& x, bool inverse) const;
  std::size_t mN;
  std::vector<std::complex<double>> mTwiddle;  // e^{-2 pi i k / N}, k < N/2
  std::vector<std::size_t> mBitReverse;
};

/** Kaiser-windowed sinc, tabulated: value(x) = sinc(x) * kaiser(x / kZeroCrossings)
 *  for |x| < kZeroCrossings (x in zero-crossing units), 0 outside. */
class SincKernel {
 public:
  static constexpr int kZeroCrossings = 32;
  static constexpr int kPhases = 512;  // table entries per zero crossing
  static constexpr double kBeta = 9.0; // Kaiser beta: ~ -90 dB stop band
  SincKernel();
  double value(double x) const {
    double a = x < 0 ? -x : x;
    if (a >= kZeroCrossings) return 0.0;
    double p = a * kPhases;
    auto i = static_cast<std::size_t>(p);
    double f = p - double(i);
    return mTable[i] + f * (mTable[i + 1] - mTable[i]);
  }
  static const SincKernel& instance();

 private:
  std::vector<double> mTable;
};

/** Band-limited value of the sequence x at fractional index t (sinc interpolation). */
double interpolateAt(const float* x, std::size_t n, double t);
double interpolateAt(const double* x, std::size_t n, double t);

/** Resamples the HRIR x (length n, rate fsIn) to rate fsOut, shifted so that
 *  input time `startIn` (in input samples, fractional) lands on output tap 0:
 *  out[m] = g * lowpass(x)((m * fsIn / fsOut) + startIn). The gain g keeps the
 *  filter's frequency response (taps scale with fsIn / fsOut). */
void resampleShifted(const float* x, std::size_t n, double fsIn, double fsOut, double startIn, float* out,
                     std::size_t outLength);

/** Minimum-phase version of an impulse response with the same magnitude
 *  response (folded real cepstrum). Reusable scratch; not thread-safe. */
class MinimumPhase {
 public:
  explicit MinimumPhase(std::size_t irLength);
  /** x has irLength taps; writes outLength (<= FFT size) taps to out. */
  void compute(const float* x, float* out, std::size_t outLength);

 private:
  std::size_t mLength;
  Fft mFft;
  std::vector<std::complex<double>> mWork;
};

/** Onset of an impulse response in (fractional) samples: the lag maximising the
 *  cross-correlation of x with its minimum-phase version. Reusable scratch. */
class OnsetEstimator {
 public:
  /** @param lowpassFraction Gaussian weight cutoff / sampling rate (0 = none). */
  OnsetEstimator(std::size_t irLength, double lowpassFraction);
  double onsetSamples(const float* x);

 private:
  std::size_t mLength;
  double mLowpassFraction;
  Fft mFft;
  std::vector<std::complex<double>> mSpec, mWork;
  std::vector<double> mCorr;
};

}  // namespace earshot::hrtf::detail
