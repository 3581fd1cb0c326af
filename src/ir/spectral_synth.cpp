// Frequency-domain IR synthesis shared by the omni and binaural paths: see
// spectral_synth.h and ir_synthesis.h for the method.
#include "spectral_synth.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <string>

#include "earshot/core/math.h"
#include "earshot/core/random.h"
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

Result<SpectralSynth> SpectralSynth::create(size_t length, double fs) {
  SpectralSynth s;
  s.mFs = fs;
  s.mLength = length;
  s.mN = fastFftSize(length + size_t(kMarginSeconds * fs));
  s.mBins = s.mN / 2 + 1;
  s.mForward.reset(kiss_fftr_alloc(int(s.mN), 0, nullptr, nullptr));
  s.mInverse.reset(kiss_fftr_alloc(int(s.mN), 1, nullptr, nullptr));
  if (!s.mForward || !s.mInverse) return Status(StatusCode::kInternal, "FFT allocation failed");
  s.mSqrtWeights.assign(kNumBands, std::vector<float>(s.mBins));
  s.mLowerBand.resize(s.mBins);
  s.mLowerWeight.resize(s.mBins);
  for (size_t k = 0; k < s.mBins; ++k) {
    const BandArrayD noiseW = noiseBandWeights(double(k) * fs / double(s.mN));
    for (int b = 0; b < kNumBands; ++b) s.mSqrtWeights[b][k] = float(std::sqrt(std::max(0.0, noiseW[b])));
    const BandArrayD w = bandWeights(double(k) * fs / double(s.mN));
    // At most two band weights are non-zero at any frequency: keep the lower one.
    int lb = kNumBands - 1;
    for (int b = 0; b < kNumBands; ++b)
      if (float(w[b]) > 0) {
        lb = b;
        break;
      }
    s.mLowerBand[k] = uint8_t(lb);
    s.mLowerWeight[k] = float(w[lb]);
  }
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
  return create(length, settings.sampleRateHz);
}

void SpectralSynth::prepareGrid(size_t gridSize) {
  if (mGridSize == gridSize) return;
  mGridSize = gridSize;
  mGridIndex.resize(mBins);
  mGridFrac.resize(mBins);
  const size_t last = gridSize / 2;
  for (size_t k = 0; k < mBins; ++k) {
    const double pos = double(k) * double(gridSize) / double(mN);
    const size_t i = std::min(size_t(pos), last);
    mGridIndex[k] = uint32_t(i == last ? last - 1 : i);
    mGridFrac[k] = i == last ? 1.0 : pos - double(i);
  }
}

std::complex<double> SpectralSynth::filterAt(const GridFilter& h, size_t k) const {
  const size_t i = mGridIndex[k];
  const double f = mGridFrac[k];
  return std::complex<double>(h.values[i]) * (1.0 - f) + std::complex<double>(h.values[i + 1]) * f;
}

