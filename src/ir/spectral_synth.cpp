// Frequency-domain IR synthesis shared by the omni and binaural paths: see
// spectral_synth.h and ir_synthesis.h for the method.
#include "spectral_synth.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <iterator>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <thread>
#include <tuple>

#include "earshot/core/math.h"
#include "earshot/core/random.h"
#include "earshot/core/target_clones.h"
#include "earshot/core/thread_runs.h"
#include "earshot/dsp/fir.h"
#include "earshot/io/disk_cache.h"
#include "earshot/io/input_file.h"
#include "earshot/ir/band_filter_bank.h"

namespace earshot::detail {

namespace {
// Samples appended beyond the IR before the circular FFT, so that what the
// zero-phase band filters spread before time 0 (the 125 Hz band's response
// lasts ~0.1 s each way) wraps into the margin and not onto the IR's end, and
// the direct sound's sinc tail stays below 1 / (pi * margin).
constexpr double kMarginSeconds = 0.35;
}  // namespace

size_t fastFftSize(size_t minimum) {
  size_t best = size_t(1) << 62;
  for (size_t p2 = 2; p2 < 2 * minimum + 2; p2 *= 2)
    for (size_t p3 = p2; p3 < 2 * minimum + 2; p3 *= 3)
      for (size_t p5 = p3; p5 < 2 * minimum + 2; p5 *= 5)
        if (p5 >= minimum && p5 < best) best = p5;
  return best;
}

namespace {
// Real FFT plans (forward or inverse) by size. A KissFFT plan holds scratch,
// so each is lent to one user at a time and comes back when its last
// reference goes; the most recently returned few are kept for the next
// user, whatever its thread (a noise's helper thread is new each time):
// making one costs a sincos per bin, a large part of a short IR's synthesis
// and ~5 ms for a 2 s IR's noise period.
using Plan = std::shared_ptr<std::remove_pointer_t<kiss_fftr_cfg>>;
struct PlanPool {
  std::mutex mutex;
  std::vector<std::pair<size_t, kiss_fftr_cfg>> idle;  // most recent first; key 2n + inverse
};
PlanPool& planPool() {
  static PlanPool* pool = new PlanPool;  // never destroyed: plans may come back during static destruction
  return *pool;
}
constexpr size_t kIdlePlans = 8;
Plan realPlan(size_t n, bool inverse) {
  const size_t key = 2 * n + (inverse ? 1 : 0);
  PlanPool& pool = planPool();
  auto giveBack = [key](kiss_fftr_cfg cfg) {
    PlanPool& p = planPool();
    kiss_fftr_cfg dropped = nullptr;
    {
      std::lock_guard<std::mutex> lock(p.mutex);
      try {
        p.idle.insert(p.idle.begin(), {key, cfg});
      } catch (...) {
        dropped = cfg;  // no room to keep it
      }
      if (p.idle.size() > kIdlePlans) {
        dropped = p.idle.back().second;
        p.idle.pop_back();
      }
    }
    if (dropped) kiss_fftr_free(dropped);
  };
  {
    std::lock_guard<std::mutex> lock(pool.mutex);
    for (size_t i = 0; i < pool.idle.size(); ++i)
      if (pool.idle[i].first == key) {
        kiss_fftr_cfg cfg = pool.idle[i].second;
        pool.idle.erase(pool.idle.begin() + std::ptrdiff_t(i));
        return Plan(cfg, giveBack);
      }
  }
  kiss_fftr_cfg cfg = kiss_fftr_alloc(int(n), inverse ? 1 : 0, nullptr, nullptr);
  if (!cfg) return Plan();
  return Plan(cfg, giveBack);
}
Plan inversePlan(size_t n) { return realPlan(n, true); }

// body(b0, b1) for the bands [0, kNumBands) in two runs (forRuns: the
// caller's thread and a helper in its denormal mode, so a band's noise is
// the same whichever thread makes it). A noise's bands are independent FFT
// work (its 22 FFTs of the period: ~57 ms on one core for a 2 s IR), and
// the sources of a simulation that need it wait for it. One run where there
// is one core. Out of memory in a run is thrown here.
template <typename Body>
void forBandHalves(const Body& body) {
  const size_t parts = std::thread::hardware_concurrency() > 1 ? 2 : 1;
  if (!forRuns(size_t(kNumBands), 1, parts, [&](size_t b0, size_t b1) {
        body(int(b0), int(b1));
        return true;
      }))
    throw std::bad_alloc();
}

// The period of the band noises for an IR of `length` samples: the power of
// two at or above it (at least 1024), so IRs of similar lengths share them.
size_t noisePeriod(size_t length) {
  size_t n = 1024;
  while (n < length) n *= 2;
  return n;
}

// A noise cache (most recent first; entries of n samples per band) cut to
// at most `entries` and `maxBytes`, the newest always kept.
template <typename Entry>
void trimNoiseCache(std::vector<Entry>& cache, size_t maxBytes, size_t entries) {
  size_t bytes = 0;
  for (size_t i = 0; i < cache.size(); ++i) {
    bytes += cache[i].n * kNumBands * sizeof(float);
    if (i > 0 && (bytes > maxBytes || i >= entries)) {
      cache.resize(i);
      return;
    }
  }
}

// sqrt(W_b) of the noise band weights on the bins of an n-point real FFT
// (n / 2 + 1 rows), made once per (n, rate): noiseBandWeights costs a few
// logs and sines per bin.
std::shared_ptr<const std::vector<std::array<float, kNumBands>>> sqrtNoiseWeights(size_t n, double fs) {
  using Table = std::vector<std::array<float, kNumBands>>;
  static std::mutex mutex;
  static std::vector<std::tuple<size_t, double, std::shared_ptr<const Table>>> tables;
  std::lock_guard<std::mutex> lock(mutex);
  for (const auto& [tn, tfs, t] : tables)
    if (tn == n && tfs == fs) return t;
  auto t = std::make_shared<Table>(n / 2 + 1);
  for (size_t k = 0; k <= n / 2; ++k) {
    const BandArrayD w = noiseBandWeights(double(k) * fs / double(n));
    for (int b = 0; b < kNumBands; ++b) (*t)[k][size_t(b)] = float(std::sqrt(std::max(0.0, w[size_t(b)])));
  }
  tables.emplace_back(n, fs, t);
  if (tables.size() > 8) tables.erase(tables.begin());
  return t;
}
}  // namespace

std::shared_ptr<const SpectralSynth::BandTable> SpectralSynth::bandTable(size_t n, double fs) {
  static std::mutex mutex;
  static std::vector<std::tuple<size_t, double, std::shared_ptr<const BandTable>>> tables;  // most recent first
  {
    std::lock_guard<std::mutex> lock(mutex);
    for (size_t i = 0; i < tables.size(); ++i)
      if (std::get<0>(tables[i]) == n && std::get<1>(tables[i]) == fs) {
        std::rotate(tables.begin(), tables.begin() + std::ptrdiff_t(i), tables.begin() + std::ptrdiff_t(i) + 1);
        return std::get<2>(tables[0]);
      }
  }
  const size_t bins = n / 2 + 1;
  auto t = std::make_shared<BandTable>();
  t->lowerBand.resize(bins);
  t->lowerWeight.resize(bins);
  t->runEnd.resize(bins);
  for (size_t k = 0; k < bins; ++k) {
    const BandArrayD w = bandWeights(double(k) * fs / double(n));
    // At most two band weights are non-zero at any frequency: keep the lower one.
    int lb = kNumBands - 1;
    for (int b = 0; b < kNumBands; ++b)
      if (float(w[b]) > 0) {
        lb = b;
        break;
      }
    t->lowerBand[k] = uint8_t(lb);
    t->lowerWeight[k] = float(w[lb]);  // lb = kNumBands - 1: the weight of the top band, 1
  }
  for (size_t k = bins; k-- > 0;)
    t->runEnd[k] = uint32_t(k + 1 < bins && t->lowerBand[k + 1] == t->lowerBand[k] ? t->runEnd[k + 1] : k + 1);
  std::lock_guard<std::mutex> lock(mutex);
  tables.insert(tables.begin(), {n, fs, t});
  if (tables.size() > 16) tables.pop_back();  // at most ~16 x 0.5 MB for 2 s IRs
  return t;
}

Result<SpectralSynth> SpectralSynth::create(size_t length, double fs, size_t arrivalsEnd, double bandShiftOctaves) {
  SpectralSynth s;
  s.mFs = fs;
  s.mBandFs = fs * std::exp2(-bandShiftOctaves);  // exactly fs for the octaves
  s.mLength = length;
  // The arrivals' frame: up to the last arrival, half the margin after it
  // for its band filters' ringing and sinc tail (kept), and the whole margin
  // beyond (where what rings before time 0 wraps to, dropped).
  const size_t margin = size_t(kMarginSeconds * fs);
  s.mKeep = std::min(length, arrivalsEnd + margin / 2);
  s.mN = fastFftSize(s.mKeep + margin);
  s.mBins = s.mN / 2 + 1;
  s.mInverse = inversePlan(s.mN);
  if (!s.mInverse) return Status(StatusCode::kInternal, "FFT allocation failed");
  s.mBands = bandTable(s.mN, s.mBandFs);
  s.mScratch.resize(s.mBins);
  return s;
}

Result<SpectralSynth> SpectralSynth::plan(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                                          const IrSynthesisSettings& settings) {
  EARSHOT_RETURN_IF_ERROR(validate(settings));
  for (const Arrival& a : arrivals)
    if (!std::isfinite(a.delaySeconds) || a.delaySeconds < 0 || !std::isfinite(a.gain))
      return invalidArgument("arrival with delay " + std::to_string(a.delaySeconds) + " s, gain " + std::to_string(a.gain));
  const size_t length = irLengthSamples(arrivals, reflections, settings);
  if (length > kMaxIrSamples) return outOfRange("IR of " + std::to_string(length) + " samples is over the limit");
  double end = -1.0;
  for (const Arrival& a : arrivals)
    if (a.gain != 0) end = std::max(end, a.delaySeconds);
  const size_t arrivalsEnd =
      end < 0 ? 0 : size_t(std::min(double(kMaxIrSamples), std::ceil((end + kArrivalSlackSeconds) * settings.sampleRateHz)));
  return create(length, settings.sampleRateHz, arrivalsEnd, settings.bandShiftOctaves);
}

size_t SpectralSynth::noisePeriod() const { return detail::noisePeriod(mLength); }

double SpectralSynth::memoryBytes(size_t channels, size_t noises) const {
  const double perSample = 2.0 * double(channels) * sizeof(float) + double(kNumBands + 4) * sizeof(float);
  // A set's bands, and (once, while one is made) the white noise, its
  // spectrum and each of two threads' inverse, filtered bins and level sums.
  const double perNoiseSample = double(noises) * kNumBands * sizeof(float) + 6.0 * sizeof(float) + 2.0 * 3.0 * 8.0;
  return double(mLength) * perSample + double(noisePeriod()) * perNoiseSample;
}

Status SpectralSynth::checkMemory(size_t channels, size_t noises) const {
  return checkMemoryEstimate(memoryBytes(channels, noises), "synthesising an IR of " + std::to_string(mLength) +
                                                                " samples at " + std::to_string(std::lround(mFs)) +
                                                                " Hz in " + std::to_string(channels) + " channels");
}

void SpectralSynth::prepareGrid(size_t gridSize) {
  if (mGridSize == gridSize) return;
  mGridSize = gridSize;
  mGridIndex.resize(mBins);
  mGridFrac.resize(mBins);
  mGridRunEnd.resize(mBins);
  const size_t last = gridSize / 2;
  for (size_t k = 0; k < mBins; ++k) {
    const double pos = double(k) * double(gridSize) / double(mN);
    const size_t i = std::min(size_t(pos), last);
    mGridIndex[k] = uint32_t(i == last ? last - 1 : i);
    mGridFrac[k] = i == last ? 1.0f : float(pos - double(i));
  }
  // The index grows with k: each bin's run of bins with its grid point ends
  // where the next run starts.
  for (size_t k = mBins; k-- > 0;)
    mGridRunEnd[k] = uint32_t(k + 1 < mBins && mGridIndex[k + 1] == mGridIndex[k] ? mGridRunEnd[k + 1] : k + 1);
}

namespace {
// An arrival's values, kPhasorBlock bins at a time: the phasor
// exp(-j 2 pi k tau / n) per block, the block's first phase in double
// precision and the others from it by a table of the steps
// exp(-j 2 pi m tau / n), m < kPhasorBlock, so that the inner loops are plain
// float arithmetic the compiler vectorises. The table and the blocks' first
// phases follow by products of double-precision unit phasors (a sincos per
// block and per step was a quarter of an omni IR's synthesis): each product
// adds ~1e-16 of error, so after the largest IR's 2.3e5 blocks the phase is
// within ~5e-11 of exact, far under a float's 6e-8. And the arrival's band
// gains through the complementary band weights: bin k takes
// g[lb] w + g[lb + 1] (1 - w) of its (at most two) bands.
// Inlined into its callers' clones (EARSHOT_CLONES).
constexpr size_t kPhasorBlock = 64;
struct ArrivalBlocks {
  float stepRe[kPhasorBlock], stepIm[kPhasorBlock];
  double blockCos, blockSin, blockRe = 1.0, blockIm = 0.0;  // block: exp(j angle k0)
  float gains[kNumBands + 1];

