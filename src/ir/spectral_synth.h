#pragma once
// Internal: the frequency-domain synthesis shared by the omnidirectional and
// the binaural IR (ir_synthesis.cpp, binaural_synthesis.cpp). One FFT frame
// of n samples holds the IR plus a margin; discrete arrivals are added as
// exact fractional delays, late reflections as band-shaped noise, each
// optionally through a filter given on a coarse frequency grid (an HRTF or a
// diffuse-field filter) and interpolated to the frame's bins. With no filter
// the arithmetic is exactly the omnidirectional synthesis, so an identity
// HRTF gives the omni IR in both ears.
#include <kiss_fftr.h>

#include <complex>
#include <cstdint>
#include <memory>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/ir/ir_synthesis.h"

namespace earshot::detail {

struct FftrDeleter {
  void operator()(kiss_fftr_cfg c) const { kiss_fftr_free(c); }
};
using FftrPtr = std::unique_ptr<std::remove_pointer_t<kiss_fftr_cfg>, FftrDeleter>;

/** A filter sampled at k * fs / gridSize for k = 0 .. gridSize / 2
 *  (gridSize / 2 + 1 values), linearly interpolated in between. */
struct GridFilter {
  const std::complex<float>* values = nullptr;  ///< null: the identity filter
  size_t gridSize = 0;
};

class SpectralSynth {
 public:
  /** Plans an IR of `length` samples at `fs`; fails on FFT allocation. */
  static Result<SpectralSynth> create(size_t length, double fs);
  /** Validates the settings and arrivals (finite, delay >= 0) and plans the
   *  IR of irLengthSamples() samples (at most kMaxIrSamples). */
  static Result<SpectralSynth> plan(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                                    const IrSynthesisSettings& settings);

  size_t length() const { return mLength; }
  size_t bins() const { return mBins; }

  /** spectrum += gain * G_a(f) * H(f) * exp(-j 2 pi f delay), where G_a is the
   *  arrival's band gains through the complementary band weights. */
  void addArrival(const Arrival& a, double delaySeconds, const GridFilter& h, std::complex<double>* spectrum);

  /** Per band, white noise of (seed, stream) through sqrt(W_band), with its
   *  slow fluctuations of level taken out: divided by its RMS over a moving
   *  window of kLevelWindowCycles periods of the band's width, times the
   *  RMS it has on average. A noise realisation's level wanders (over the
   *  first 10 dB of a 1 s decay an octave band holds only B x 0.17 s degrees
   *  of freedom: EDT scattered by 2 JND at 250 Hz between seeds); levelled,
   *  the band carries the histogram's envelope much more closely, while its
   *  fine structure stays noise. Pass a band's noise to shapeBand and the
   *  result to addBand (whose second sqrt(W_band) completes
   *  W_band). At least length() samples per band; made for the
   *  power of two at or above length() and shared by every IR of that size
   *  class (the last few (seed, stream, size class) are cached: at most 6, 32 MB). */
  std::shared_ptr<const std::vector<std::vector<float>>> levelledBandNoise(uint64_t seed, uint64_t stream) const;

  /** shaped[i] = noise[(i + offset) mod noise.size()] * sqrt(density_band(i)
   *  * gain(bin of i)), the density the histogram's energy per sample,
   *  linear between bin centres; gainPerHistogramBin may be null (1). The
   *  noise is periodic (levelledBandNoise), so any offset reads a stationary
   *  stretch of it. Returns false if all zero. */
  bool shapeBand(const std::vector<float>& noise, size_t offset, const EnergyHistogram& h, int band,
                 const float* gainPerHistogramBin, std::vector<float>& shaped) const;

  /** spectrum += sqrt(W_band(f)) * H(f) * FFT(shaped): shaped is a band's
   *  levelledBandNoise (through sqrt(W_band) already) after shapeBand, n
   *  samples (the tail beyond length() zero). */
  void addBand(int band, const std::vector<float>& shaped, const GridFilter& h, std::complex<double>* spectrum);

  /** A zeroed spectrum of bins() values. */
  std::vector<std::complex<double>> emptySpectrum() const { return std::vector<std::complex<double>>(mBins, 0.0); }

  /** The first length() samples of the inverse transform of `spectrum`. */
  void inverse(std::vector<std::complex<double>>& spectrum, std::vector<float>& out);

  /** Buffer for shapeBand (n samples). */
  std::vector<float> shapedBuffer() const { return std::vector<float>(mN, 0.0f); }

 private:
  std::complex<double> filterAt(const GridFilter& h, size_t k) const;
  void prepareGrid(size_t gridSize);  // bin -> grid position table for one grid size

  double mFs = 48000.0;
  size_t mLength = 0, mN = 0, mBins = 0;
  FftrPtr mForward, mInverse;
  std::vector<std::vector<float>> mSqrtWeights;  // [band][bin]: sqrt of the complementary band weights
  std::vector<uint8_t> mLowerBand;           // per bin: the lower of the (at most two) non-zero bands
  std::vector<double> mLowerWeight;
  std::vector<kiss_fft_cpx> mScratch;
  size_t mGridSize = 0;
  std::vector<uint32_t> mGridIndex;  // per bin: the grid point below
  std::vector<double> mGridFrac;     // per bin: position between it and the next
};

/** The offset into a noise of `period` samples that IrSynthesisSettings'
 *  seed and noiseKey give (0 for key 0). */
size_t noiseOffset(uint64_t seed, uint64_t noiseKey, size_t period);

/** `count` samples of white Gaussian noise (unit variance). */
std::vector<float> whiteNoise(uint64_t seed, uint64_t stream, size_t count);

/** Noise stream of the late reflections. The binaural path's first noise (U)
 *  uses it too, so an identity HRTF reproduces the omni IR of the same seed. */
constexpr uint64_t kLateNoiseStream = 0x1F2E3D4CULL;
/** The binaural path's second, independent noise (V). */
constexpr uint64_t kLateNoiseStreamIndependent = 0x5A6B7C8DULL;

/** Window of levelledBandNoise: periods of the band's width (an octave band
 *  at f is 0.71 f wide): 45 ms at 125 Hz, 5.6 ms at 1 kHz. */
constexpr double kLevelWindowCycles = 4.0;

/** IRs longer than this are refused (10 minutes at 48 kHz). */
constexpr size_t kMaxIrSamples = size_t(48000) * 600;

/** Smallest even n >= minimum with only factors 2, 3, 5 (fast for KissFFT). */
size_t fastFftSize(size_t minimum);

}  // namespace earshot::detail