void SpectralSynth::addArrival(const Arrival& a, double delaySeconds, const GridFilter& h,
                               std::complex<double>* spectrum) {
  if (a.gain == 0) return;
  if (h.values) prepareGrid(h.gridSize);
  const double tau = delaySeconds * mFs;  // samples
  // exp(-j 2 pi k tau / n) by recurrence: one complex multiply per bin, in
  // plain real arithmetic (std::complex multiplies check for NaN and are
  // several times slower here).
  // Four interleaved recurrences (bins k, k+1, k+2, k+3 advance by step^4)
  // so the multiplies of neighbouring bins do not wait on each other.
  constexpr int kLanes = 4;
  const double angle = -2.0 * kPi * tau / double(mN);
  double pr[kLanes], pi[kLanes];
  for (int l = 0; l < kLanes; ++l) {
    pr[l] = std::cos(angle * l);
    pi[l] = std::sin(angle * l);
  }
  const double sr = std::cos(angle * kLanes), si = std::sin(angle * kLanes);
  double* out = reinterpret_cast<double*>(spectrum);  // std::complex<double> is two doubles
  const float* hv = h.values ? reinterpret_cast<const float*>(h.values) : nullptr;
  for (size_t k0 = 0; k0 < mBins; k0 += kLanes) {
    const int lanes = int(std::min<size_t>(kLanes, mBins - k0));
    for (int l = 0; l < lanes; ++l) {
      const size_t k = k0 + size_t(l);
      const int lb = mLowerBand[k];
      const double w = mLowerWeight[k];
      const double g = a.gain * (a.bandGain[lb] * w + (lb + 1 < kNumBands ? a.bandGain[lb + 1] * (1.0 - w) : 0.0));
      double vr = g * pr[l], vi = g * pi[l];
      if (hv) {
        const size_t i = mGridIndex[k];
        const double f = mGridFrac[k];
        const double fr = double(hv[2 * i]) * (1.0 - f) + double(hv[2 * i + 2]) * f;
        const double fi = double(hv[2 * i + 1]) * (1.0 - f) + double(hv[2 * i + 3]) * f;
        const double t = vr * fr - vi * fi;
        vi = vr * fi + vi * fr;
        vr = t;
      }
      out[2 * k] += vr;
      out[2 * k + 1] += vi;
    }
    for (int l = 0; l < kLanes; ++l) {
      const double npr = pr[l] * sr - pi[l] * si;
      pi[l] = pr[l] * si + pi[l] * sr;
      pr[l] = npr;
    }
    if ((k0 & 1023) == 1020) {  // keep |phase| = 1 over long recurrences
      for (int l = 0; l < kLanes; ++l) {
        const double m = std::sqrt(pr[l] * pr[l] + pi[l] * pi[l]);
        pr[l] /= m;
        pi[l] /= m;
      }
    }
  }
  // The Nyquist bin of a real signal must be real.
  if (mN % 2 == 0) spectrum[mBins - 1] = spectrum[mBins - 1].real();
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
  size_t n = 1024;
  while (n < mLength) n *= 2;
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
      if (c.seed == seed && c.stream == stream && c.n == n && c.fs == mFs) return c.bands;
  }
  FftrPtr forward(kiss_fftr_alloc(int(n), 0, nullptr, nullptr)), inverse(kiss_fftr_alloc(int(n), 1, nullptr, nullptr));
  auto bands = std::make_shared<Bands>(kNumBands, std::vector<float>(n, 0.0f));
  if (!forward || !inverse) return bands;  // allocation failed: silence rather than a crash
  const size_t bins = n / 2 + 1;
  std::vector<float> white = whiteNoise(seed, stream, n), time(n);
  std::vector<kiss_fft_cpx> spectrum(bins), filtered(bins);
  kiss_fftr(forward.get(), white.data(), spectrum.data());
  std::vector<BandArrayD> weights(bins);
  for (size_t k = 0; k < bins; ++k) weights[k] = noiseBandWeights(double(k) * mFs / double(n));
  std::vector<double> prefix(n + 1);
  for (int b = 0; b < kNumBands; ++b) {
    // Through sqrt(W); white noise keeps the mean of W over the circle.
    double power = 0;
    for (size_t k = 0; k < bins; ++k) {
      const double w = std::max(0.0, weights[k][b]);
      const float g = float(std::sqrt(w));
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
    const size_t half = std::max<size_t>(4, size_t(0.5 * kLevelWindowCycles * mFs / width));
    std::vector<float>& out = (*bands)[size_t(b)];
    for (size_t i = 0; i < n; ++i) {
      const size_t lo = i > half ? i - half : 0, hi = std::min(n, i + half + 1);
      const double rms2 = (prefix[hi] - prefix[lo]) / double(hi - lo);
      out[i] = rms2 > 0 ? float(double(time[i]) * scale * std::sqrt(power / rms2)) : 0.0f;
    }
  }
  std::lock_guard<std::mutex> lock(mutex);
  cache.insert(cache.begin(), Cached{seed, stream, n, mFs, bands});
  constexpr size_t kMaxCachedBytes = size_t(32) << 20;
  size_t bytes = 0;
  for (size_t i = 0; i < cache.size(); ++i) {
    bytes += cache[i].n * kNumBands * sizeof(float);
    if (i > 0 && (bytes > kMaxCachedBytes || i >= 6)) {
      cache.resize(i);
      break;
    }
  }
  return bands;
}