  __attribute__((always_inline)) inline ArrivalBlocks(const Arrival& a, double angle) {
    const double c1 = std::cos(angle), s1 = std::sin(angle);
    double zr = 1.0, zi = 0.0;
    for (size_t m = 0; m < kPhasorBlock; ++m) {
      stepRe[m] = float(zr);
      stepIm[m] = float(zi);
      const double nr = zr * c1 - zi * s1;
      zi = zr * s1 + zi * c1;
      zr = nr;
    }
    blockCos = std::cos(angle * double(kPhasorBlock));
    blockSin = std::sin(angle * double(kPhasorBlock));
    for (int b = 0; b < kNumBands; ++b) gains[b] = float(a.gain * a.bandGain[size_t(b)]);
    gains[kNumBands] = 0.0f;
  }
  /** This block's phasor (count bins) and band gains into pr, pi and g;
   *  then on to the next block. */
  __attribute__((always_inline)) inline void next(size_t k0, size_t count, const uint8_t* lowerBand,
                                                  const uint32_t* runEnd, const float* lowerWeight, float* pr,
                                                  float* pi, float* g) {
    const float br = float(blockRe), bi = float(blockIm);
    {
      const double nr = blockRe * blockCos - blockIm * blockSin;
      blockIm = blockRe * blockSin + blockIm * blockCos;
      blockRe = nr;
    }
    for (size_t m = 0; m < count; ++m) {
      pr[m] = br * stepRe[m] - bi * stepIm[m];
      pi[m] = br * stepIm[m] + bi * stepRe[m];
    }
    // A run of bins per lower band: its two gains loaded once, the run's
    // loop vectorised.
    for (size_t m = 0; m < count;) {
      const size_t k = k0 + m;
      const uint8_t lb = lowerBand[k];
      const size_t end = std::min(count, size_t(runEnd[k]) - k0);
      const float ga = gains[lb], gb = gains[lb + 1];
      const float* wk = lowerWeight + k0;
      for (; m < end; ++m) g[m] = ga * wk[m] + gb * (1.0f - wk[m]);
    }
  }
};
}  // namespace

EARSHOT_CLONES
void SpectralSynth::addArrival(const Arrival& a, double delaySeconds, const GridFilter& h, Spectrum& spectrum) {
  if (a.gain == 0) return;
  if (h.values) prepareGrid(h.gridSize);
  ArrivalBlocks blocks(a, -2.0 * kPi * (delaySeconds * mFs) / double(mN));
  constexpr size_t kBlock = kPhasorBlock;
  const float* hv = h.values ? reinterpret_cast<const float*>(h.values) : nullptr;
  float* re = spectrum.re.data();
  float* im = spectrum.im.data();
  float pr[kBlock], pi[kBlock], g[kBlock];
  for (size_t k0 = 0; k0 < mBins; k0 += kBlock) {
    const size_t count = std::min(kBlock, mBins - k0);
    blocks.next(k0, count, mBands->lowerBand.data(), mBands->runEnd.data(), mBands->lowerWeight.data(), pr, pi, g);
    if (hv) {
      // The filter on these bins, a run of bins per grid interval (the
      // interval's two points loaded once, the run's loop vectorised).
      float hr[kBlock], hi[kBlock];
      for (size_t m = 0; m < count;) {
        const size_t k = k0 + m;
        const uint32_t i = mGridIndex[k];
        const size_t end = std::min(count, size_t(mGridRunEnd[k]) - k0);
        const float lowRe = hv[2 * i], lowIm = hv[2 * i + 1], highRe = hv[2 * i + 2], highIm = hv[2 * i + 3];
        const float* fk = mGridFrac.data() + k0;
        for (; m < end; ++m) {
          const float f = fk[m];
          hr[m] = lowRe * (1.0f - f) + highRe * f;
          hi[m] = lowIm * (1.0f - f) + highIm * f;
        }
      }
      for (size_t m = 0; m < count; ++m) {
        const size_t k = k0 + m;
        const float vr = g[m] * pr[m], vi = g[m] * pi[m];
        re[k] += vr * hr[m] - vi * hi[m];
        im[k] += vr * hi[m] + vi * hr[m];
      }
    } else {
      for (size_t m = 0; m < count; ++m) {
        re[k0 + m] += g[m] * pr[m];
        im[k0 + m] += g[m] * pi[m];
      }
    }
  }
  // The Nyquist bin of a real signal must be real.
  if (mN % 2 == 0) im[mBins - 1] = 0.0f;
}

EARSHOT_CLONES
void SpectralSynth::addWeightedArrivals(const std::vector<Arrival>& arrivals, const float* weights, size_t channels,
                                       Spectrum* spectra) {
  // Each arrival's phasor and band gains as addArrival makes them (ArrivalBlocks).
  constexpr size_t kBlock = kPhasorBlock;
  std::vector<ArrivalBlocks> arrivalBlocks;
  std::vector<const float*> arrivalWeights;
  arrivalBlocks.reserve(arrivals.size());
  arrivalWeights.reserve(arrivals.size());
  for (size_t i = 0; i < arrivals.size(); ++i) {
    const Arrival& a = arrivals[i];
    if (a.gain == 0) continue;
    arrivalBlocks.emplace_back(a, -2.0 * kPi * (a.delaySeconds * mFs) / double(mN));
    arrivalWeights.push_back(weights + i * channels);
  }
  float pr[kBlock], pi[kBlock], g[kBlock];
  for (size_t k0 = 0; k0 < mBins; k0 += kBlock) {
    const size_t count = std::min(kBlock, mBins - k0);
    for (size_t j = 0; j < arrivalBlocks.size(); ++j) {
      arrivalBlocks[j].next(k0, count, mBands->lowerBand.data(), mBands->runEnd.data(), mBands->lowerWeight.data(),
                            pr, pi, g);
      for (size_t m = 0; m < count; ++m) {
        pr[m] = g[m] * pr[m];
        pi[m] = g[m] * pi[m];
      }
      for (size_t c = 0; c < channels; ++c) {
        const float w = arrivalWeights[j][c];
        if (w == 0.0f) continue;
        float* re = spectra[c].re.data() + k0;
        float* im = spectra[c].im.data() + k0;
        for (size_t m = 0; m < count; ++m) {
          re[m] += w * pr[m];
          im[m] += w * pi[m];
        }
      }
    }
  }
  // The Nyquist bin of a real signal must be real.
  if (mN % 2 == 0)
    for (size_t c = 0; c < channels; ++c) spectra[c].im[mBins - 1] = 0.0f;
}

std::vector<float> whiteNoise(uint64_t seed, uint64_t stream, size_t count) {
  std::vector<float> out(count);
  Pcg32 rng(seed, stream);
  for (size_t i = 0; i < count; i += 2) {  // Box-Muller, two at a time
    double u1 = std::max(rng.uniformDouble(), 1e-300), u2 = rng.uniformDouble();
    double r = std::sqrt(-2.0 * std::log(u1));
    out[i] = float(r * std::cos(2 * kPi * u2));
    if (i + 1 < count) out[i + 1] = float(r * std::sin(2 * kPi * u2));
  }
  return out;
}

std::shared_ptr<const std::vector<std::vector<float>>> SpectralSynth::levelledBandNoise(uint64_t seed,
                                                                                      uint64_t stream) const {
  // Made for a power-of-two period n >= length(), circularly filtered (so
  // exactly stationary), and cached: IRs of similar lengths share it, and an
  // IR's length and seed alone decide its noise.
  const size_t n = noisePeriod();
  using Bands = std::vector<std::vector<float>>;
  struct Cached {
    uint64_t seed = 0, stream = 0;
    size_t n = 0;
    double fs = 0;
    std::shared_ptr<const Bands> bands;
  };
  // The most recent first; IRs of neighbouring size classes (a render's,
  // the runtime's) alternate, so a few are kept, up to kMaxCachedBytes.
  static std::mutex mutex;
  static std::vector<Cached> cache;
  {
    std::lock_guard<std::mutex> lock(mutex);
    for (const Cached& c : cache)
      if (c.seed == seed && c.stream == stream && c.n == n && c.fs == mBandFs) return c.bands;
  }
  const Plan forward = realPlan(n, false);
  auto bands = std::make_shared<Bands>(kNumBands, std::vector<float>(n, 0.0f));
  if (!forward) return bands;  // allocation failed: silence rather than a crash
  const size_t bins = n / 2 + 1;
  std::vector<kiss_fft_cpx> spectrum(bins);
  {
    std::vector<float> white = whiteNoise(seed, stream, n);
    kiss_fftr(forward.get(), white.data(), spectrum.data());
  }
  const auto weights = sqrtNoiseWeights(n, mBandFs);
  forBandHalves([&](int b0, int b1) {
    const Plan inverse = realPlan(n, true);  // this thread's while it runs
    if (!inverse) return;                    // silence, as above
    std::vector<float> time(n);
    std::vector<kiss_fft_cpx> filtered(bins);
    std::vector<double> prefix(n + 1);
    for (int b = b0; b < b1; ++b) {
      // Through sqrt(W); white noise keeps the mean of W over the circle.
      double power = 0;
      for (size_t k = 0; k < bins; ++k) {
        const float g = (*weights)[k][size_t(b)];
        const double w = double(g) * double(g);
        filtered[k] = {spectrum[k].r * g, spectrum[k].i * g};
        power += (k == 0 || k == bins - 1) ? w : 2.0 * w;
      }
      power /= double(n);
      kiss_fftri(inverse.get(), filtered.data(), time.data());
      const double scale = 1.0 / double(n);  // KissFFT's inverse is unnormalised
      prefix[0] = 0;
      for (size_t i = 0; i < n; ++i) {
        const double x = double(time[i]) * scale;
        prefix[i + 1] = prefix[i] + x * x;
      }
      const double width = 0.7071 * kBandCentersHz[size_t(b)];
      const size_t half = std::max<size_t>(4, size_t(0.5 * kLevelWindowCycles * mBandFs / width));
      std::vector<float>& out = (*bands)[size_t(b)];
      for (size_t i = 0; i < n; ++i) {
        const size_t lo = i > half ? i - half : 0, hi = std::min(n, i + half + 1);
        const double rms2 = (prefix[hi] - prefix[lo]) / double(hi - lo);
        out[i] = rms2 > 0 ? float(double(time[i]) * scale * std::sqrt(power / rms2)) : 0.0f;
      }
    }
  });
  std::lock_guard<std::mutex> lock(mutex);
  cache.insert(cache.begin(), Cached{seed, stream, n, mBandFs, bands});
  trimNoiseCache(cache, size_t(32) << 20, 6);
  return bands;
}

namespace {
struct ScratchStack {
  std::vector<std::unique_ptr<std::vector<float>>> buffers;  // each buffer stays where it is as this grows
  size_t top = 0;
};
ScratchStack& scratchStack() {
  thread_local ScratchStack stack;
  return stack;
}
}  // namespace

ThreadScratch::ThreadScratch(size_t count) {
  ScratchStack& st = scratchStack();
  mBase = st.top;
  while (st.buffers.size() < mBase + count) st.buffers.push_back(std::make_unique<std::vector<float>>());
  st.top = mBase + count;
  mCount = count;
}

std::vector<float>& ThreadScratch::operator[](size_t i) { return *scratchStack().buffers[mBase + i]; }

ThreadScratch::~ThreadScratch() {
  ScratchStack& st = scratchStack();
  for (size_t i = mBase; i < mBase + mCount; ++i)
    if (st.buffers[i]->capacity() > kKeptFloats) std::vector<float>().swap(*st.buffers[i]);
  st.top = mBase;
}

size_t noiseOffset(uint64_t seed, uint64_t noiseKey, size_t period) {
  if (noiseKey == 0 || period == 0) return 0;
  return size_t(mix64(mix64(seed) ^ mix64(noiseKey + 0x9E3779B97F4A7C15ULL)) % uint64_t(period));
}

const std::vector<double>& SpectralSynth::energyResponse(int band, size_t q) const {
  struct Cached {
    int band;
    size_t q;
    double fs;
    std::vector<double> kernel;
  };
  static std::mutex mutex;
  static std::vector<std::unique_ptr<Cached>> cache;  // never shrinks: bands x grid steps x rates in use
  std::lock_guard<std::mutex> lock(mutex);
  for (const auto& c : cache)
    if (c->band == band && c->q == q && c->fs == mBandFs) return c->kernel;
  // |f_b(t)|^2 from sqrt(W_b) on a 2^16-point grid (1.4 s at 48 kHz: far
  // longer than any band filter's response), summed into cells of q
  // samples centred on t = 0, cut where a cell holds under 1e-5 of the
  // whole (-50 dB), normalised.
  constexpr size_t n = size_t(1) << 16;
  FftrPtr inverse(kiss_fftr_alloc(int(n), 1, nullptr, nullptr));
  auto c = std::make_unique<Cached>(Cached{band, q, mBandFs, {1.0}});
  if (inverse) {
    std::vector<kiss_fft_cpx> spectrum(n / 2 + 1);
    const auto weights = sqrtNoiseWeights(n, mBandFs);
    for (size_t k = 0; k <= n / 2; ++k) spectrum[k] = {(*weights)[k][size_t(band)], 0.0f};
    std::vector<float> f(n);
    kiss_fftri(inverse.get(), spectrum.data(), f.data());
    const long cells = long(n / q / 2) - 1;
    std::vector<double> e(size_t(2 * cells + 1), 0.0);
    double total = 0;
    for (size_t i = 0; i < n; ++i) {
      const long t = i < n / 2 ? long(i) : long(i) - long(n);  // zero-phase: centred on 0, wrapped
      const long cell = long(std::floor((double(t) + 0.5 * double(q)) / double(q)));
      if (cell < -cells || cell > cells) continue;
      const double v = double(f[i]) * double(f[i]);
      e[size_t(cell + cells)] += v;
      total += v;
    }
    long keep = 0;
    for (long k = 0; k <= cells; ++k)
      if (e[size_t(cells + k)] > 1e-5 * total || e[size_t(cells - k)] > 1e-5 * total) keep = k;
    c->kernel.assign(e.begin() + (cells - keep), e.begin() + (cells + keep + 1));
    double sum = 0;
    for (double v : c->kernel) sum += v;
    for (double& v : c->kernel) v /= sum;
  }
  cache.push_back(std::move(c));
  return cache.back()->kernel;
}

namespace {

// bandEnvelope's samples between its grid points, `cells` whole cells of Q:
// e = a0 + (a1 - a0) frac[k], with Q known when compiled so that a cell's
// samples are straight-line code. Q is 3 and 6 for the top octaves at
// 48 kHz (3 and 5 at 44.1 kHz): a loop of Q iterations per cell was most of
// bandEnvelope's time. The same operations, so the same bits.
template <size_t Q>
void expandCells(const float* amp, const float* frac, size_t cells, float* e) {
  float f[Q];
  for (size_t k = 0; k < Q; ++k) f[k] = frac[k];
  for (size_t m = 0; m < cells; ++m, e += Q) {
    const float a0 = amp[m], d = amp[m + 1] - a0;
    for (size_t k = 0; k < Q; ++k) e[k] = a0 + d * f[k];
  }
}

}  // namespace

void expandEnvelope(const float* amp, size_t q, size_t length, float* env) {
  if (q <= 1) {
    std::copy(amp, amp + length, env);
    return;
  }
  // Position within a grid cell: the same q fractions in every cell.
  std::vector<float> frac(q);
  for (size_t k = 0; k < q; ++k) frac[k] = float(k) / float(q);
  using Expand = void (*)(const float*, const float*, size_t, float*);
  static constexpr Expand kExpand[] = {nullptr,        nullptr,        expandCells<2>, expandCells<3>,
                                       expandCells<4>, expandCells<5>, expandCells<6>};
  size_t m = 0;  // cells made
  if (q < std::size(kExpand)) {
    m = length / q;  // the whole cells (the last may be cut short)
    kExpand[q](amp, frac.data(), m, env);
  }
  for (; m * q < length; ++m) {
    const float a0 = amp[m], d = amp[m + 1] - a0;
    const size_t count = std::min(q, length - m * q);
    float* e = env + m * q;
    for (size_t k = 0; k < count; ++k) e[k] = a0 + d * frac[k];
  }
}

bool SpectralSynth::bandEnvelope(const EnergyHistogram& h, int band, const float* gain, std::vector<float>& env) const {
  const double binSamples = h.binSeconds() * mFs;
  const size_t histBins = h.binCount();
  env.resize(mLength);  // every sample is written below
  if (mLength == 0) return false;
  // The density per bin (energy per sample), with a zero bin on each side.
  std::vector<double> density(histBins + 2, 0.0);
  bool any = false;
  for (size_t b = 0; b < histBins; ++b) {
    const double d = h.energy(b, band) / binSamples;
    density[b + 1] = gain ? d * double(gain[b]) : d;
    any = any || density[b + 1] > 0;
  }
  if (!any) return false;
  auto densityAt = [&](long bin) { return bin < 0 || size_t(bin) >= histBins ? 0.0 : density[size_t(bin) + 1]; };
  // The noise is shaped after its band filters (finishedBandNoise), not
  // filtered after the shaping, so the envelope's steps (the late field's
  // onset, the histogram's end) would widen the band (a step spreads a band
  // by ~1 / (pi f) into its neighbours), and the band's onset would be
  // sharper than a band-limited signal's can be. The energy envelope is
  // therefore the density convolved with the band filter's own energy
  // response |f_b(t)|^2 (f_b: the zero-phase response of sqrt(W_b)), which
  // is what filtering after the shaping gave on average (E|f * (n e)|^2 =
  // |f|^2 * e^2 for white n): the onset spreads as the band filter spreads
  // it, and the envelope's spectrum stays within the filter's bandwidth. The
  // convolution runs on a grid of half a period of the band's centre (at
  // most a histogram bin), the amplitude linear between grid points.
  const size_t width = std::max<size_t>(1, size_t(std::lround(mBandFs / kBandCentersHz[size_t(band)])));
  const size_t q = std::max<size_t>(1, std::min(width / 2, size_t(binSamples)));
  const size_t points = mLength / q + 2;  // grid point m at sample m q
  // The grid and the float temporaries in this thread's buffers (see
  // ThreadScratch), kept for its next envelope.
  thread_local std::vector<double> gridBuffer;
  struct ReleaseLarge {
    std::vector<double>& v;
    ~ReleaseLarge() {
      if (v.capacity() > ThreadScratch::kKeptFloats / 2) std::vector<double>().swap(v);
    }
  } releaseGrid{gridBuffer};
  ThreadScratch scratch(3);
  std::vector<double>& grid = gridBuffer;
  grid.resize(points);
  {
    // The density between bin centres: sample i sits at (i + 0.5) /
    // binSamples - 0.5 bins; the bin j at or before it followed as it grows
    // (a floor per point is a libm call on baseline x86-64).
    const double perSample = 1.0 / binSamples;
    long j = long(std::floor(0.5 * perSample - 0.5));
    double lo = densityAt(j), hi = densityAt(j + 1);
    for (size_t m = 0; m < points; ++m) {
      const double x = (double(m * q) + 0.5) * perSample - 0.5;
      if (double(j + 1) <= x) {
        while (double(j + 1) <= x) ++j;
        lo = densityAt(j);
        hi = densityAt(j + 1);
      }
      const double frac = x - double(j);
      grid[m] = std::max(0.0, (1.0 - frac) * lo + frac * hi);
    }
  }
  const std::vector<double>& kernel = energyResponse(band, q);  // odd length, centred, sum 1
  if (kernel.size() > 1) {
    // In float (the kernel sums to one; float keeps 1e-7 of each sum), by
    // the FIR kernel (earshot/dsp/fir.h; the kernel is symmetric).
    const size_t taps = kernel.size(), half = taps / 2;
    std::vector<float>& padded = scratch[0];
    padded.assign(points + 2 * half, 0.0f);
    const std::vector<float> k32(kernel.begin(), kernel.end());
    for (size_t m = 0; m < points; ++m) padded[m + half] = float(grid[m]);
    std::vector<float>& convolved = scratch[2];
    convolved.resize(points);
    firInto(k32.data(), taps, padded.data(), convolved.data(), points);
    for (size_t m = 0; m < points; ++m) grid[m] = double(convolved[m]);
  }
  std::vector<float>& amp = scratch[1];
  amp.resize(points);
  for (size_t m = 0; m < points; ++m) amp[m] = float(std::sqrt(std::max(0.0, grid[m])));
  expandEnvelope(amp.data(), q, mLength, env.data());
  return true;
}

namespace {

// out[i] += a[j] env[i], then (Two) += b[j] env[i], j = (i + offset) mod
// period (offset < period): two runs, up to the noises' wrap and from
// their start (length <= period).
template <bool Two>
void addEnveloped(const float* a, const float* b, size_t period, size_t offset, const float* env, float* out,
                  size_t length) {
  const size_t first = std::min(length, period - offset);
  const float* na = a + offset;
  const float* nb = Two ? b + offset : nullptr;  // (b is null for one noise)
  for (size_t i = 0; i < first; ++i) {
    float o = out[i] + na[i] * env[i];
    if (Two) o = o + nb[i] * env[i];
    out[i] = o;
  }
  for (size_t i = first; i < length; ++i) {
    float o = out[i] + a[i - first] * env[i];
    if (Two) o = o + b[i - first] * env[i];
    out[i] = o;
  }
}

}  // namespace

void SpectralSynth::addEnvelopedNoise(const std::vector<float>& noise, size_t offset, const std::vector<float>& env,
                                      float* out, size_t count) const {
  const size_t period = noise.size();
  if (period == 0) return;
  addEnveloped<false>(noise.data(), nullptr, period, offset % period, env.data(), out, std::min(mLength, count));
}

void SpectralSynth::addEnvelopedNoises(const std::vector<float>& a, const std::vector<float>& b, size_t offset,
                                       const std::vector<float>& env, float* out, size_t count) const {
  const size_t period = a.size();
  if (b.size() != period) {
    addEnvelopedNoise(a, offset, env, out, count);
    addEnvelopedNoise(b, offset, env, out, count);
    return;
  }
  if (period == 0) return;
  addEnveloped<true>(a.data(), b.data(), period, offset % period, env.data(), out, std::min(mLength, count));
}

std::shared_ptr<const std::vector<std::vector<float>>> SpectralSynth::finishedBandNoise(uint64_t seed,
                                                                                     uint64_t stream,
                                                                                     const GridFilter& h,
                                                                                     uint64_t filterKey) const {
  return finishedBandNoises(seed, stream, {{h, filterKey}})[0];
}

namespace {

// The late noises' disk cache (earshot/io/disk_cache.h): a finished noise
// (one (seed, stream, period, rate, filter)) costs 22 FFTs of its period
// (~45 ms for 2 s IRs), which a one-shot `earshot ir` or render pays again
// for every noise it reads; from the cache folder it is a file read. An
// entry is used only if its key (the filter by a hash of its values, the
// noise's numerics by a fingerprint of the code on a short period) and its
// size are the expected ones and its checksum and values hold. A process
// adds at most kNoiseCacheWritesPerProcess entries (a dataset whose every
// IR has its own seed would otherwise write a noise per IR); the folder
// keeps the newest kNoiseCacheEntries.
constexpr int kNoiseCacheWritesPerProcess = 8;
constexpr size_t kNoiseCacheEntries = 16;
constexpr char kNoiseMagic[8] = {'E', 'A', 'R', 'S', 'N', 'O', 'I', 'S'};
constexpr uint32_t kNoiseFormatVersion = 1;

struct NoiseEntryKey {
  char magic[8];
  uint32_t version = kNoiseFormatVersion, bands = kNumBands;
  uint64_t seed = 0, stream = 0, filterA = 0, filterB = 0, n = 0;
  double fs = 0;
  uint64_t fingerprint = 0;
};
static_assert(sizeof(NoiseEntryKey) == 8 + 8 + 40 + 8 + 8, "no padding in the noise entry key");

std::atomic<int> gNoiseCacheWrites{0};

// A grid filter's response on the bins of a period of n (linear between its
// grid points); empty for no filter (identity).
std::vector<std::complex<float>> responseOnPeriod(const GridFilter& h, size_t n) {
  std::vector<std::complex<float>> response;
  if (!h.values) return response;
  const size_t bins = n / 2 + 1;
  response.resize(bins);
  const size_t last = h.gridSize / 2;
  for (size_t k = 0; k < bins; ++k) {
    const double pos = double(k) * double(h.gridSize) / double(n);
    const size_t i0 = std::min(size_t(pos), last);
    const size_t i = i0 == last ? last - 1 : i0;
    const float fr = i0 == last ? 1.0f : float(pos - double(i0));
    response[k] = h.values[i] * (1.0f - fr) + h.values[i + 1] * fr;
  }
  return response;
}

// The most mean square a finished band can have, per band: the levelled
// noise has a mean square of (about) its power, sum of W over the circle /
// n, and the second filtering (sqrt(W) times the response) multiplies no
// bin's energy by more than its largest W |h|^2 (Parseval). Twice that for
// the levelling's window. A cached entry over it was not made here (its
// checksum is no seal: anyone can compute one).
std::array<double, kNumBands> finishedBandBounds(const std::vector<std::array<float, kNumBands>>& weights,
                                                 const std::vector<std::complex<float>>& response, size_t n) {
  std::array<double, kNumBands> bound{};
  const size_t bins = n / 2 + 1;
  for (int b = 0; b < kNumBands; ++b) {
    double power = 0, gain = 0;
    for (size_t k = 0; k < bins; ++k) {
      const double w = double(weights[k][size_t(b)]) * double(weights[k][size_t(b)]);
      power += (k == 0 || k == bins - 1) ? w : 2.0 * w;
      gain = std::max(gain, w * (response.empty() ? 1.0 : double(std::norm(response[k]))));
    }
    bound[size_t(b)] = 2.0 * power / double(n) * gain;
  }
  return bound;
}

}  // namespace

uint64_t SpectralSynth::noiseFingerprint() {
  // The whole chain on a short period: any change to the white noise, the
  // band weights, the levelling or the second filtering changes it.
  static const uint64_t fingerprint = [] {
    auto plan = create(1000, 48000.0, 0);
    if (!plan.isOk()) return uint64_t(0);
    const std::vector<std::pair<GridFilter, uint64_t>> identity = {{GridFilter{}, 0}};
    const auto made = plan->makeFinishedBandNoises(0xF1F0, 1, identity, {0});
    std::vector<float> all;
    for (const auto& band : *made[0]) all.insert(all.end(), band.begin(), band.end());
    return hashBytes(all.data(), all.size() * sizeof(float), kNoiseFormatVersion).a;
  }();
  return fingerprint;
}

std::vector<std::shared_ptr<const std::vector<std::vector<float>>>> SpectralSynth::finishedBandNoises(
    uint64_t seed, uint64_t stream, const std::vector<std::pair<GridFilter, uint64_t>>& filters) const {
  using Bands = std::vector<std::vector<float>>;
  struct Key {
    uint64_t seed = 0, stream = 0, filterKey = 0;
    size_t n = 0;
    double fs = 0;
    bool operator==(const Key& o) const {
      return seed == o.seed && stream == o.stream && filterKey == o.filterKey && n == o.n && fs == o.fs;
    }
  };
  struct Cached {
    Key key;
    size_t n = 0;  // samples per band (trimNoiseCache)
    std::shared_ptr<const Bands> bands;
  };
  static std::mutex mutex;
  static std::vector<Cached> cache;
  // Noises another thread is making: a thread that needs one waits for it
  // instead of making it too (the sources of one simulation start their
  // synthesis together and need the same noises), and makes the others.
  static std::vector<Key> making;
  static std::condition_variable made;
  const size_t n = noisePeriod();
  auto keyOf = [&](size_t f) { return Key{seed, stream, filters[f].second, n, mBandFs}; };
  std::vector<std::shared_ptr<const Bands>> out(filters.size());
  std::unique_lock<std::mutex> lock(mutex);
  for (;;) {
    std::vector<size_t> missing;
    bool othersMaking = false;
    for (size_t f = 0; f < filters.size(); ++f) {
      if (out[f]) continue;
      const Key key = keyOf(f);
      for (const Cached& c : cache)
        if (c.key == key) {
          out[f] = c.bands;
          break;
        }
      if (out[f]) continue;
      if (std::find(making.begin(), making.end(), key) != making.end()) othersMaking = true;
      else missing.push_back(f);
    }
    if (missing.empty()) {
      if (!othersMaking) return out;
      made.wait(lock);
      continue;
    }
    for (size_t f : missing) making.push_back(keyOf(f));
    lock.unlock();
    std::vector<std::shared_ptr<Bands>> bands;
    try {
      bands = cachedOrMadeBandNoises(seed, stream, filters, missing);
    } catch (...) {
      lock.lock();
      for (size_t f : missing) making.erase(std::find(making.begin(), making.end(), keyOf(f)));
      made.notify_all();
      throw;
    }
    lock.lock();
    for (size_t k = 0; k < missing.size(); ++k) {
      out[missing[k]] = bands[k];
      cache.insert(cache.begin(), Cached{keyOf(missing[k]), n, bands[k]});
      making.erase(std::find(making.begin(), making.end(), keyOf(missing[k])));
    }
    trimNoiseCache(cache, size_t(128) << 20, 48);
    made.notify_all();
  }
}

std::vector<std::shared_ptr<std::vector<std::vector<float>>>> SpectralSynth::cachedOrMadeBandNoises(
    uint64_t seed, uint64_t stream, const std::vector<std::pair<GridFilter, uint64_t>>& filters,
    const std::vector<size_t>& missing) const {
  using Bands = std::vector<std::vector<float>>;
  const std::string folder = cacheFolder();
  if (folder.empty()) return makeFinishedBandNoises(seed, stream, filters, missing);
  const size_t n = noisePeriod();
  const uint64_t payload = uint64_t(kNumBands) * n * sizeof(float);
  std::vector<std::shared_ptr<Bands>> out(missing.size());
  std::vector<NoiseEntryKey> keys(missing.size());
  std::vector<std::string> names(missing.size());
  std::vector<size_t> toMake, toMakeAt;
  for (size_t k = 0; k < missing.size(); ++k) {
    NoiseEntryKey& key = keys[k];
    std::memcpy(key.magic, kNoiseMagic, 8);
    key.seed = seed;
    key.stream = stream;
    const GridFilter& h = filters[missing[k]].first;
    if (h.values) {
      const Hash128 fh = hashBytes(h.values, (h.gridSize / 2 + 1) * sizeof(std::complex<float>), h.gridSize);
      key.filterA = fh.a;
      key.filterB = fh.b;
    }
    key.n = n;
    key.fs = mBandFs;
    key.fingerprint = noiseFingerprint();
    names[k] = cacheEntryName("noise-", &key, sizeof key);
    const auto entry = readCacheEntry(folder + "/" + names[k], sizeof key + payload + 16);
    bool ok = entry && entry->size() == sizeof key + payload && std::memcmp(entry->data(), &key, sizeof key) == 0;
    if (ok) {
      auto bands = std::make_shared<Bands>(kNumBands, std::vector<float>(n));
      const auto bound = finishedBandBounds(*sqrtNoiseWeights(n, mBandFs), responseOnPeriod(h, n), n);
      const char* p = entry->data() + sizeof key;
      for (size_t b = 0; b < size_t(kNumBands); ++b) {
        std::vector<float>& band = (*bands)[b];
        std::memcpy(band.data(), p, n * sizeof(float));
        p += n * sizeof(float);
        double sum = 0;
        for (float v : band) sum += double(v) * double(v);  // inf or NaN for a non-finite v
        ok = ok && sum / double(n) <= bound[b];
      }
      if (ok) out[k] = std::move(bands);
    }
    if (!out[k]) {
      toMake.push_back(missing[k]);
      toMakeAt.push_back(k);
    }
  }
  if (toMake.empty()) return out;
  const auto made = makeFinishedBandNoises(seed, stream, filters, toMake);
  for (size_t j = 0; j < toMake.size(); ++j) {
    const size_t k = toMakeAt[j];
    out[k] = made[j];
    // Silence means an FFT plan could not be allocated: never kept.
    bool audible = false;
    for (const auto& band : *made[j])
      for (size_t i = 0; i < band.size() && !audible; ++i) audible = band[i] != 0.0f;
    if (!audible || gNoiseCacheWrites.fetch_add(1) >= kNoiseCacheWritesPerProcess) continue;
    std::string bytes(reinterpret_cast<const char*>(&keys[k]), sizeof keys[k]);
    bytes.reserve(sizeof keys[k] + payload);
    for (const auto& band : *made[j]) bytes.append(reinterpret_cast<const char*>(band.data()), n * sizeof(float));
    writeCacheEntry(folder, names[k], bytes, "noise-", kNoiseCacheEntries);
  }
  return out;
}

std::vector<std::shared_ptr<std::vector<std::vector<float>>>> SpectralSynth::makeFinishedBandNoises(
    uint64_t seed, uint64_t stream, const std::vector<std::pair<GridFilter, uint64_t>>& filters,
    const std::vector<size_t>& missing) const {
  using Bands = std::vector<std::vector<float>>;
  const size_t n = noisePeriod();
  const auto levelled = levelledBandNoise(seed, stream);
  std::vector<std::shared_ptr<Bands>> made;
  for (size_t k = 0; k < missing.size(); ++k) made.push_back(std::make_shared<Bands>(kNumBands, std::vector<float>(n, 0.0f)));
  const size_t bins = n / 2 + 1;
  // The second sqrt(W_band) and each h on this period's bins (h linear
  // between its grid points); one forward FFT per band serves every filter.
  const auto weights = sqrtNoiseWeights(n, mBandFs);
  std::vector<std::vector<std::complex<float>>> response(missing.size());
  for (size_t f = 0; f < missing.size(); ++f) response[f] = responseOnPeriod(filters[missing[f]].first, n);
  const float scale = 1.0f / float(n);  // KissFFT's inverse is unnormalised
  forBandHalves([&](int b0, int b1) {
    const Plan forward = realPlan(n, false), inverse = realPlan(n, true);  // this thread's while it runs
    if (!forward || !inverse) return;  // allocation failed: silence rather than a crash
    std::vector<kiss_fft_cpx> spectrum(bins), filtered(bins);
    for (int b = b0; b < b1; ++b) {
      kiss_fftr(forward.get(), (*levelled)[size_t(b)].data(), spectrum.data());
      for (size_t f = 0; f < missing.size(); ++f) {
        for (size_t k = 0; k < bins; ++k) {
          const float g = (*weights)[k][size_t(b)] * scale;
          std::complex<float> x(spectrum[k].r * g, spectrum[k].i * g);
          if (!response[f].empty()) x *= response[f][k];
          filtered[k] = {x.real(), x.imag()};
        }
        if (n % 2 == 0) filtered[bins - 1].i = 0.0f;
        kiss_fftri(inverse.get(), filtered.data(), (*made[f])[size_t(b)].data());
      }
    }
  });
  return made;
}

void SpectralSynth::inverse(const Spectrum& spectrum, std::vector<float>& out) {
  for (size_t k = 0; k < mBins; ++k) mScratch[k] = {spectrum.re[k], spectrum.im[k]};
  std::vector<float> time(mN);
  kiss_fftri(mInverse.get(), mScratch.data(), time.data());
  out.assign(mLength, 0.0f);
  const float scale = 1.0f / float(mN);  // KissFFT's inverse is unnormalised
  for (size_t i = 0; i < mKeep; ++i) out[i] = time[i] * scale;
}

}  // namespace earshot::detail
