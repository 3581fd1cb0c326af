// Binaural cues of a two-channel IR: ITD, ILD, IACC (definitions in
// include/earshot/analysis/binaural.h).
//
// Methods:
// - ITD as the lag of the maximum of the interaural cross-correlation of the
//   low-passed direct sound (B. F. G. Katz and M. Noisternig, "A comparative
//   study of interaural time delay estimation methods", JASA 135(6), 2014:
//   the "IACC" method on low-passed HRIRs).
// - IACC: ISO 3382-1:2009 Annex A.3; early/late split after Hidaka, Beranek
//   and Okano, JASA 98(2), 1995.
// - Sub-sample maximum: the correlation at a fractional lag tau is exactly
//   sum_m c(m) sinc(tau - m) when the signals are band-limited (c = the
//   integer-lag correlation; r(t + tau) is the sinc interpolation of r), so
//   c is interpolated with a Kaiser-windowed sinc (32 zero crossings each
//   side, beta 12: ~-117 dB stop band, flat to ~0.44 fs; J. F. Kaiser and
//   R. W. Schafer, IEEE Trans. ASSP 28(1), 1980) and its maximum found by
//   golden-section search around each candidate peak. A shorter kernel (16
//   crossings, beta 8) left a 1e-4 ripple between samples that moved the peak
//   of a wide correlation by 0.002 samples; this one, 4e-8 and 5e-6 samples.
#include "earshot/analysis/binaural.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "analysis_internal.h"
#include "earshot/analysis/octave_filter.h"
#include "earshot/core/math.h"

namespace earshot::analysis {
namespace {

constexpr int kKernelLobes = 32;  // zero crossings of the interpolation kernel each side
// Late IACC in a band needs late energy above the octave filter's own ringing,
// which octaveBandGuardSamples bounds at -50 dB of an arrival's energy.
constexpr double kMinLateBandEnergyFraction = 1e-5;

double sincPi(double x) { return x == 0.0 ? 1.0 : std::sin(kPi * x) / (kPi * x); }

double besselI0(double x) {
  double sum = 1.0, term = 1.0;
  for (int k = 1; k < 60 && term > 1e-17 * sum; ++k) {
    term *= x * x / (4.0 * double(k) * double(k));
    sum += term;
  }
  return sum;
}

constexpr double kKaiserBeta = 12.0;

double kaiserSinc(double x) {
  static const double norm = 1.0 / besselI0(kKaiserBeta);
  const double u = x / double(kKernelLobes);
  return std::abs(u) < 1.0 ? sincPi(x) * besselI0(kKaiserBeta * std::sqrt(1.0 - u * u)) * norm : 0.0;
}

std::string fmtHz(double hz) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.1f Hz", hz);
  return buf;
}

/** Cross-correlation of two segments of n samples each at integer lags
 *  -half .. +half: c[j] = sum over t in [0, n) of x[t] y[t + j - half], y
 *  read as zero outside [0, n). */
class LagCorrelation {
 public:
  void compute(const double* x, const double* y, size_t n, long half) {
    mHalf = half;
    const size_t lags = size_t(2 * half + 1);
    // y padded with `half` zeros on both sides: padded[t + j] = y[t + j - half].
    mPadded.assign(n + 2 * size_t(half), 0.0);
    std::copy(y, y + n, mPadded.begin() + half);
    mC.assign(lags, 0.0);
    // Four lags per pass: independent accumulators share each load of x.
    size_t j = 0;
    for (; j + 4 <= lags; j += 4) {
      double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
      const double* p = mPadded.data() + j;
      for (size_t t = 0; t < n; ++t) {
        const double v = x[t];
        s0 += v * p[t];
        s1 += v * p[t + 1];
        s2 += v * p[t + 2];
        s3 += v * p[t + 3];
      }
      mC[j] = s0;
      mC[j + 1] = s1;
      mC[j + 2] = s2;
      mC[j + 3] = s3;
    }
    for (; j < lags; ++j) {
      double s = 0.0;
      for (size_t t = 0; t < n; ++t) s += x[t] * mPadded[t + j];
      mC[j] = s;
    }
  }

  double atInteger(long lag) const { return mC[size_t(lag + mHalf)]; }

