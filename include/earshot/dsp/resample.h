#pragma once
/** @file Band-limited sample-rate conversion and fractional interpolation of
 *  whole signals with a tabulated Kaiser-windowed sinc (J. O. Smith and
 *  P. Gossett, "A flexible sampling-rate conversion method", ICASSP 1984;
 *  Kaiser & Schafer 1980 for the window). 32 zero crossings per side, Kaiser
 *  beta 9 (about -90 dB stop band); when downsampling the sinc is stretched
 *  to a cutoff of 0.95 * fsOut / 2. The filter is linear- (zero-) phase: no
 *  delay is added. Not for the audio thread (per-sample cost ~64-70 taps,
 *  no state between calls). */
#include <cstddef>
#include <vector>

namespace earshot {

/** Kaiser-windowed sinc, tabulated: value(x) = sinc(x) * kaiser(x / kZeroCrossings)
 *  for |x| < kZeroCrossings (x in zero-crossing units), 0 outside; linear
 *  interpolation between kPhases table entries per zero crossing.
 *  Threading: instance() is built once (thread-safe static); value() is const. */
class SincKernel {
 public:
  static constexpr int kZeroCrossings = 32;
  static constexpr int kPhases = 512;   ///< table entries per zero crossing
  static constexpr double kBeta = 9.0;  ///< Kaiser beta: ~ -90 dB stop band
  /** Cutoff, as a fraction of the output Nyquist frequency, when downsampling. */
  static constexpr double kDownsampleCutoff = 0.95;
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

/** Band-limited value of the sequence x (length n, zero outside) at the
 *  fractional index t (sinc interpolation, no low-pass beyond Nyquist).
 *  Threading: pure function. */
double interpolateAt(const float* x, std::size_t n, double t);
double interpolateAt(const double* x, std::size_t n, double t);

/** Resamples x (length n, rate fsIn Hz) to rate fsOut Hz, shifted so that input
 *  time `startIn` (in input samples, fractional) lands on output sample 0:
 *  out[m] = g * lowpass(x)(m * fsIn / fsOut + startIn) for m < outLength, x
 *  taken as zero outside [0, n). The gain g = kappa * fsIn / fsOut (kappa the
 *  cutoff stretch) keeps the frequency response of a filter (taps scale with
 *  the rate ratio): use it for impulse responses.
 *  fsIn, fsOut > 0. Threading: pure function. */
void resampleShifted(const float* x, std::size_t n, double fsIn, double fsOut, double startIn, float* out,
                     std::size_t outLength);

/** Number of output samples resample() gives for n input samples:
 *  round(n * fsOut / fsIn) (the same duration). */
std::size_t resampledLength(std::size_t n, double fsIn, double fsOut);

/** Resamples a whole signal (libsoxr, very high quality, linear phase: 8.6x
 *  faster than this file's sinc for 60 s at 44.1 -> 48 kHz, the two agreeing
 *  to 114 dB below the signal) (length n at fsIn Hz) to fsOut Hz keeping its
 *  amplitude (a 0 dBFS sine below the cutoff stays 0 dBFS): output sample m
 *  is the band-limited signal at time m / fsOut, resampledLength(n, fsIn,
 *  fsOut) samples (edges: x is zero outside [0, n)). Equal rates copy x.
 *  fsIn, fsOut > 0 and finite. Threading: pure function; allocates. */
std::vector<float> resample(const float* x, std::size_t n, double fsIn, double fsOut);

}  // namespace earshot
