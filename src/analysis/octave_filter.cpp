// Zero-phase octave-band filter: Butterworth high-pass + low-pass biquads
// (bilinear transform with pre-warping; R. Bristow-Johnson, "Cookbook formulae
// for audio EQ biquad filter coefficients"), applied forward and backward
// (Gustafsson 1996 style forward-backward filtering without initial-state
// matching: the input is zero-padded by the filter's ringing length instead).
#include "earshot/analysis/octave_filter.h"

#include <array>
#include <cmath>
#include <limits>

#include "analysis_internal.h"

#include <kiss_fftr.h>

#include <algorithm>
#include <memory>
#include <mutex>
#include <vector>

namespace earshot::analysis {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Cut-off widening so that the forward-backward (squared) response of a
// 4th-order Butterworth is -3 dB at the nominal edge: (fe/fc)^8 = sqrt(2) - 1.
const double kEdgeFactor = std::pow(std::sqrt(2.0) - 1.0, 1.0 / 8.0);  // 0.8956
// Q of the two sections of a 4th-order Butterworth: 1 / (2 cos(k pi / 8)), k = 1, 3.
constexpr std::array<double, 2> kButterworthQ = {0.54119610014619698, 1.3065629648763766};

struct Biquad {
  double b0, b1, b2, a1, a2;  // normalised by a0
};

Biquad makeSection(double cutoffHz, double rateHz, double q, bool highPass) {
  const double w0 = 2.0 * kPi * cutoffHz / rateHz;
  const double c = std::cos(w0), alpha = std::sin(w0) / (2.0 * q);
  const double a0 = 1.0 + alpha;
  Biquad s{};
  if (highPass) {
    s.b0 = (1.0 + c) / 2.0 / a0;
    s.b1 = -(1.0 + c) / a0;
  } else {
    s.b0 = (1.0 - c) / 2.0 / a0;
    s.b1 = (1.0 - c) / a0;
  }
  s.b2 = s.b0;
  s.a1 = -2.0 * c / a0;
  s.a2 = (1.0 - alpha) / a0;
  return s;
}

// Cut-offs are set on the pre-warped axis (Omega = tan(pi f / fs)), where
// the digital response equals the analog Butterworth's: so the nominal edges
// get exactly the intended attenuation even close to Nyquist.
// `bandwidthOctaves` wide (1: an octave, 1/3: a third octave): edges at
// centre x 2^(-+bandwidth / 2).
std::array<Biquad, 4> designBand(double rateHz, double centerHz, double bandwidthOctaves = 1.0) {
  auto warp = [&](double f) { return std::tan(kPi * f / rateHz); };
  auto unwarp = [&](double w) { return std::atan(w) * rateHz / kPi; };
  const double half = bandwidthOctaves == 1.0 ? std::sqrt(2.0) : std::exp2(0.5 * bandwidthOctaves);
  const double lowEdge = centerHz / half, highEdge = centerHz * half;
  const double hp = unwarp(warp(lowEdge) * kEdgeFactor), lp = unwarp(warp(highEdge) / kEdgeFactor);
  return {makeSection(hp, rateHz, kButterworthQ[0], true), makeSection(hp, rateHz, kButterworthQ[1], true),
          makeSection(lp, rateHz, kButterworthQ[0], false), makeSection(lp, rateHz, kButterworthQ[1], false)};
}

// A low-pass alone, in the same four-section form (the last two sections pass
// the signal through), with the same cut-off widening: the forward-backward
// response is -3 dB at cutoffHz.
std::array<Biquad, 4> designLowPass(double rateHz, double cutoffHz) {
  const double lp = std::atan(std::tan(kPi * cutoffHz / rateHz) / kEdgeFactor) * rateHz / kPi;
  const Biquad identity{1.0, 0.0, 0.0, 0.0, 0.0};
  return {makeSection(lp, rateHz, kButterworthQ[0], false), makeSection(lp, rateHz, kButterworthQ[1], false),
          identity, identity};
}

// One pass of the cascade over y[0..n), in place, forward or backward. All
// four sections advance per sample (transposed direct form II) so the CPU can
// overlap their dependency chains across samples.
// One transposed direct-form II biquad step.
inline double step(const Biquad& s, double in, double& z1, double& z2) {
  const double out = s.b0 * in + z1;
  z1 = s.b1 * in - s.a1 * out + z2;
  z2 = s.b2 * in - s.a2 * out;
  return out;
}

void runCascade(const std::array<Biquad, 4>& sections, double* y, size_t n, bool backward) {
  const Biquad s0 = sections[0], s1 = sections[1], s2 = sections[2], s3 = sections[3];
  double a1 = 0, a2 = 0, b1 = 0, b2 = 0, c1 = 0, c2 = 0, d1 = 0, d2 = 0;
  for (size_t k = 0; k < n; ++k) {
    double& v = y[backward ? n - 1 - k : k];
    v = step(s3, step(s2, step(s1, step(s0, v, a1, a2), b1, b2), c1, c2), d1, d2);
  }
}

// Two independent cascades (two bands) in one loop: twice the independent work
// per iteration, which roughly doubles throughput on latency-bound biquads.
void runCascadePair(const std::array<Biquad, 4>& sa, const std::array<Biquad, 4>& sb, double* ya, double* yb,
                    size_t n, bool backward) {
  const Biquad a0 = sa[0], a1 = sa[1], a2 = sa[2], a3 = sa[3];
  const Biquad b0 = sb[0], b1 = sb[1], b2 = sb[2], b3 = sb[3];
  double p0 = 0, p1 = 0, q0 = 0, q1 = 0, r0 = 0, r1 = 0, s0 = 0, s1 = 0;  // band a states
  double t0 = 0, t1 = 0, u0 = 0, u1 = 0, v0 = 0, v1 = 0, w0 = 0, w1 = 0;  // band b states
  for (size_t k = 0; k < n; ++k) {
    const size_t i = backward ? n - 1 - k : k;
    ya[i] = step(a3, step(a2, step(a1, step(a0, ya[i], p0, p1), q0, q1), r0, r1), s0, s1);
    yb[i] = step(b3, step(b2, step(b1, step(b0, yb[i], t0, t1), u0, u1), v0, v1), w0, w1);
  }
}

}  // namespace

