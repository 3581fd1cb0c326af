// IR synthesis: see ir_synthesis.h for the method and its references.
#include "earshot/ir/ir_synthesis.h"

#include <kiss_fftr.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <memory>
#include <string>

#include "earshot/core/math.h"
#include "earshot/core/random.h"
#include "earshot/ir/band_filter_bank.h"

namespace earshot {

namespace {

// Samples appended beyond the IR before the circular FFT, so that what the
// zero-phase band filters spread before time 0 (the 125 Hz band's response
// lasts ~0.1 s each way) wraps into the margin and not onto the IR's end, and
// the direct sound's sinc tail stays below 1 / (pi * margin).
constexpr double kMarginSeconds = 0.35;
// IRs longer than this are refused (10 minutes at 48 kHz).
constexpr size_t kMaxSamples = size_t(48000) * 600;

// Smallest n >= minimum with only factors 2, 3, 5 (fast for KissFFT), even.
size_t fastFftSize(size_t minimum) {
  size_t best = size_t(1) << 62;
  for (size_t p2 = 2; p2 < 2 * minimum + 2; p2 *= 2)
    for (size_t p3 = p2; p3 < 2 * minimum + 2; p3 *= 3)
      for (size_t p5 = p3; p5 < 2 * minimum + 2; p5 *= 5)
        if (p5 >= minimum && p5 < best) best = p5;
  return best;
}

struct FftrDeleter {
  void operator()(kiss_fftr_cfg c) const { kiss_fftr_free(c); }
};
using FftrPtr = std::unique_ptr<std::remove_pointer_t<kiss_fftr_cfg>, FftrDeleter>;

}  // namespace

Status validate(const IrSynthesisSettings& s) {
  if (!(s.sampleRateHz >= 8000.0 && s.sampleRateHz <= 384000.0))
    return invalidArgument("sample rate " + std::to_string(s.sampleRateHz) + " Hz is outside [8000, 384000]");
  if (!(s.lengthSeconds >= 0.0 && s.lengthSeconds <= 600.0))
    return invalidArgument("IR length " + std::to_string(s.lengthSeconds) + " s is outside [0, 600]");
  return Status::ok();
}

Arrival toArrival(const DirectPath& direct) {
  Arrival a;
  a.delaySeconds = direct.delaySeconds;
  a.gain = direct.audible ? direct.spreadingGain : 0.0;
  a.bandGain = direct.bandGain;
  a.direction = direct.directionFromListener;
  return a;
}

size_t irLengthSamples(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                       const IrSynthesisSettings& s) {
  if (s.lengthSeconds > 0) return std::max<size_t>(1, size_t(std::llround(s.lengthSeconds * s.sampleRateHz)));
  double end = 0.0;
  for (const Arrival& a : arrivals)
    if (a.gain != 0) end = std::max(end, a.delaySeconds);
  if (reflections) {
    long last = reflections->lastNonEmptyBin();
    if (last >= 0) end = std::max(end, double(last + 1) * reflections->binSeconds());
  }
  return size_t(std::ceil((end + 0.05) * s.sampleRateHz));
}

Result<AudioBuffer> synthesizeOmniIr(const DirectPath* direct, const EnergyHistogram* reflections,
                                     const IrSynthesisSettings& settings) {
  std::vector<Arrival> arrivals;
  if (direct && direct->audible) arrivals.push_back(toArrival(*direct));
  return synthesizeOmniIr(arrivals, reflections, settings);
}

Result<AudioBuffer> synthesizeOmniIr(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                                     const IrSynthesisSettings& settings) {
  EARSHOT_RETURN_IF_ERROR(validate(settings));
  for (const Arrival& a : arrivals)
    if (!std::isfinite(a.delaySeconds) || a.delaySeconds < 0 || !std::isfinite(a.gain))
      return invalidArgument("arrival with delay " + std::to_string(a.delaySeconds) + " s, gain " + std::to_string(a.gain));
  const double fs = settings.sampleRateHz;
  const size_t length = irLengthSamples(arrivals, reflections, settings);
  if (length > kMaxSamples) return outOfRange("IR of " + std::to_string(length) + " samples is over the limit");
  const size_t n = fastFftSize(length + size_t(kMarginSeconds * fs));
  const size_t bins = n / 2 + 1;

  FftrPtr fwd(kiss_fftr_alloc(int(n), 0, nullptr, nullptr));
  FftrPtr inv(kiss_fftr_alloc(int(n), 1, nullptr, nullptr));
  if (!fwd || !inv) return Status(StatusCode::kInternal, "FFT allocation failed");

  // Band weights per FFT bin, [band][bin].
  std::vector<std::vector<float>> weights(kNumBands, std::vector<float>(bins));
  for (size_t k = 0; k < bins; ++k) {
    BandArrayD w = bandWeights(double(k) * fs / double(n));
    for (int b = 0; b < kNumBands; ++b) weights[b][k] = float(w[b]);
  }

  std::vector<std::complex<double>> spectrum(bins, 0.0);

  // Discrete arrivals: exact fractional delays per band. At most two band
  // weights are non-zero at any frequency: precompute the lower one.
  if (!arrivals.empty()) {
    std::vector<uint8_t> lowerBand(bins);
    std::vector<double> lowerWeight(bins);
    for (size_t k = 0; k < bins; ++k) {
      int lb = kNumBands - 1;
      for (int b = 0; b < kNumBands; ++b)
        if (weights[b][k] > 0) {
          lb = b;
          break;
        }
      lowerBand[k] = uint8_t(lb);
      lowerWeight[k] = weights[lb][k];
    }
    for (const Arrival& a : arrivals) {
      if (a.gain == 0) continue;
      const double tau = a.delaySeconds * fs;  // samples
      // exp(-j 2 pi k tau / n) by recurrence: one complex multiply per bin.
      const std::complex<double> step = std::polar(1.0, -2.0 * kPi * tau / double(n));
      std::complex<double> phase = 1.0;
      for (size_t k = 0; k < bins; ++k) {
        const int lb = lowerBand[k];
        const double w = lowerWeight[k];
        const double g = a.bandGain[lb] * w + (lb + 1 < kNumBands ? a.bandGain[lb + 1] * (1.0 - w) : 0.0);
        spectrum[k] += a.gain * g * phase;
        phase *= step;
        if ((k & 1023) == 1023) phase /= std::abs(phase);  // keep |phase| = 1 over long recurrences
      }
    }
    // The Nyquist bin of a real signal must be real.
    if (n % 2 == 0) spectrum[bins - 1] = spectrum[bins - 1].real();
  }

  // Reflections: per band, noise x sqrt(energy density), then W_b.
  if (reflections && reflections->lastNonEmptyBin() >= 0) {
    const double binSamples = reflections->binSeconds() * fs;
    const size_t histBins = reflections->binCount();
    std::vector<float> noise(length);
    Pcg32 rng(settings.seed, 0x1F2E3D4CULL);
    for (size_t i = 0; i < length; i += 2) {  // Box-Muller, two at a time
      double u1 = std::max(rng.uniformDouble(), 1e-300), u2 = rng.uniformDouble();
      double r = std::sqrt(-2.0 * std::log(u1));
      noise[i] = float(r * std::cos(2 * kPi * u2));
      if (i + 1 < length) noise[i + 1] = float(r * std::sin(2 * kPi * u2));
    }
    std::vector<float> shaped(n);
    std::vector<kiss_fft_cpx> bandSpectrum(bins);
    for (int b = 0; b < kNumBands; ++b) {
      bool any = false;
      std::fill(shaped.begin(), shaped.end(), 0.0f);
      for (size_t i = 0; i < length; ++i) {
        // Energy density per sample, linear between bin centres.
        const double x = (double(i) + 0.5) / binSamples - 0.5;
        const double xf = std::floor(x);
        const long j = long(xf);
        const double frac = x - xf;
        auto densityAt = [&](long bin) {
          return (bin < 0 || size_t(bin) >= histBins) ? 0.0 : reflections->energy(size_t(bin), b) / binSamples;
        };
        const double density = (1.0 - frac) * densityAt(j) + frac * densityAt(j + 1);
        if (density > 0) {
          shaped[i] = float(noise[i] * std::sqrt(density));
          any = true;
        }
      }
      if (!any) continue;
      kiss_fftr(fwd.get(), shaped.data(), bandSpectrum.data());
      for (size_t k = 0; k < bins; ++k)
        spectrum[k] += double(weights[b][k]) * std::complex<double>(bandSpectrum[k].r, bandSpectrum[k].i);
    }
  }

  std::vector<kiss_fft_cpx> spec(bins);
  for (size_t k = 0; k < bins; ++k) spec[k] = {float(spectrum[k].real()), float(spectrum[k].imag())};
  std::vector<float> time(n);
  kiss_fftri(inv.get(), spec.data(), time.data());
  AudioBuffer out(1, length, fs);
  const float scale = 1.0f / float(n);  // KissFFT's inverse is unnormalised
  for (size_t i = 0; i < length; ++i) out.channels[0][i] = time[i] * scale;
  return out;
}

}  // namespace earshot
