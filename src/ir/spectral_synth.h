#pragma once
// Internal: the synthesis shared by the omnidirectional and the binaural IR
// (ir_synthesis.cpp, binaural_synthesis.cpp). Discrete arrivals are added as
// exact fractional delays in one FFT frame that covers them (not the whole
// IR: the early part plus margins), optionally through a filter given on a
// coarse frequency grid (an HRTF) interpolated to the frame's bins. Late
// reflections are made in the time domain: per band, a periodic noise that
// has been through its band filters and the channel's filter once per
// (seed, filter) and cached (finishedBandNoise), times the square root of the
// histogram's energy density (bandEnvelope, addEnvelopedNoise). With no filter the arithmetic
// is exactly the omnidirectional synthesis, so an identity HRTF gives the
// omni IR in both ears.
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

/** A real signal's spectrum (bins 0 .. n / 2), real and imaginary parts apart. */
struct Spectrum {
  std::vector<float> re, im;
};

class SpectralSynth {
 public:
  /** Plans an IR of `length` samples at `fs` whose arrivals all lie before
   *  sample `arrivalsEnd` (their filters' onset and length included); fails
   *  on FFT allocation. */
  static Result<SpectralSynth> create(size_t length, double fs, size_t arrivalsEnd, double bandShiftOctaves = 0.0);
  /** Validates the settings and arrivals (finite, delay >= 0) and plans the
   *  IR of irLengthSamples() samples (at most kMaxIrSamples). */
  static Result<SpectralSynth> plan(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                                    const IrSynthesisSettings& settings);

  size_t length() const { return mLength; }
  /** The period of this IR's band noises (finishedBandNoise's band size). */
  size_t noisePeriod() const;
  /** About what synthesising this IR into `channels` channels holds, in
   *  bytes (an estimate from above): per sample, the output and a copy of
   *  it, the band envelopes and late-field buffers; per sample of the
   *  noise period, `noises` band-noise sets (levelled and finished, every
   *  band) and their FFT work. Measured (`earshot ir --length 60`, the
   *  process's peak RSS without a noise cache): omni at 384 kHz 5.2 GB
   *  against 5.5 GB here, ambisonic order 3 (16 channels) at 384 kHz 7.3
   *  GB against 8.3 GB, at 48 kHz 0.96 GB against 1.03 GB. */
  double memoryBytes(size_t channels, size_t noises) const;
  /** kOutOfRange (before anything is allocated) when memoryBytes() passes
   *  defaultInputLimits().maxMemoryBytes (earshot/io/input_file.h). */
  Status checkMemory(size_t channels, size_t noises) const;
  size_t bins() const { return mBins; }
  /** Samples of the arrivals' frame that reach the IR (from 0). */
  size_t arrivalSamples() const { return mKeep; }

  /** spectrum += gain * G_a(f) * H(f) * exp(-j 2 pi f delay), where G_a is the
   *  arrival's band gains through the complementary band weights. */
  void addArrival(const Arrival& a, double delaySeconds, const GridFilter& h, Spectrum& spectrum);
  /** spectra[c] += weights[i * channels + c] x (arrival i's addArrival with
   *  no filter, at its own delay), for every arrival i and channel c < channels.
   *  The sums of addArrival into one spectrum and its weighted adds into each
   *  channel, arrival by arrival, but a block of bins at a time for all
   *  arrivals: the channels' spectra pass through the cache once, not once
   *  per arrival. */
  void addWeightedArrivals(const std::vector<Arrival>& arrivals, const float* weights, size_t channels,
                           Spectrum* spectra);

  /** Per band, white noise of (seed, stream) through sqrt(W_band), with its
   *  slow fluctuations of level taken out: divided by its RMS over a moving
   *  window of kLevelWindowCycles periods of the band's width, times the
   *  RMS it has on average. A noise realisation's level wanders (over the
   *  first 10 dB of a 1 s decay an octave band holds only B x 0.17 s degrees
   *  of freedom: EDT scattered by 2 JND at 250 Hz between seeds); levelled,
   *  the band carries the histogram's envelope much more closely, while its
   *  fine structure stays noise. finishedBandNoise applies the second
   *  sqrt(W_band) (completing W_band). At least length() samples per band; made for the
   *  power of two at or above length() and shared by every IR of that size
   *  class (the last few (seed, stream, size class) are cached: at most 6, 32 MB). */
  std::shared_ptr<const std::vector<std::vector<float>>> levelledBandNoise(uint64_t seed, uint64_t stream) const;