  /** Band-limited value at a fractional lag (|lag| <= half - kKernelLobes). */
  double at(double lag) const {
    const double pos = lag + double(mHalf);
    const long lo = std::max(0L, long(std::ceil(pos - kKernelLobes))),
               hi = std::min(long(mC.size()) - 1, long(std::floor(pos + kKernelLobes)));
    double s = 0.0;
    for (long k = lo; k <= hi; ++k) s += mC[size_t(k)] * kaiserSinc(pos - double(k));
    return s;
  }

 private:
  long mHalf = 0;
  std::vector<double> mPadded;
  std::vector<double> mC;
};

struct Peak {
  double lagSamples = 0.0;
  double value = 0.0;  // the correlation itself (signed)
};

/** Maximum over lags in [-limit, limit] (samples) of the correlation, or of
 *  its magnitude when `absolute`: the best integer lags (local maxima within
 *  half of the best) are refined by golden-section search within +-1 sample. */
Peak findPeak(const LagCorrelation& c, double limit, bool absolute) {
  auto score = [&](double v) { return absolute ? std::abs(v) : v; };
  const long m = long(std::floor(limit));
  double best = -std::numeric_limits<double>::infinity();
  for (long k = -m; k <= m; ++k) best = std::max(best, score(c.atInteger(k)));
  Peak out;
  out.value = kNaN;
  double bestScore = -std::numeric_limits<double>::infinity();
  for (long k = -m; k <= m; ++k) {
    const double s = score(c.atInteger(k));
    const bool localMax = (k == -m || s >= score(c.atInteger(k - 1))) && (k == m || s >= score(c.atInteger(k + 1)));
    if (!localMax || s < best - 0.5 * std::abs(best)) continue;
    // Golden-section search for the maximum of score(c.at(.)) on [a, b].
    double a = std::max(double(k) - 1.0, -limit), b = std::min(double(k) + 1.0, limit);
    const double g = 0.5 * (std::sqrt(5.0) - 1.0);
    double x1 = b - g * (b - a), x2 = a + g * (b - a);
    double f1 = score(c.at(x1)), f2 = score(c.at(x2));
    while (b - a > 1e-7) {
      if (f1 < f2) {
        a = x1;
        x1 = x2;
        f1 = f2;
        x2 = a + g * (b - a);
        f2 = score(c.at(x2));
      } else {
        b = x2;
        x2 = x1;
        f2 = f1;
        x1 = b - g * (b - a);
        f1 = score(c.at(x1));
      }
    }
    // The interval ends can beat the interior (a maximum at the search limit).
    for (double x : {0.5 * (a + b), std::max(double(k) - 1.0, -limit), std::min(double(k) + 1.0, limit)}) {
      const double v = c.at(x);
      if (score(v) > bestScore) {
        bestScore = score(v);
        out.lagSamples = x;
        out.value = v;
      }
    }
  }
  return out;
}

double energy(const double* x, size_t from, size_t to) {
  double s = 0.0;
  for (size_t t = from; t < to; ++t) s += x[t] * x[t];
  return s;
}

// Windows of the IACC, in samples of the IR (end exclusive, clamped to it).
struct IaccWindows {
  size_t onset = 0, earlyEnd = 0, lateEnd = 0;
};

/** IACC of the early and late windows of one band: x, y are the left and
 *  right band signals with `guard` samples before IR sample 0 (and after its
 *  end); `band` says whether they went through an octave filter. */
void bandIacc(const std::vector<double>& x, const std::vector<double>& y, size_t guard, bool band,
              const IaccWindows& w, double limitSamples, double rateHz, LagCorrelation& scratch, IaccBand& out) {
  const long half = long(std::ceil(limitSamples)) + kKernelLobes + 1;
  const double totalL = energy(x.data(), 0, x.size()), totalR = energy(y.data(), 0, y.size());
  auto one = [&](size_t from, size_t to, bool late, double& value, double& lagS, std::string& reason) {
    if (to <= from) {
      reason = "the impulse response ends before this window";
      return;
    }
    const double el = energy(x.data(), from, to), er = energy(y.data(), from, to);
    if (!(el > 0.0) || !(er > 0.0)) {
      reason = std::string(el > 0.0 ? "right" : "left") + " ear has no energy in this window";
      return;
    }
    if (late && band && (el < kMinLateBandEnergyFraction * totalL || er < kMinLateBandEnergyFraction * totalR)) {
      reason = "late energy below the octave filter's ringing (-50 dB of the band's total)";
      return;
    }
    scratch.compute(x.data() + from, y.data() + from, to - from, half);
    const Peak p = findPeak(scratch, limitSamples, true);
    value = std::abs(p.value) / std::sqrt(el * er);
    lagS = p.lagSamples / rateHz;
  };
  // Early: from the onset (in a band, from where the zero-phase filter's
  // pre-ringing of the direct sound starts, `guard` samples before it).
  const size_t earlyFrom = band ? w.onset : guard + w.onset;
  one(earlyFrom, guard + w.earlyEnd, false, out.early, out.earlyLagS, out.earlyReason);
  one(guard + w.earlyEnd, guard + w.lateEnd, true, out.late, out.lateLagS, out.lateReason);
}

Status checkSettings(const BinauralAnalysisSettings& s) {
  auto bad = [](const char* field, double v, const char* range) {
    return invalidArgument(std::string("binaural analysis setting ") + field + " = " + std::to_string(v) +
                           " is outside " + range);
  };
  if (!(s.directBeforeS >= 0.0 && s.directBeforeS <= 1.0)) return bad("directBeforeS", s.directBeforeS, "[0, 1] s");
  if (!(s.directAfterS > 0.0 && s.directAfterS <= 1.0)) return bad("directAfterS", s.directAfterS, "(0, 1] s");
  if (!(s.itdLowPassHz > 0.0 && std::isfinite(s.itdLowPassHz)))
    return bad("itdLowPassHz", s.itdLowPassHz, "(0, inf) Hz");
  if (!(s.maxLagS > 0.0 && s.maxLagS <= 0.01)) return bad("maxLagS", s.maxLagS, "(0, 0.01] s");
  if (!(s.earlyEndS > 0.0 && std::isfinite(s.earlyEndS))) return bad("earlyEndS", s.earlyEndS, "(0, inf) s");
  if (!(s.lateEndS > s.earlyEndS)) return bad("lateEndS", s.lateEndS, "(earlyEndS, inf] s");
  return Status::ok();
}

size_t framesAfter(size_t onset, double seconds, double rateHz, size_t frames) {
  if (!(seconds * rateHz < double(frames))) return frames;
  return std::min(frames, onset + size_t(std::llround(seconds * rateHz)));
}

}  // namespace