size_t noiseOffset(uint64_t seed, uint64_t noiseKey, size_t period) {
  if (noiseKey == 0 || period == 0) return 0;
  return size_t(mix64(mix64(seed) ^ mix64(noiseKey + 0x9E3779B97F4A7C15ULL)) % uint64_t(period));
}

bool SpectralSynth::shapeBand(const std::vector<float>& noise, size_t offset, const EnergyHistogram& h, int band,
                              const float* gain, std::vector<float>& shaped) const {
  const size_t period = noise.size();
  if (period == 0) return false;
  offset %= period;
  const double binSamples = h.binSeconds() * mFs;
  const size_t histBins = h.binCount();
  bool any = false;
  std::fill(shaped.begin(), shaped.end(), 0.0f);
  auto densityAt = [&](long bin) {
    if (bin < 0 || size_t(bin) >= histBins) return 0.0;
    const double d = h.energy(size_t(bin), band) / binSamples;
    return gain ? d * double(gain[bin]) : d;
  };
  // Energy density per sample, linear between bin centres: one segment per
  // pair of neighbouring centres, samples i with (i + 0.5) / binSamples - 0.5
  // in [j, j + 1).
  for (long j = -1; j < long(histBins); ++j) {
    const double d0 = densityAt(j), d1 = densityAt(j + 1);
    if (d0 <= 0 && d1 <= 0) continue;
    const double first = (double(j) + 0.5) * binSamples - 0.5, next = (double(j) + 1.5) * binSamples - 0.5;
    const size_t begin = size_t(std::max(0.0, std::ceil(first)));
    const size_t end = std::min(mLength, size_t(std::max(0.0, std::ceil(next))));
    for (size_t i = begin; i < end; ++i) {
      const double frac = (double(i) + 0.5) / binSamples - 0.5 - double(j);
      const double density = (1.0 - frac) * d0 + frac * d1;
      if (density > 0) {
        size_t at = i + offset;
        if (at >= period) at -= period;  // offset < period, i < length <= period
        shaped[i] = float(noise[at] * std::sqrt(density));
        any = true;
      }
    }
  }
  return any;
}

void SpectralSynth::addBand(int band, const std::vector<float>& shaped, const GridFilter& h,
                            std::complex<double>* spectrum) {
  if (h.values) prepareGrid(h.gridSize);
  kiss_fftr(mForward.get(), shaped.data(), mScratch.data());
  const std::vector<float>& w = mSqrtWeights[band];  // the second sqrt(W_band)
  for (size_t k = 0; k < mBins; ++k) {
    if (w[k] == 0.0f) continue;
    const std::complex<double> x(mScratch[k].r, mScratch[k].i);
    if (h.values)
      spectrum[k] += double(w[k]) * filterAt(h, k) * x;
    else
      spectrum[k] += double(w[k]) * x;
  }
}

void SpectralSynth::inverse(std::vector<std::complex<double>>& spectrum, std::vector<float>& out) {
  for (size_t k = 0; k < mBins; ++k) mScratch[k] = {float(spectrum[k].real()), float(spectrum[k].imag())};
  std::vector<float> time(mN);
  kiss_fftri(mInverse.get(), mScratch.data(), time.data());
  out.resize(mLength);
  const float scale = 1.0f / float(mN);  // KissFFT's inverse is unnormalised
  for (size_t i = 0; i < mLength; ++i) out[i] = time[i] * scale;
}

}  // namespace earshot::detail
