#pragma once
// Internal DSP for HRIR preparation: a radix-2 FFT, minimum phase and the
// onset (excess phase delay) estimator. See hrir_dsp.cpp for methods and
// references; resampling is earshot/dsp/resample.h.
#include <complex>
#include <cstddef>
#include <vector>

#include "earshot/dsp/resample.h"

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

// The Kaiser-windowed sinc, band-limited interpolation and resampling live in
// the dsp module (earshot/dsp/resample.h); these names keep the HRIR code's
// spelling.
using ::earshot::interpolateAt;
using ::earshot::resampleShifted;
using ::earshot::SincKernel;

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