Result<BinauralMetrics> analyzeBinaural(const AudioBuffer& ir, const BinauralAnalysisSettings& settings) {
  if (ir.channelCount() != 2)
    return invalidArgument("binaural analysis needs exactly 2 channels (left, right); the impulse response has " +
                           std::to_string(ir.channelCount()));
  const std::vector<float>& left = ir.channels[0];
  const std::vector<float>& right = ir.channels[1];
  if (left.size() != right.size())
    return invalidArgument("left and right channels differ in length (" + std::to_string(left.size()) + " and " +
                           std::to_string(right.size()) + " samples)");
  const size_t n = left.size();
  if (n == 0) return invalidArgument("impulse response is empty");
  const double fs = ir.sampleRateHz;
  if (!(fs >= 1000.0 && fs <= 1e6))
    return invalidArgument("sample rate " + std::to_string(fs) + " Hz is outside [1000, 1e6]");
  for (size_t c = 0; c < 2; ++c) {
    const size_t bad = detail::firstNonFinite(ir.channels[c].data(), n);
    if (bad < n)
      return invalidArgument(std::string(c == 0 ? "left" : "right") + " channel sample " + std::to_string(bad) +
                             " is not finite");
  }
  EARSHOT_RETURN_IF_ERROR(checkSettings(settings));
  const float* both[2] = {left.data(), right.data()};
  const size_t onset = detail::isoOnsetFrame(both, 2, n);
  if (onset >= n) return invalidArgument("impulse response is silent (all samples are zero)");

  BinauralMetrics m;
  m.onsetS = double(onset) / fs;
  const double limit = settings.maxLagS * fs;  // lag search range, samples
  const long half = long(std::ceil(limit)) + kKernelLobes + 1;
  LagCorrelation corr;

  // Direct sound: ILD on the raw window, ITD on its low-passed version.
  const size_t before = size_t(std::llround(settings.directBeforeS * fs));
  const size_t a = onset > before ? onset - before : 0;
  const size_t b = std::max(onset + 1, framesAfter(onset, settings.directAfterS, fs, n));
  m.directStartS = double(a) / fs;
  m.directEndS = double(b) / fs;
  double el = 0.0, er = 0.0;
  for (size_t t = a; t < b; ++t) {
    el += double(left[t]) * double(left[t]);
    er += double(right[t]) * double(right[t]);
  }
  m.ildDb = er > 0.0 ? (el > 0.0 ? 10.0 * std::log10(el / er) : -std::numeric_limits<double>::infinity())
                     : std::numeric_limits<double>::infinity();
  if (!(el > 0.0) || !(er > 0.0)) {
    m.itdReason = std::string(el > 0.0 ? "right" : "left") + " ear is silent in the direct-sound window";
  } else {
    std::vector<double> lowL(left.begin() + long(a), left.begin() + long(b)),
        lowR(right.begin() + long(a), right.begin() + long(b));
    if (settings.itdLowPassHz < 0.45 * fs) {  // else the signal holds nothing above it to remove
      detail::zeroPhaseLowPassInto(left.data() + a, b - a, fs, settings.itdLowPassHz, lowL);
      detail::zeroPhaseLowPassInto(right.data() + a, b - a, fs, settings.itdLowPassHz, lowR);
    }
    const double norm = std::sqrt(energy(lowL.data(), 0, lowL.size()) * energy(lowR.data(), 0, lowR.size()));
    if (!(norm > 0.0)) {
      m.itdReason = "no energy below " + fmtHz(settings.itdLowPassHz) + " in the direct-sound window";
    } else {
      corr.compute(lowL.data(), lowR.data(), lowL.size(), half);
      const Peak p = findPeak(corr, limit, false);
      m.itdS = p.lagSamples / fs;
      m.itdPeakCorrelation = p.value / norm;
      m.itdAtSearchLimit = std::abs(p.lagSamples) >= limit - 1e-6;
    }
  }

  // IACC per octave band (two bands per filter pass, as analyzeIr) and broadband.
  IaccWindows w;
  w.onset = onset;
  w.earlyEnd = framesAfter(onset, settings.earlyEndS, fs, n);
  w.lateEnd = framesAfter(onset, settings.lateEndS, fs, n);
  std::vector<int> available;
  for (int band = 0; band < kNumBands; ++band) {
    const double fc = kBandCentersHz[size_t(band)];
    IaccBand& out = m.iacc[size_t(band)];
    out.bandCenterHz = fc;
    if (octaveBandAvailable(fs, fc)) {
      available.push_back(band);
    } else {
      out.earlyReason = out.lateReason = "octave band above the sample rate's limit (" + fmtHz(fs) + ")";
    }
  }
  std::vector<double> la, lb, ra, rb;
  for (size_t i = 0; i < available.size(); i += 2) {
    const int b1 = available[i];
    const int b2 = i + 1 < available.size() ? available[i + 1] : b1;
    const double f1 = kBandCentersHz[size_t(b1)], f2 = kBandCentersHz[size_t(b2)];
    const size_t guard = octaveBandGuardSamples(fs, std::min(f1, f2));
    octaveBandFilterPairInto(left.data(), n, fs, f1, f2, guard, la, lb);
    octaveBandFilterPairInto(right.data(), n, fs, f1, f2, guard, ra, rb);
    bandIacc(la, ra, guard, true, w, limit, fs, corr, m.iacc[size_t(b1)]);
    if (b2 != b1) bandIacc(lb, rb, guard, true, w, limit, fs, corr, m.iacc[size_t(b2)]);
  }
  la.assign(left.begin(), left.end());
  ra.assign(right.begin(), right.end());
  m.iacc[kBroadbandIndex].bandCenterHz = 0.0;
  bandIacc(la, ra, 0, false, w, limit, fs, corr, m.iacc[kBroadbandIndex]);

  // Hidaka et al.'s three-band means (500 Hz, 1 kHz, 2 kHz): NaN if any is.
  double e3 = 0.0, l3 = 0.0;
  for (const IaccBand& band : m.iacc) {
    if (band.bandCenterHz < 500.0 || band.bandCenterHz > 2000.0) continue;
    e3 += band.early / 3.0;
    l3 += band.late / 3.0;
  }
  m.iaccE3 = e3;
  m.iaccL3 = l3;
  return m;
}

}  // namespace earshot::analysis