void octaveBandFilterPairInto(const float* signal, size_t count, double rateHz, double centerA, double centerB,
                              size_t guard, std::vector<double>& outA, std::vector<double>& outB) {
  outA.assign(guard + count + guard, 0.0);
  for (size_t i = 0; i < count; ++i) outA[guard + i] = signal[i];
  outB = outA;
  const auto sa = designBand(rateHz, centerA), sb = designBand(rateHz, centerB);
  runCascadePair(sa, sb, outA.data(), outB.data(), outA.size(), false);
  runCascadePair(sa, sb, outA.data(), outB.data(), outA.size(), true);
}

bool fractionalOctaveBandAvailable(double rateHz, double centerHz, double bandwidthOctaves) {
  if (bandwidthOctaves == 1.0) return octaveBandAvailable(rateHz, centerHz);
  return bandwidthOctaves > 0.0 && bandwidthOctaves < 1.0 && centerHz > 0.0 && rateHz > 0.0 &&
         centerHz * std::exp2(0.5 * bandwidthOctaves) < 0.45 * rateHz;
}

bool octaveBandAvailable(double rateHz, double centerHz) {
  // The upper edge must lie below 0.45 fs so that its widened low-pass cut-off
  // (pre-warped) is a valid frequency below Nyquist.
  return centerHz > 0.0 && rateHz > 0.0 && centerHz * std::sqrt(2.0) < 0.45 * rateHz;
}

