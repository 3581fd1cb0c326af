// Band-limited (Whittaker-Shannon) interpolation with a Kaiser-windowed sinc,
// tabulated and linearly interpolated (J. O. Smith and P. Gossett, "A flexible
// sampling-rate conversion method", ICASSP 1984; J. F. Kaiser and R. W.
// Schafer, "On the use of the I0-sinh window for spectrum analysis", IEEE
// Trans. ASSP 28(1), 1980). When downsampling, the sinc is stretched by
// kappa = 0.95 * fsOut / fsIn so its cutoff sits below the output Nyquist
// frequency; the sum of a stretched kernel over the input grid is 1 / kappa,
// hence the gain kappa for signals and kappa * fsIn / fsOut for filter taps.
#include "earshot/dsp/resample.h"

#include <algorithm>
#include <cmath>

#include <soxr.h>

#include "earshot/core/math.h"

namespace earshot {

namespace {

double besselI0(double x) {
  // Power series; converges quickly for the arguments used (<= 9).
  double sum = 1.0, term = 1.0, q = x * x / 4.0;
  for (int k = 1; k < 60; ++k) {
    term *= q / (double(k) * double(k));
    sum += term;
    if (term < sum * 1e-17) break;
  }
  return sum;
}

template <class T>
double interpolateImpl(const T* x, std::size_t n, double t) {
  const SincKernel& k = SincKernel::instance();
  const double z = SincKernel::kZeroCrossings;
  long lo = static_cast<long>(std::ceil(t - z));
  long hi = static_cast<long>(std::floor(t + z));
  lo = std::max(lo, 0L);
  hi = std::min(hi, static_cast<long>(n) - 1);
  double sum = 0.0;
  for (long i = lo; i <= hi; ++i) sum += double(x[i]) * k.value(t - double(i));
  return sum;
}

double cutoffStretch(double fsIn, double fsOut) {
  return fsOut < fsIn ? SincKernel::kDownsampleCutoff * fsOut / fsIn : 1.0;
}

// out[m] = gain * sum_i x[i] * sinc(kappa * (t_m - i)), t_m = m * fsIn / fsOut + startIn.
void resampleCore(const float* x, std::size_t n, double fsIn, double fsOut, double startIn, double gain,
                  float* out, std::size_t outLength) {
  const SincKernel& k = SincKernel::instance();
  const double ratio = fsIn / fsOut;  // input samples per output sample
  const double kappa = cutoffStretch(fsIn, fsOut);
  const double half = SincKernel::kZeroCrossings / kappa;
  for (std::size_t m = 0; m < outLength; ++m) {
    double t = double(m) * ratio + startIn;
    long lo = std::max(0L, static_cast<long>(std::ceil(t - half)));
    long hi = std::min(static_cast<long>(n) - 1, static_cast<long>(std::floor(t + half)));
    double sum = 0.0;
    for (long i = lo; i <= hi; ++i) sum += double(x[i]) * k.value(kappa * (t - double(i)));
    out[m] = static_cast<float>(gain * sum);
  }
}

}  // namespace

SincKernel::SincKernel() : mTable(std::size_t(kZeroCrossings) * kPhases + 2, 0.0) {
  double i0b = besselI0(kBeta);
  for (std::size_t i = 0; i <= std::size_t(kZeroCrossings) * kPhases; ++i) {
    double x = double(i) / kPhases;
    double u = x / kZeroCrossings;
    double sinc = i == 0 ? 1.0 : std::sin(kPi * x) / (kPi * x);
    if (i % kPhases == 0 && i != 0) sinc = 0.0;  // exact zeros at integers
    double w = besselI0(kBeta * std::sqrt(std::max(0.0, 1.0 - u * u))) / i0b;
    mTable[i] = sinc * w;
  }
}

const SincKernel& SincKernel::instance() {
  static const SincKernel kernel;
  return kernel;
}

double interpolateAt(const float* x, std::size_t n, double t) { return interpolateImpl(x, n, t); }
double interpolateAt(const double* x, std::size_t n, double t) { return interpolateImpl(x, n, t); }

void resampleShifted(const float* x, std::size_t n, double fsIn, double fsOut, double startIn, float* out,
                     std::size_t outLength) {
  const double gain = cutoffStretch(fsIn, fsOut) * fsIn / fsOut;
  resampleCore(x, n, fsIn, fsOut, startIn, gain, out, outLength);
}

std::size_t resampledLength(std::size_t n, double fsIn, double fsOut) {
  return static_cast<std::size_t>(std::llround(double(n) * fsOut / fsIn));
}

std::vector<float> resample(const float* x, std::size_t n, double fsIn, double fsOut) {
  if (fsIn == fsOut) return std::vector<float>(x, x + n);
  std::vector<float> out(resampledLength(n, fsIn, fsOut), 0.0f);
  if (n == 0 || out.empty()) return out;
  // libsoxr, very high quality, linear phase: its one-shot call removes the
  // filter's delay, so output sample m is the signal at time m / fsOut.
  const soxr_io_spec_t io = soxr_io_spec(SOXR_FLOAT32_I, SOXR_FLOAT32_I);
  const soxr_quality_spec_t quality = soxr_quality_spec(SOXR_VHQ | SOXR_LINEAR_PHASE, 0);
  std::size_t done = 0;
  const soxr_error_t error =
      soxr_oneshot(fsIn, fsOut, 1, x, n, nullptr, out.data(), out.size(), &done, &io, &quality, nullptr);
  if (error) {
    // Only bad rates fail (the callers check them): the sinc path instead.
    resampleCore(x, n, fsIn, fsOut, 0.0, cutoffStretch(fsIn, fsOut), out.data(), out.size());
  }
  return out;
}

}  // namespace earshot
