#pragma once
// Shared by the band-exactness tests (band_exact_test.cpp, octaves;
// third_octave_test.cpp, third octaves): a band of an IR taken through a
// zero-phase mask on the frequency axis, the traced energy smoothed by the
// same mask's energy response, and EDT / T20 of an energy signal.
#include <kiss_fftr.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <vector>

#include "earshot/analysis/room_acoustics.h"
#include "earshot/core/math.h"

namespace earshot::testing {

/** Raised-cosine from 0 (at lo) to 1 (at lo + width), on log2 frequency. */
inline double rise(double log2f, double lo, double width) {
  const double u = (log2f - lo) / width;
  if (u <= 0) return 0.0;
  if (u >= 1) return 1.0;
  return 0.5 - 0.5 * std::cos(kPi * u);
}

/** x through the zero-phase mask m(log2 f) (log2 f = -1e9 at 0 Hz),
 *  zero-padded so that the mask's ringing does not wrap onto the tail. */
inline std::vector<float> masked(const std::vector<float>& x, double fs, const std::function<double(double)>& mask) {
  size_t n = 1024;
  while (n < 2 * x.size()) n *= 2;
  std::unique_ptr<kiss_fftr_state, decltype(&kiss_fftr_free)> fwd(kiss_fftr_alloc(int(n), 0, nullptr, nullptr),
                                                                    &kiss_fftr_free),
      inv(kiss_fftr_alloc(int(n), 1, nullptr, nullptr), &kiss_fftr_free);
  std::vector<float> in(n, 0.0f), out(n);
  std::copy(x.begin(), x.end(), in.begin());
  std::vector<kiss_fft_cpx> spec(n / 2 + 1);
  kiss_fftr(fwd.get(), in.data(), spec.data());
  for (size_t k = 0; k < spec.size(); ++k) {
    const double f = double(k) * fs / double(n);
    const double m = mask(f > 0 ? std::log2(f) : -1e9);
    spec[k].r = float(spec[k].r * m / double(n));
    spec[k].i = float(spec[k].i * m / double(n));
  }
  kiss_fftri(inv.get(), spec.data(), out.data());
  out.resize(x.size());
  return out;
}

/** `traced` (energy per histogram bin at binRate) smoothed by the mask's
 *  own energy response (zero-phase, so centred; measured on an impulse in
 *  the middle of impulseSeconds), over +-halfSeconds: what the mask does to
 *  an energy envelope. */
inline void smoothByMaskResponse(std::vector<double>& traced, double binRate, double fs, double impulseSeconds,
                                 double halfSeconds, const std::function<double(double)>& mask) {
  const size_t len = size_t(impulseSeconds * fs), mid = len / 2;
  std::vector<float> impulse(len, 0.0f);
  impulse[mid] = 1.0f;
  const std::vector<float> hm = masked(impulse, fs, mask);
  const long half = long(halfSeconds * binRate);
  std::vector<double> kernel(size_t(2 * half + 1), 0.0);
  double sum = 0;
  for (size_t i = 0; i < len; ++i) {
    const long bin = std::lround((double(i) - double(mid)) / fs * binRate);
    if (bin < -half || bin > half) continue;
    kernel[size_t(bin + half)] += double(hm[i]) * hm[i];
    sum += double(hm[i]) * hm[i];
  }
  std::vector<double> smooth(traced.size(), 0.0);
  for (size_t i = 0; i < traced.size(); ++i)
    for (long k = -half; k <= half; ++k) {
      const long j = long(i) + k;
      if (j >= 0 && size_t(j) < traced.size()) smooth[size_t(j)] += traced[i] * kernel[size_t(k + half)] / sum;
    }
  traced.swap(smooth);
}

/** EDT and T20 of an energy signal (Schroeder, no noise treatment). */
inline analysis::BandMetrics energyMetrics(const std::vector<double>& e, double rateHz) {
  std::vector<float> amplitude(e.size());
  for (size_t i = 0; i < e.size(); ++i) amplitude[i] = float(std::sqrt(e[i]));
  return analysis::analyzeBandSignal(amplitude.data(), amplitude.size(), rateHz, -1, 0,
                                     analysis::NoiseTreatment::kNone);
}

}  // namespace earshot::testing
