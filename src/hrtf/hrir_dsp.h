#pragma once
// Internal DSP for HRIR preparation: a radix-2 FFT, minimum phase and the
// onset (excess phase delay) estimator, each working on the two ears of a
// measurement at once. See hrir_dsp.cpp for methods and references;
// resampling is earshot/dsp/resample.h.
#include <cstddef>
#include <vector>

#include "earshot/dsp/resample.h"

namespace earshot::hrtf::detail {

/** In-place iterative radix-2 complex FFT of a power-of-two length on split
 *  real/imaginary arrays (double); the inverse includes 1/N. Twiddles are
 *  computed once, stored per stage contiguously. Const methods: thread-safe. */
class Fft {
 public:
  explicit Fft(std::size_t n);
  std::size_t size() const { return mN; }
  void forward(double* re, double* im) const { run<false>(re, im); }
  void inverse(double* re, double* im) const;

 private:
  template <bool kInverse>
  void run(double* re, double* im) const;
  std::size_t mN;
  // Stage with half-length h (h = 1, 2, 4, ... N/2) uses entries [h - 1, 2h - 1):
  // e^{-2 pi i j / (2h)}, j < h.
  std::vector<double> mTwRe, mTwIm;
  std::vector<std::size_t> mBitReverse;
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