  /** The band's amplitude envelope over the IR's length() samples: the
   *  square root of the histogram's energy per sample (times
   *  gainPerHistogramBin, which may be null), linear between bin centres and
   *  smoothed as energy over ~3 periods of the band's centre (the .cpp says
   *  why). Returns false if all zero. */
  bool bandEnvelope(const EnergyHistogram& h, int band, const float* gainPerHistogramBin, std::vector<float>& env) const;

  /** Per band, levelledBandNoise(seed, stream) through the second
   *  sqrt(W_band) and the filter h, circularly (still periodic and
   *  stationary). `filterKey` names h for the cache (0: the identity; a
   *  model's filters: BinauralModel::id() with the filter's index), so each
   *  (seed, stream, size class, filter) is filtered once per process; at most
   *  48 kept (an order-3 ambisonic IR reads 16 noises: 101 MB for
   *  3 s IRs, and IRs of two size classes alternate as a room's decay
   *  changes), 128 MB. */
  std::shared_ptr<const std::vector<std::vector<float>>> finishedBandNoise(uint64_t seed, uint64_t stream,
                                                                           const GridFilter& h,
                                                                           uint64_t filterKey) const;

  /** finishedBandNoise for several (filter, key) at once: the levelled
   *  noise's band spectra are computed once for all of them. */
  std::vector<std::shared_ptr<const std::vector<std::vector<float>>>> finishedBandNoises(
      uint64_t seed, uint64_t stream, const std::vector<std::pair<GridFilter, uint64_t>>& filters) const;

 private:
  // What the code makes of a fixed short noise, hashed: part of the disk
  // cache's key, so that entries of other numerics are never read.
  static uint64_t noiseFingerprint();
  // finishedBandNoises' work for filters[missing[k]], k in order, from the
  // disk cache where it holds them (see the .cpp), else made (and written).
  std::vector<std::shared_ptr<std::vector<std::vector<float>>>> cachedOrMadeBandNoises(
      uint64_t seed, uint64_t stream, const std::vector<std::pair<GridFilter, uint64_t>>& filters,
      const std::vector<size_t>& missing) const;
  // finishedBandNoises' work for filters[missing[k]], k in order (no cache).
  std::vector<std::shared_ptr<std::vector<std::vector<float>>>> makeFinishedBandNoises(
      uint64_t seed, uint64_t stream, const std::vector<std::pair<GridFilter, uint64_t>>& filters,
      const std::vector<size_t>& missing) const;

 public:

  /** out[i] += noise[(i + offset) mod noise.size()] * env[i] for i <
   *  min(length(), count): a finishedBandNoise band under its bandEnvelope,
   *  added into the IR. The noise is periodic, so any offset reads a
   *  stationary stretch of it. */
  void addEnvelopedNoise(const std::vector<float>& noise, size_t offset, const std::vector<float>& env, float* out,
                         size_t count = SIZE_MAX) const;
  /** addEnvelopedNoise of a, then of b, under one envelope, in one pass
   *  over out and env: the same bits as the two calls. */
  void addEnvelopedNoises(const std::vector<float>& a, const std::vector<float>& b, size_t offset,
                          const std::vector<float>& env, float* out, size_t count = SIZE_MAX) const;

  /** A zeroed spectrum of bins() values. */
  Spectrum emptySpectrum() const { return Spectrum{std::vector<float>(mBins, 0.0f), std::vector<float>(mBins, 0.0f)}; }

  /** The IR's length() samples: the inverse transform of `spectrum` over
   *  arrivalSamples(), zero after. */
  void inverse(const Spectrum& spectrum, std::vector<float>& out);


 private:
  void prepareGrid(size_t gridSize);  // bin -> grid position table for one grid size

  // |f_b(t)|^2 of band b's noise filter sqrt(W_b) in cells of q samples,
  // centred, normalised (cached per band, q and rate).
  const std::vector<double>& energyResponse(int band, size_t q) const;

