// Third-octave IRs: three shifted octave passes combined through zero-phase
// crossovers (third_octave.h).
#include "earshot/ir/third_octave.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <vector>

#include "earshot/core/math.h"
#include "spectral_synth.h"

namespace earshot {

namespace {

// Raised-cosine step from 0 to 1 across the crossover between third octaves
// k and k + 1 (at the geometric mean of their centres); 1 below band 0's
// crossover side, 0 above the top band's.
double thirdStep(int k, double log2f) {
  if (k < 0) return 1.0;
  if (k >= kNumThirdOctaveBands - 1) return 0.0;
  const double x0 = std::log2(125.0) + (double(k) - 1.0) / 3.0 + 1.0 / 6.0;
  const double u = (log2f - x0) / kThirdOctaveCrossoverOctaves;
  if (u <= -0.5) return 0.0;
  if (u >= 0.5) return 1.0;
  return 0.5 * (1.0 + std::sin(kPi * u));
}

double msSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

// A per-band directivity table at a pass's bands (linear in log-frequency,
// held beyond the ends, as materials are).
Directivity shiftedDirectivity(const Directivity& d, double octaves) {
  if (!d.perBand) return d;
  Directivity out = d;
  for (int b = 0; b < kNumBands; ++b) {
    const double x = double(b) + octaves;  // position on the octave axis
    if (x <= 0) {
      out.bandAlpha[size_t(b)] = d.bandAlpha[0];
    } else if (x >= double(kNumBands - 1)) {
      out.bandAlpha[size_t(b)] = d.bandAlpha[size_t(kNumBands - 1)];
    } else {
      const size_t i = size_t(x);
      const double t = x - double(i);
      out.bandAlpha[size_t(b)] = d.bandAlpha[i] + t * (d.bandAlpha[i + 1] - d.bandAlpha[i]);
    }
  }
  return out;
}

}  // namespace

double thirdOctaveBandWeight(int j, double hz) {
  if (j < 0 || j >= kNumThirdOctaveBands) return 0.0;
  const double lf = hz > 0 ? std::log2(hz) : -1e9;
  return thirdStep(j - 1, lf) - thirdStep(j, lf);
}

double thirdOctavePassWeight(int pass, double hz) {
  double w = 0;
  for (int j = pass; j < kNumThirdOctaveBands; j += kThirdOctavePasses) w += thirdOctaveBandWeight(j, hz);
  return w;
}

Result<ThirdOctaveIrResult> computeIrThirdOctave(const RayTracer& tracer, const MaterialTable& materials,
                                                 const Vec3d& source, const Vec3d& listener,
                                                 const OmniIrSettings& settings, ThreadPool& pool,
                                                 const BinauralReceiver* binaural, const AmbisonicReceiver* ambisonic) {
  if (settings.air.bandShiftOctaves != 0.0)
    return invalidArgument("a third-octave IR sets each pass's band shift itself; air.bandShiftOctaves must be 0");
  ThirdOctaveIrResult out;
  for (int p = 0; p < kThirdOctavePasses; ++p) {
    const double shift = thirdOctavePassShift(p);
    OmniIrSettings s = settings;
    s.air.bandShiftOctaves = shift;
    s.directivity = shiftedDirectivity(settings.directivity, shift);
    MaterialTable shifted;  // the unshifted pass reads the caller's table, not a copy
    if (shift != 0.0) shifted = materials.atBandShift(shift);
    auto r = computeIr(tracer, shift != 0.0 ? shifted : materials, source, listener, s, pool, binaural, ambisonic);
    if (!r.isOk()) return r.status();
    out.passes[size_t(p)] = std::move(r.value());
  }

  // Combined per channel in one transform of the longest IR plus a guard
  // for the crossovers' ringing (a sixth of an octave at 111 Hz is ~13 Hz
  // wide: ~0.1 s; what rings before time 0 wraps into the guard and is
  // dropped, as is what rings past the end).
  const auto t = std::chrono::steady_clock::now();
  const double fs = settings.sampleRateHz;
  size_t length = 0;
  for (const OmniIrResult& r : out.passes) length = std::max(length, r.ir.frameCount());
  const size_t channels = out.passes[0].ir.channelCount();
  out.ir = AudioBuffer(channels, length, fs);
  if (length == 0) return out;
  const size_t guard = size_t(0.25 * fs);
  size_t n = detail::fastFftSize(length + guard);
  n += n % 2;  // a real transform of even size
  const size_t bins = n / 2 + 1;
  detail::FftrPtr forward(kiss_fftr_alloc(int(n), 0, nullptr, nullptr));
  detail::FftrPtr inverse(kiss_fftr_alloc(int(n), 1, nullptr, nullptr));
  if (!forward || !inverse) return Status(StatusCode::kInternal, "FFT allocation failed");
  std::vector<std::array<float, kThirdOctavePasses>> weight(bins);
  for (size_t k = 0; k < bins; ++k)
    for (int p = 0; p < kThirdOctavePasses; ++p)
      weight[k][size_t(p)] = float(thirdOctavePassWeight(p, double(k) * fs / double(n)));
  std::vector<float> time(n);
  std::vector<kiss_fft_cpx> spectrum(bins), sum(bins);
  for (size_t c = 0; c < channels; ++c) {
    std::fill(sum.begin(), sum.end(), kiss_fft_cpx{0.0f, 0.0f});
    for (int p = 0; p < kThirdOctavePasses; ++p) {
      const AudioBuffer& ir = out.passes[size_t(p)].ir;
      std::fill(time.begin(), time.end(), 0.0f);
      if (c < ir.channelCount()) std::copy(ir.channels[c].begin(), ir.channels[c].end(), time.begin());
      kiss_fftr(forward.get(), time.data(), spectrum.data());
      for (size_t k = 0; k < bins; ++k) {
        const float w = weight[k][size_t(p)];
        sum[k].r += w * spectrum[k].r;
        sum[k].i += w * spectrum[k].i;
      }
    }
    kiss_fftri(inverse.get(), sum.data(), time.data());
    const float scale = 1.0f / float(n);  // KissFFT's inverse is unnormalised
    float* dst = out.ir.channels[c].data();
    for (size_t i = 0; i < length; ++i) dst[i] = time[i] * scale;
  }
  out.combineMs = msSince(t);
  return out;
}

ThirdOctaveDecay tracedDecay(const ThirdOctaveIrResult& result) {
  ThirdOctaveDecay d;
  for (int p = 0; p < kThirdOctavePasses; ++p) {
    const TracedDecay pd = tracedDecay(result.passes[size_t(p)]);
    for (int b = 0; b < kNumBands; ++b) {
      const size_t j = size_t(3 * b + p);
      d.edtSeconds[j] = pd.edtSeconds[size_t(b)];
      d.t20Seconds[j] = pd.t20Seconds[size_t(b)];
      d.t30Seconds[j] = pd.t30Seconds[size_t(b)];
    }
  }
  return d;
}

}  // namespace earshot