namespace {

// See octaveBandGuardSamples; the convergence test runs over periods of
// `slowestHz`, about the lowest cut-off of the cascade (which rings longest);
// `outside` is the energy fraction left beyond the guard.
size_t guardSamples(const std::array<Biquad, 4>& sections, double rateHz, double slowestHz, double outside) {
  // The zero-phase kernel is the autocorrelation of the causal response h, so
  // it spans +-len(h); len(h) is where h's remaining energy drops below -50 dB.
  // h rings at ~centerHz and decays exponentially: its total is reached (to
  // 1e-9) once a whole period of the slowest cut-off adds < 1e-9 of the
  // energy so far. Then a second pass finds the -50 dB point. No allocation.
  const size_t maxLen = size_t(std::ceil(rateHz * 0.5)) + 1;
  const size_t period = std::max<size_t>(8, size_t(rateHz / slowestHz));
  auto run = [&](double stopAt, bool findTotal, size_t* reached) {
    std::array<double, 4> z1{}, z2{};
    double energy = 0.0, blockEnergy = 0.0;
    for (size_t k = 0; k < maxLen; ++k) {
      double v = k == 0 ? 1.0 : 0.0;
      for (size_t s = 0; s < sections.size(); ++s) {
        const Biquad& q = sections[s];
        const double out = q.b0 * v + z1[s];
        z1[s] = q.b1 * v - q.a1 * out + z2[s];
        z2[s] = q.b2 * v - q.a2 * out;
        v = out;
      }
      energy += v * v;
      blockEnergy += v * v;
      if (!findTotal && energy >= stopAt) {
        *reached = k + 1;
        return energy;
      }
      if (findTotal && (k + 1) % period == 0) {
        if (blockEnergy < 1e-9 * energy) break;
        blockEnergy = 0.0;
      }
    }
    *reached = maxLen;
    return energy;
  };
  size_t reached = 0;
  const double total = run(0.0, true, &reached);
  run((1.0 - outside) * total, false, &reached);
  return reached;
}

// signal zero-padded by `guard` on both sides into `out`, then filtered
// forward and backward.
void filterZeroPhaseInto(const std::array<Biquad, 4>& sections, size_t guard, const float* signal, size_t count,
                         std::vector<double>& out) {
  out.assign(guard + count + guard, 0.0);
  for (size_t i = 0; i < count; ++i) out[guard + i] = signal[i];
  runCascade(sections, out.data(), out.size(), false);
  runCascade(sections, out.data(), out.size(), true);
}

}  // namespace

namespace {

// A fractional octave's zero-phase power response on the pre-warped axis
// Omega = tan(pi f / fs): 1 / (1 + x^12), x = (Omega^2 - Omega0^2) /
// (Omega B), Omega0^2 = Omega_l Omega_h, B = Omega_h - Omega_l: a Butterworth
// band-pass's shape (x = -+1 at the edges: -3 dB; 0 dB at the centre) with
// the skirts of a sixth-order band-pass run forward and backward (IEC 61260
// class 1 filters are third-order prototypes: ~ -18 dB at a neighbouring
// third octave's centre, -36 dB run both ways). Returns the amplitude
// weight, sqrt of that.
double fractionalWeight(double f, double rateHz, double centerHz, double bandwidthOctaves) {
  if (!(f > 0.0) || f >= 0.5 * rateHz) return 0.0;
  auto warp = [&](double hz) { return std::tan(kPi * hz / rateHz); };
  const double wl = warp(centerHz * std::exp2(-0.5 * bandwidthOctaves)), wh = warp(centerHz * std::exp2(0.5 * bandwidthOctaves));
  const double w = warp(f);
  const double x = (w * w - wl * wh) / (w * (wh - wl));
  const double x2 = x * x, x4 = x2 * x2;
  return std::sqrt(1.0 / (1.0 + x4 * x4 * x4));
}

// The kernel's extent (samples on each side) holding all but `outside` of
// its energy, from the weights on an n-point grid.
size_t fractionalGuard(double rateHz, double centerHz, double bandwidthOctaves, double outside) {
  constexpr size_t n = size_t(1) << 17;  // 2.7 s at 48 kHz: far beyond the kernel
  std::unique_ptr<kiss_fftr_state, decltype(&kiss_fftr_free)> inv(kiss_fftr_alloc(int(n), 1, nullptr, nullptr),
                                                                   &kiss_fftr_free);
  if (!inv) return size_t(rateHz);  // allocation failed: a second of guard
  std::vector<kiss_fft_cpx> spec(n / 2 + 1);
  for (size_t k = 0; k <= n / 2; ++k)
    spec[k] = {float(fractionalWeight(double(k) * rateHz / double(n), rateHz, centerHz, bandwidthOctaves)), 0.0f};
  std::vector<float> h(n);
  kiss_fftri(inv.get(), spec.data(), h.data());
  double total = 0;
  for (float v : h) total += double(v) * v;
  // Energy beyond +-m, from the ends inwards (the kernel is symmetric).
  double beyond = 0;
  for (size_t m = n / 2; m > 0; --m) {
    beyond += double(h[m]) * h[m] + (m != n - m ? double(h[n - m]) * h[n - m] : 0.0);
    if (beyond > outside * total) return std::min(n / 2, m + 1);
  }
  return 1;
}

}  // namespace

