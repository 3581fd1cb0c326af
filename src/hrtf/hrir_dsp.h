#pragma once
// Internal DSP for HRIR preparation: a radix-2 FFT, minimum phase and the
// onset (excess phase delay) estimator, each working on the two ears of a
// measurement at once. See hrir_dsp.cpp for methods and references;
// resampling is earshot/dsp/resample.h.
#include <cstddef>
#include <vector>

#include <kissfft/kissfft.hh>

#include "earshot/dsp/resample.h"

namespace earshot::hrtf::detail {

/** In-place complex FFT (double) on split real/imaginary arrays, through
 *  KissFFT's C++ template (kissfft.hh, Debian's libkissfft-dev); the
 *  inverse includes 1/N. Const methods: thread-safe (scratch per call). */
class Fft {
 public:
  explicit Fft(std::size_t n);
  std::size_t size() const { return mN; }
  void forward(double* re, double* im) const { transform(mForward, re, im); }
  void inverse(double* re, double* im) const;

 private:
  void transform(const kissfft<double>& plan, double* re, double* im) const;
  std::size_t mN;
  kissfft<double> mForward, mInverse;
};

// The Kaiser-windowed sinc, band-limited interpolation and resampling live in
// the dsp module (earshot/dsp/resample.h); these names keep the HRIR code's
// spelling.
using ::earshot::interpolateAt;
using ::earshot::resampleShifted;
using ::earshot::SincKernel;

/** Minimum-phase versions of two impulse responses (one measurement's two
 *  ears) with the same magnitude responses (folded real cepstrum), both in
 *  one complex FFT. Reusable scratch; not thread-safe. */
class MinimumPhase {
 public:
  explicit MinimumPhase(std::size_t irLength);
  /** a, b have irLength taps; writes outLength (<= FFT size) taps to outA, outB.
   *  An all-zero input gives zeros. */
  void computePair(const float* a, const float* b, float* outA, float* outB, std::size_t outLength);

 private:
  std::size_t mLength;
  Fft mFft;
  std::vector<double> mRe, mIm;
  std::vector<double> mLogA, mLogB;  // squared magnitude, then log magnitude, bins 0..N/2
};

/** Onsets of two impulse responses in (fractional) samples: for each, the lag
 *  maximising the cross-correlation of x with its minimum-phase version.
 *  Reusable scratch; not thread-safe. */
class OnsetEstimator {
 public:
  /** @param lowpassFraction Gaussian weight cutoff / sampling rate (0 = none). */
  OnsetEstimator(std::size_t irLength, double lowpassFraction);
  /** a, b have irLength taps. An all-zero input has onset 0. */
  void onsetPair(const float* a, const float* b, double* onsetA, double* onsetB);

 private:
  // Golden-section peak of the band-limited correlation (circular, FFT length).
  double peakLag(const double* circular);
  std::size_t mLength;
  Fft mFft;
  std::vector<double> mWeight;  // Gaussian low-pass weight per bin k <= N/2
  std::vector<double> mRe, mIm;
  std::vector<double> mSpecA, mSpecB;  // spectra, bins 0..N/2, (re, im) interleaved
  std::vector<double> mLogA, mLogB;    // squared magnitude, then log magnitude, bins 0..N/2
  std::vector<double> mCorr;
};

}  // namespace earshot::hrtf::detail