  double mFs = 48000.0;
  // The rate at which the engine's octave bands fall where this IR's bands
  // are: fs x 2^-(IrSynthesisSettings::bandShiftOctaves). Every band
  // computation (weights, filters' responses, the noises' levelling) reads
  // it instead of mFs, and the caches are keyed by it: a band noise depends
  // on the rate only through its bands.
  double mBandFs = 48000.0;
  size_t mLength = 0, mN = 0, mBins = 0, mKeep = 0;
  std::shared_ptr<std::remove_pointer_t<kiss_fftr_cfg>> mInverse;  // a plan for mN, lent while this lives (inversePlan)
  // Per bin of an mN-point FFT at mFs, shared by the IRs of that size
  // (bandWeights costs logs per bin): the lower of the (at most two)
  // non-zero bands, its weight, and the first bin after the bin's run of
  // bins with the same lower band.
  struct BandTable {
    std::vector<uint8_t> lowerBand;
    std::vector<float> lowerWeight;
    std::vector<uint32_t> runEnd;
  };
  std::shared_ptr<const BandTable> mBands;
  static std::shared_ptr<const BandTable> bandTable(size_t n, double fs);
  std::vector<kiss_fft_cpx> mScratch;
  size_t mGridSize = 0;
  std::vector<uint32_t> mGridIndex;  // per bin: the grid point below
  std::vector<float> mGridFrac;      // per bin: position between it and the next
  std::vector<uint32_t> mGridRunEnd;  // per bin: the first bin after its run of bins with the same grid point
};

/** `count` float buffers of the calling thread for an IR's temporaries
 *  (band envelopes, late fields), lent for the scope and reused by the
 *  thread's next IR: a fresh buffer of a 2 s IR (384 KB) is mapped and
 *  zeroed by the kernel as it is first written (~0.2 ms; an ambisonic
 *  IR's seven band envelopes were a sixth of its synthesis). Their size
 *  and contents are what the last user left: resize and write them. A
 *  buffer of over kKeptFloats is released when the scope ends. Scopes
 *  nest (each takes the next buffers); not shared between threads. */
class ThreadScratch {
 public:
  explicit ThreadScratch(size_t count);
  ~ThreadScratch();
  ThreadScratch(const ThreadScratch&) = delete;
  ThreadScratch& operator=(const ThreadScratch&) = delete;
  std::vector<float>& operator[](size_t i);

  // 4 MB: a 21 s IR at 48 kHz (an ambisonic IR uses 14 buffers: at most
  // 56 MB a thread are kept).
  static constexpr size_t kKeptFloats = size_t(1) << 20;

 private:
  size_t mBase = 0, mCount = 0;
};

/** bandEnvelope's samples from its grid: env[m q + k] = amp[m] + (amp[m + 1]
 *  - amp[m]) (k / q) for m q + k < length (amp[m] where q is 1); amp holds
 *  length / q + 2 points. */
void expandEnvelope(const float* amp, size_t q, size_t length, float* env);

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

/** Two reads of one band noise at least this far apart are as independent
 *  as two noises: band noise is uncorrelated beyond ~11 ms (measured: every
 *  band's |r| <= 0.06 from a lag of 512 samples at 48 kHz, the estimate's
 *  own floor over a 2.7 s period). The ambisonic channels read W's noise
 *  so, where the period allows. */
constexpr double kMinNoiseSpacingSeconds = 0.05;

/** Window of levelledBandNoise: periods of the band's width (an octave band
 *  at f is 0.71 f wide): 45 ms at 125 Hz, 5.6 ms at 1 kHz. */
constexpr double kLevelWindowCycles = 4.0;

/** What an arrival's filter may add to its delay in the arrivals' frame: an
 *  HRIR's onset and length (20 ms: 960 taps at 48 kHz). */
constexpr double kArrivalSlackSeconds = 0.02;

/** IRs longer than this are refused (10 minutes at 48 kHz). */
constexpr size_t kMaxIrSamples = size_t(48000) * 600;

/** Smallest even n >= minimum with only factors 2, 3, 5 (fast for KissFFT). */
size_t fastFftSize(size_t minimum);

}  // namespace earshot::detail