size_t fractionalOctaveBandGuardSamples(double rateHz, double centerHz, double bandwidthOctaves) {
  if (bandwidthOctaves == 1.0) return octaveBandGuardSamples(rateHz, centerHz);
  // Each guard is an inverse transform of 2^17 points: kept for the bands
  // in use (21 third octaves at a rate or two), so that analysing many IRs
  // pays for it once.
  struct Entry {
    double rate, center, bandwidth;
    size_t guard;
  };
  static std::mutex mutex;
  static std::vector<Entry> cache;
  {
    std::lock_guard<std::mutex> lock(mutex);
    for (const Entry& e : cache)
      if (e.rate == rateHz && e.center == centerHz && e.bandwidth == bandwidthOctaves) return e.guard;
  }
  const size_t guard = fractionalGuard(rateHz, centerHz, bandwidthOctaves, 1e-5);
  std::lock_guard<std::mutex> lock(mutex);
  if (cache.size() >= 128) cache.erase(cache.begin());
  cache.push_back({rateHz, centerHz, bandwidthOctaves, guard});
  return guard;
}

void fractionalOctaveBandFilterInto(const float* signal, size_t count, double rateHz, double centerHz,
                                    double bandwidthOctaves, std::vector<double>& out, size_t* preGuardSamples) {
  if (bandwidthOctaves == 1.0) {
    octaveBandFilterInto(signal, count, rateHz, centerHz, out, preGuardSamples);
    return;
  }
  // In the frequency domain: zero phase by construction, the weights
  // applied to the zero-padded signal (the guards hold the kernel's
  // ringing; the transform is long enough that nothing wraps).
  const size_t guard = fractionalOctaveBandGuardSamples(rateHz, centerHz, bandwidthOctaves);
  if (preGuardSamples) *preGuardSamples = guard;
  size_t n = 2;
  while (n < count + 4 * guard) n *= 2;
  std::unique_ptr<kiss_fftr_state, decltype(&kiss_fftr_free)> fwd(kiss_fftr_alloc(int(n), 0, nullptr, nullptr),
                                                                   &kiss_fftr_free),
      inv(kiss_fftr_alloc(int(n), 1, nullptr, nullptr), &kiss_fftr_free);
  out.assign(guard + count + guard, 0.0);
  if (!fwd || !inv) return;  // allocation failed: silence
  std::vector<float> x(n, 0.0f);
  std::copy(signal, signal + count, x.begin() + std::ptrdiff_t(2 * guard));
  std::vector<kiss_fft_cpx> spec(n / 2 + 1);
  kiss_fftr(fwd.get(), x.data(), spec.data());
  for (size_t k = 0; k <= n / 2; ++k) {
    const float w = float(fractionalWeight(double(k) * rateHz / double(n), rateHz, centerHz, bandwidthOctaves) / double(n));
    spec[k].r *= w;
    spec[k].i *= w;
  }
  kiss_fftri(inv.get(), spec.data(), x.data());
  for (size_t i = 0; i < out.size(); ++i) out[i] = x[guard + i];
}

size_t octaveBandGuardSamples(double rateHz, double centerHz) {
  // The high-pass cut-off (below the centre) rings longest.
  return guardSamples(designBand(rateHz, centerHz), rateHz, 0.5 * centerHz, 1e-5);
}

void octaveBandFilterInto(const float* signal, size_t count, double rateHz, double centerHz,
                          std::vector<double>& out, size_t* preGuardSamples) {
  const size_t guard = octaveBandGuardSamples(rateHz, centerHz);
  if (preGuardSamples) *preGuardSamples = guard;
  filterZeroPhaseInto(designBand(rateHz, centerHz), guard, signal, count, out);
}

namespace detail {

size_t zeroPhaseLowPassInto(const float* signal, size_t count, double rateHz, double cutoffHz,
                            std::vector<double>& out) {
  const auto sections = designLowPass(rateHz, cutoffHz);
  const size_t guard = guardSamples(sections, rateHz, cutoffHz, 1e-12);
  filterZeroPhaseInto(sections, guard, signal, count, out);
  return guard;
}

}  // namespace detail

std::vector<double> octaveBandFilter(const float* signal, size_t count, double rateHz, double centerHz,
                                     size_t* preGuardSamples) {
  std::vector<double> y;
  octaveBandFilterInto(signal, count, rateHz, centerHz, y, preGuardSamples);
  return y;
}

}  // namespace earshot::analysis
