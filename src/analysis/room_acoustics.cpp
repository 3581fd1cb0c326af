// ISO 3382-1 room-acoustic parameters from an impulse response.
//
// Methods:
// - Schroeder backward integration of the squared IR (M. R. Schroeder, "New
//   method of measuring reverberation time", JASA 37, 1965), EDT/T20/T30 as
//   least-squares line fits of the decay curve in dB (ISO 3382-1:2009, 5.3).
// - Noise floor: the iterative cross-point search of A. Lundeby, T. E. Vigran,
//   H. Bietz, M. Vorlaender, "Uncertainties of measurements in room acoustics",
//   Acustica 81, 1995: local time averages, noise from the tail, regression of
//   the late decay 5..25 dB above noise, intersection with the noise level,
//   iterated; the integral is truncated at the cross-point and the energy of
//   the exponential decay beyond it is added (their "compensation").
//   The noise mean is also subtracted before the cross-point (ISO 3382-1
//   names both truncation/compensation and noise subtraction as corrections),
//   removing the ~1 % lengthening left by truncation alone. Exact, noise-free
//   data that simply ends (its last 10 % still decays at over half the overall
//   rate) is integrated to its last non-zero sample with no compensation.
// - Onset: first sample within 20 dB of the maximum (ISO 3382-1, Annex A).
#include "earshot/analysis/room_acoustics.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cmath>

#include "analysis_internal.h"
#include "earshot/analysis/octave_filter.h"

namespace earshot::analysis {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Shortest decay times an octave band resolves, in periods of its centre
// frequency (see analyzeIr).
constexpr double kMinEdtCycles = 12.0;
constexpr double kMinTCycles = 8.0;
// The same for a third octave's filter (octave_filter.h), measured likewise
// (ThirdOctaveAnalysis.* tests): EDT within 3.3 % from 45 cycles, T20/T30
// within 1.2 % from 36 (at 24 cycles T20 reads 7 % long).
constexpr double kMinEdtCyclesThird = 45.0;
constexpr double kMinTCyclesThird = 36.0;

struct LineFit {
  double slope = 0.0;      // dB per second
  double intercept = 0.0;  // dB at t = 0
  bool ok = false;
};

// Least-squares line through (t[i], y[i]); centred sums for accuracy.
template <class GetT, class GetY>
LineFit fitLine(size_t first, size_t last, GetT t, GetY y) {
  LineFit f;
  const size_t n = last - first;
  if (n < 2) return f;
  double mt = 0.0, my = 0.0;
  for (size_t i = first; i < last; ++i) {
    mt += t(i);
    my += y(i);
  }
  mt /= double(n);
  my /= double(n);
  double stt = 0.0, sty = 0.0;
  for (size_t i = first; i < last; ++i) {
    const double dt = t(i) - mt;
    stt += dt * dt;
    sty += dt * (y(i) - my);
  }
  if (!(stt > 0.0)) return f;
  f.slope = sty / stt;
  f.intercept = my - f.slope * mt;
  f.ok = true;
  return f;
}

double toDb(double energyRatio) { return energyRatio > 0.0 ? 10.0 * std::log10(energyRatio) : -kInf; }

// Mean energy per sample in consecutive blocks of `block` samples, in dB.
void blockLevels(const double* e, size_t n, size_t block, std::vector<double>& levels) {
  levels.clear();
  for (size_t s = 0; s < n; s += block) {
    const size_t end = std::min(n, s + block);
    double sum = 0.0;
    for (size_t k = s; k < end; ++k) sum += e[k];
    levels.push_back(toDb(sum / double(end - s)));
  }
}

double meanOf(const double* e, size_t from, size_t to) {
  double sum = 0.0;
  for (size_t k = from; k < to; ++k) sum += e[k];
  return to > from ? sum / double(to - from) : 0.0;
}

struct NoiseResult {
  bool found = false;
  size_t cross = 0;           // samples after the onset where integration stops
  double slopeDbPerS = 0.0;   // late decay rate used for the compensation
  double crossEnergy = 0.0;   // energy per sample of the decay line at the cross-point
  double noiseEnergy = 0.0;   // mean noise energy per sample
  double noiseRelDb = kNaN;   // noise level relative to the late-decay line at the onset
};

// Lundeby et al. 1995 on e[0..n) (energy from the onset on).
NoiseResult lundeby(const double* e, size_t n, double fs) {
  NoiseResult r;
  r.cross = n;
  if (double(n) < 0.05 * fs) return r;  // too short to tell noise from decay
  const size_t tail = n - n / 10, mid = n - n / 20;
  const double m1 = meanOf(e, tail, mid), m2 = meanOf(e, mid, n);
  if (!(m1 > 0.0) || !(m2 > 0.0)) return r;
  std::vector<double> levels;
  size_t block = std::max<size_t>(1, size_t(std::lround(0.01 * fs)));
  blockLevels(e, n, block, levels);
  const size_t peak = size_t(std::max_element(levels.begin(), levels.end()) - levels.begin());
  double noiseDb = toDb(meanOf(e, tail, n));
  auto blockT = [&](size_t b) { return (double(b) + 0.5) * double(block) / fs; };
  auto lev = [&](size_t b) { return levels[b]; };
  // Noise-free test: stationary noise has the same mean level in both halves
  // of the last 10 %; a decay that simply ends (exact or synthetic data) still
  // falls there at a good part of the rate it had just before (fitted over
  // 50 .. 90 % of the data, so that a double-slope decay is judged by its late
  // slope). Over half that rate, and at least 0.25 dB between the halves,
  // counts as "still decaying".
  {
    const size_t b0 = std::max(peak, (n / 2) / block), b1 = std::max(tail / block, b0 + 2);
    const LineFit local = fitLine(std::min(b0, levels.size() - 1), std::min(b1, levels.size()), blockT, lev);
    const double tailDropDb = 10.0 * std::log10(m1 / m2);
    const double expectedDb = local.ok ? -local.slope * double(n / 20) / fs : 0.0;
    if (expectedDb > 0.5 && tailDropDb > 0.5 * expectedDb) return r;
  }

  // Preliminary fit: from the peak down to 10 dB above the noise.
  size_t bEnd = peak + 1;
  while (bEnd < levels.size() && levels[bEnd] > noiseDb + 10.0) ++bEnd;
  LineFit fit = fitLine(peak, bEnd, blockT, lev);
  r.found = true;
  if (!fit.ok || fit.slope >= 0.0) {
    // Noise within 10 dB of the peak: no usable decay; metrics will say so.
    r.cross = std::min(n, bEnd * block);
    r.noiseRelDb = noiseDb - levels[peak];
    return r;
  }
  double tc = (noiseDb - fit.intercept) / fit.slope;
  for (int iter = 0; iter < 5; ++iter) {
    // Intervals: 5 per 10 dB of decay (Lundeby: 3 to 10), within 1 .. 50 ms.
    const double blockS = std::clamp(2.0 / -fit.slope, 0.001, 0.05);
    block = std::max<size_t>(1, size_t(std::lround(blockS * fs)));
    blockLevels(e, n, block, levels);
    // Noise from 10 dB of decay after the cross-point, at least the last 10 %.
    double noiseStartS = tc + 10.0 / -fit.slope;
    size_t noiseStart = noiseStartS * fs < double(tail) ? size_t(std::max(0.0, noiseStartS * fs)) : tail;
    noiseDb = toDb(meanOf(e, noiseStart, n));
    // Late decay: from 25 dB to 5 dB above the noise (a 20 dB range).
    size_t b0 = peak;
    while (b0 < levels.size() && levels[b0] > noiseDb + 25.0) ++b0;
    size_t b1 = b0;
    while (b1 < levels.size() && levels[b1] > noiseDb + 5.0) ++b1;
    if (b1 - b0 < 2) b0 = peak;
    LineFit next = fitLine(b0, b1, blockT, lev);
    if (!next.ok || next.slope >= 0.0) break;
    fit = next;
    const double tcNew = (noiseDb - fit.intercept) / fit.slope;
    const bool converged = std::abs(tcNew - tc) < double(block) / fs;
    tc = tcNew;
    if (converged) break;
  }
  tc = std::clamp(tc, 0.0, double(n) / fs);
  r.cross = std::max<size_t>(1, std::min(n, size_t(std::lround(tc * fs))));
  r.slopeDbPerS = fit.slope;
  r.crossEnergy = std::pow(10.0, (fit.intercept + fit.slope * tc) / 10.0);
  r.noiseEnergy = std::pow(10.0, noiseDb / 10.0);
  r.noiseRelDb = noiseDb - fit.intercept;
  return r;
}

void setAllNaN(BandMetrics& m, const std::string& reason) {
  for (Metric k : kAllMetrics) m.naReason[size_t(k)] = reason;
}

std::string fmt1(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

// The core: e[0..n) is the energy (squared pressure) of a band or broadband
// signal; onset given or -1; energy within preGuard samples before the onset
// counts in the energy ratios.
BandMetrics analyzeEnergy(const double* e, size_t n, double fs, long long onsetIn, size_t preGuard,
                          NoiseTreatment noise) {
  BandMetrics m;
  if (n == 0 || !(fs > 0.0)) {
    setAllNaN(m, "empty signal");
    return m;
  }
  double maxE = 0.0;
  size_t lastNonZero = 0;
  for (size_t k = 0; k < n; ++k) {
    if (e[k] > maxE) maxE = e[k];
    if (e[k] > 0.0) lastNonZero = k;
  }
  if (!(maxE > 0.0)) {
    setAllNaN(m, "silent signal");
    return m;
  }
  size_t onset = 0;
  if (onsetIn >= 0) {
    onset = size_t(onsetIn);
  } else {
    while (e[onset] < 0.01 * maxE) ++onset;  // ISO onset: within 20 dB of the maximum
  }
  m.onsetS = double(onset) / fs;
  const size_t dataEnd = lastNonZero + 1;
  if (onset >= dataEnd) {
    setAllNaN(m, "no energy after the direct sound");
    return m;
  }

  // Noise treatment: where the integration stops and what tail is added.
  NoiseResult nr;
  nr.cross = dataEnd - onset;
  if (noise == NoiseTreatment::kLundeby) nr = lundeby(e + onset, dataEnd - onset, fs);
  const size_t decayEnd = onset + nr.cross;  // exclusive
  m.decayEndS = double(decayEnd) / fs;
  m.noiseFloorFound = nr.found;
  m.noiseFloorDb = nr.found ? nr.noiseRelDb : kNaN;
  // Exponential tail beyond the cross-point: e(t) = crossEnergy exp(A (t - tc)).
  const double rate = nr.slopeDbPerS * std::log(10.0) / 10.0;  // A, 1/s (< 0)
  const bool compensate = nr.found && rate < 0.0 && nr.crossEnergy > 0.0;
  const double tcRel = double(nr.cross) / fs;
  auto tailEnergy = [&](double fromRel, double toRel) {  // sum-of-samples units
    if (!compensate) return 0.0;
    fromRel = std::max(fromRel, tcRel);
    if (toRel <= fromRel) return 0.0;
    const double a = std::exp(rate * (fromRel - tcRel));
    const double b = std::isinf(toRel) ? 0.0 : std::exp(rate * (toRel - tcRel));
    return nr.crossEnergy * fs * (a - b) / -rate;
  };
  const double compEnergy = tailEnergy(tcRel, kInf);
  // Time moment of the tail about the onset: fs * E_c * (tc / -A + 1 / A^2).
  const double compMoment = compensate ? nr.crossEnergy * fs * (tcRel / -rate + 1.0 / (rate * rate)) : 0.0;

  // Schroeder integral from the onset: EDC(k) = sum_{j >= k} (e - noise) +
  // tail, formed as total minus a running sum (no array), in dB only as far as
  // the deepest fit needs (-35 dB; relative rounding error there ~1e-16 /
  // 3e-4). With a noise floor its mean is subtracted up to the cross-point
  // too (truncation + compensation + subtraction):
  // truncation alone leaves the noise integrated before the cross-point,
  // which lengthened T30 by ~1.3 % in the noise test.
  const size_t len = decayEnd - onset;
  const double noiseE = compensate ? nr.noiseEnergy : 0.0;
  double e0 = compEnergy;
  for (size_t k = onset; k < decayEnd; ++k) e0 += e[k] - noiseE;
  // NOTE: thread_local scratch: reused across calls so that a sweep calling
  // this thousands of times does not pay fresh pages each time.
  thread_local std::vector<double> edcDb;
  edcDb.clear();
  {
    const double deepest = e0 * std::pow(10.0, -3.5);
    const double tiny = e0 * 1e-30;  // noise subtraction can dip a sum below 0
    double remaining = e0;
    for (size_t k = 0; k < len; ++k) {
      edcDb.push_back(toDb(std::max(remaining, tiny) / e0));
      if (remaining < deepest) break;
      remaining -= e[onset + k] - noiseE;
    }
  }
  const double lastEdc = std::max(e[decayEnd - 1] - noiseE, 0.0) + compEnergy;
  const double floorDb = toDb(lastEdc / e0);
  // Data that simply ends (no noise found): the EDC plunges to -inf at the end
  // whatever the decay, so "reaching" -35 dB proves nothing. Estimate where
  // the EDC would stand at the end had the decay continued at the fitted rate
  // (mean energy per sample over the last 5 % or 10 ms, times fs T / 13.8)
  // and ask for the same 10 dB margin below the fit range as for noise: the
  // truncation then bends the fitted part of the EDC by <= 0.46 dB.
  const double endEnergy = [&] {
    const size_t span = std::min(len, std::max(len / 20, size_t(std::lround(0.01 * fs))));
    return meanOf(e, decayEnd - span, decayEnd);
  }();
  auto truncationFloorDb = [&](double slopeDbPerS) {
    if (nr.found || !(slopeDbPerS < 0.0)) return kNaN;
    return toDb(endEnergy * fs * (10.0 / std::log(10.0)) / -slopeDbPerS / e0);
  };

  auto decayFit = [&](Metric metric, double hiDb, double loDb, double& out) {
    // ISO 3382-1: with a noise floor, it must lie >= 10 dB below the fit's end.
    if (nr.found && !(-nr.noiseRelDb >= -loDb + 10.0)) {
      m.naReason[size_t(metric)] = "decay range too short: noise floor at " + fmt1(nr.noiseRelDb) +
                                   " dB, needs " + fmt1(loDb - 10.0) + " dB";
      return;
    }
    if (!(floorDb < loDb)) {
      m.naReason[size_t(metric)] = "decay range too short: decay reaches only " + fmt1(floorDb) + " dB, needs " +
                                   fmt1(loDb) + " dB";
      return;
    }
    size_t first = 0;
    while (first < edcDb.size() && edcDb[first] > hiDb) ++first;
    size_t last = first;
    while (last < edcDb.size() && edcDb[last] >= loDb) ++last;
    LineFit f = fitLine(first, last, [&](size_t k) { return double(k) / fs; }, [&](size_t k) { return edcDb[k]; });
    if (!f.ok || !(f.slope < 0.0)) {
      m.naReason[size_t(metric)] = "no decay between " + fmt1(hiDb) + " and " + fmt1(loDb) + " dB";
      return;
    }
    const double truncDb = truncationFloorDb(f.slope);
    if (truncDb > loDb - 10.0) {
      m.naReason[size_t(metric)] = "decay range too short: data ends at about " + fmt1(truncDb) +
                                   " dB of decay, needs " + fmt1(loDb - 10.0) + " dB";
      return;
    }
    if (metric == Metric::kEdt && !nr.found) m.dynamicRangeDb = -truncDb;
    out = -60.0 / f.slope;
  };
  decayFit(Metric::kEdt, 0.0, -10.0, m.edtS);
  decayFit(Metric::kT20, -5.0, -25.0, m.t20S);
  decayFit(Metric::kT30, -5.0, -35.0, m.t30S);

  // Energy ratios. Sample k is "early" when k - onset < round(limit * fs).
  const size_t start = onset > preGuard ? onset - preGuard : 0;
  const size_t i50 = std::min(decayEnd, onset + size_t(std::lround(0.050 * fs)));
  const size_t i80 = std::min(decayEnd, onset + size_t(std::lround(0.080 * fs)));
  // One pass: energy of [start, i50), [i50, i80), [i80, end) and the time
  // moment (k - onset) e[k] in samples (summing each segment once keeps an
  // exactly empty late part exactly zero, hence C = +inf).
  double seg[3] = {0.0, 0.0, 0.0};
  double momentSamples = 0.0;
  {
    const size_t bounds[4] = {start, std::max(start, i50), std::max(start, i80), decayEnd};
    const double onsetD = double(onset);
    for (int sgi = 0; sgi < 3; ++sgi) {
      double sum = 0.0, mom = 0.0;
      for (size_t k = bounds[sgi]; k < bounds[sgi + 1]; ++k) {
        sum += e[k];
        mom += (double(k) - onsetD) * e[k];
      }
      seg[sgi] = sum;
      momentSamples += mom;
    }
  }
  const double t50 = std::round(0.050 * fs) / fs, t80 = std::round(0.080 * fs) / fs;
  const double early50 = seg[0] + tailEnergy(0.0, t50);
  const double late50 = seg[1] + seg[2] + tailEnergy(t50, kInf);
  const double early80 = seg[0] + seg[1] + tailEnergy(0.0, t80);
  const double late80 = seg[2] + tailEnergy(t80, kInf);
  const double total = early50 + late50;
  if (!(total > 0.0)) {
    for (Metric k : {Metric::kC50, Metric::kC80, Metric::kD50, Metric::kTs})
      m.naReason[size_t(k)] = "no energy after the direct sound";
    return m;
  }
  m.c50Db = late50 > 0.0 ? 10.0 * std::log10(early50 / late50) : kInf;
  m.c80Db = late80 > 0.0 ? 10.0 * std::log10(early80 / late80) : kInf;
  m.d50 = early50 / total;
  m.tsS = (momentSamples / fs + compMoment) / total;
  return m;
}

}  // namespace

namespace detail {

size_t firstNonFinite(const float* x, size_t count) {
  for (size_t i = 0; i < count; ++i)
    if (!std::isfinite(x[i])) return i;
  return count;
}

size_t isoOnsetFrame(const float* const* channels, size_t channelCount, size_t frames) {
  float maxAbs = 0.0f;
  for (size_t c = 0; c < channelCount; ++c)
    for (size_t k = 0; k < frames; ++k) maxAbs = std::max(maxAbs, std::abs(channels[c][k]));
  const double threshold = 0.01 * double(maxAbs) * double(maxAbs);  // within 20 dB of the maximum
  for (size_t k = 0; k < frames; ++k)
    for (size_t c = 0; c < channelCount; ++c)
      if (maxAbs > 0.0f && double(channels[c][k]) * double(channels[c][k]) >= threshold) return k;
  return frames;
}

}  // namespace detail

const char* metricName(Metric metric) {
  switch (metric) {
    case Metric::kEdt: return "EDT";
    case Metric::kT20: return "T20";
    case Metric::kT30: return "T30";
    case Metric::kC50: return "C50";
    case Metric::kC80: return "C80";
    case Metric::kD50: return "D50";
    case Metric::kTs: return "Ts";
  }
  return "?";
}

const char* metricUnit(Metric metric) {
  switch (metric) {
    case Metric::kC50:
    case Metric::kC80: return "dB";
    case Metric::kD50: return "";
    default: return "s";
  }
}

Result<Metric> parseMetric(const std::string& name) {
  std::string lower;
  for (char c : name) lower.push_back(char(std::tolower(static_cast<unsigned char>(c))));
  for (Metric m : kAllMetrics) {
    std::string n;
    for (const char* p = metricName(m); *p; ++p) n.push_back(char(std::tolower(static_cast<unsigned char>(*p))));
    if (n == lower) return m;
  }
  return invalidArgument("unknown metric " + quotedName(name) + " (expected EDT, T20, T30, C50, C80, D50 or Ts)");
}

double BandMetrics::value(Metric metric) const {
  switch (metric) {
    case Metric::kEdt: return edtS;
    case Metric::kT20: return t20S;
    case Metric::kT30: return t30S;
    case Metric::kC50: return c50Db;
    case Metric::kC80: return c80Db;
    case Metric::kD50: return d50;
    case Metric::kTs: return tsS;
  }
  return kNaN;
}

BandMetrics analyzeBandSignal(const float* signal, size_t count, double rateHz, long long onsetSample,
                              size_t preGuardSamples, NoiseTreatment noise) {
  std::vector<double> e(count);
  for (size_t i = 0; i < count; ++i) e[i] = std::isfinite(signal[i]) ? double(signal[i]) * double(signal[i]) : 0.0;
  if (onsetSample >= 0 && size_t(onsetSample) >= count) onsetSample = -1;
  return analyzeEnergy(e.data(), count, rateHz, onsetSample, preGuardSamples, noise);
}

Result<std::vector<BandMetrics>> analyzeIr(const std::vector<float>& ir, double rateHz,
                                           const AnalysisOptions& options) {
  if (ir.empty()) return invalidArgument("impulse response is empty");
  if (!(rateHz >= 1000.0 && rateHz <= 1e6))
    return invalidArgument("sample rate " + std::to_string(rateHz) + " Hz is outside [1000, 1e6]");
  const size_t bad = detail::firstNonFinite(ir.data(), ir.size());
  if (bad < ir.size()) return invalidArgument("impulse response sample " + std::to_string(bad) + " is not finite");
  if (!(options.windowEndS > options.windowStartS))
    return invalidArgument("window [" + std::to_string(options.windowStartS) + ", " +
                           std::to_string(options.windowEndS) + ") s is empty");
  const size_t n = ir.size();
  const float* channel = ir.data();
  const size_t onset = detail::isoOnsetFrame(&channel, 1, n);
  if (onset >= n) return invalidArgument("impulse response is silent (all samples are zero)");

  std::vector<float> src = ir;
  if (options.direct == DirectSound::kExclude) {
    const long long a = (long long)onset - std::llround(options.directBeforeS * rateHz);
    const long long b = (long long)onset + std::llround(options.directAfterS * rateHz);
    for (long long k = std::max(0LL, a); k <= b && k < (long long)n; ++k) src[size_t(k)] = 0.0f;
  }
  // Window in samples of the IR.
  const double origin = options.windowOrigin == WindowOrigin::kDirectSound ? double(onset) / rateHz : 0.0;
  const double ws = (options.windowStartS + origin) * rateHz, we = (options.windowEndS + origin) * rateHz;
  if (we <= 0.0 || ws >= double(n)) return invalidArgument("window leaves no samples of the impulse response");
  if (we - ws < 1.0)
  {
    char what[96];
    std::snprintf(what, sizeof what, "window of %.3g s is shorter than one sample at %.0f Hz",
                  options.windowEndS - options.windowStartS, rateHz);
    return invalidArgument(what);
  }
  // Applies the window to a signal whose sample j is IR sample j - offset.
  auto applyWindow = [&](std::vector<double>& y, size_t offset) {
    for (size_t j = 0; j < y.size(); ++j) {
      const double i = double(j) - double(offset);
      if ((ws > 0.0 && i < ws) || i >= we) y[j] = 0.0;
    }
  };

  {
    const size_t a = ws > 0.0 ? size_t(std::ceil(ws)) : 0, b = we >= double(n) ? n : size_t(std::ceil(we));
    bool any = false;
    for (size_t k = a; k < b && !any; ++k) any = src[k] != 0.0f;
    if (!any)
      return invalidArgument("window [" + std::to_string(ws / rateHz) + ", " + std::to_string(we / rateHz) +
                             ") s after emission holds no energy of the impulse response");
  }

  const bool thirds = options.bands == AnalysisOptions::Bands::kThirdOctave;
  const int bandCount = thirds ? kNumThirdOctaveBands : kNumBands;
  const double bandwidth = thirds ? 1.0 / 3.0 : 1.0;
  auto centerOf = [&](int b) { return thirds ? thirdOctaveCenterHz(b) : kBandCentersHz[size_t(b)]; };
  std::vector<BandMetrics> out(size_t(bandCount + 1));
  // Bands go through the filter two at a time; buffers are reused for every
  // pair (no page faults per band).
  // Scratch reused across calls on this thread (page faults on fresh
  // multi-megabyte buffers cost as much as the filtering itself).
  thread_local std::vector<double> y, y2;
  // A window that ends before 50 / 80 ms after the direct sound cannot tell
  // early from late energy: those ratios are n/a, not +inf or a number.
  auto cutByWindow = [&](BandMetrics& m) {
    const double endAfterOnsetS = (we - double(onset)) / rateHz;
    auto cutShort = [&](Metric metric, double& value, double needS) {
      if (endAfterOnsetS >= needS) return;
      value = kNaN;
      m.naReason[size_t(metric)] = "the window ends " + fmt1(1000.0 * endAfterOnsetS) + " ms after the direct sound, "
                                   "before " + fmt1(1000.0 * needS) + " ms";
    };
    cutShort(Metric::kC50, m.c50Db, 0.050);
    cutShort(Metric::kD50, m.d50, 0.050);
    cutShort(Metric::kC80, m.c80Db, 0.080);
  };
  auto finishBand = [&](int b, std::vector<double>& band, size_t guard) {
    applyWindow(band, guard);
    for (double& v : band) v *= v;
    BandMetrics& m = out[size_t(b)];
    m = analyzeEnergy(band.data(), band.size(), rateHz, (long long)(guard + onset), guard, options.noise);
    m.onsetS = double(onset) / rateHz;
    m.decayEndS -= double(guard) / rateHz;
    // The octave filter's own decay (T30 ~ 4.3 / fc, EDT ~ 4 / fc) limits what
    // a band can show. Measured on decaying tones at the band centre: EDT is
    // biased by ~5 % (1 JND) at EDT fc = 12 and 15 % at 8; T20/T30 by < 1.5 %
    // down to T fc = 8. Shorter values are the filter, not the room: n/a.
    const double fc = centerOf(b);
    auto limitDecay = [&](Metric metric, double& value, double minCycles) {
      if (std::isnan(value) || value * fc >= minCycles) return;
      value = kNaN;
      m.naReason[size_t(metric)] = "decay faster than the " + fmt1(fc) + (thirds ? " Hz third-octave" : " Hz octave") +
                                   " filter resolves (< " + fmt1(1000.0 * minCycles / fc) + " ms)";
    };
    limitDecay(Metric::kEdt, m.edtS, thirds ? kMinEdtCyclesThird : kMinEdtCycles);
    limitDecay(Metric::kT20, m.t20S, thirds ? kMinTCyclesThird : kMinTCycles);
    limitDecay(Metric::kT30, m.t30S, thirds ? kMinTCyclesThird : kMinTCycles);
    cutByWindow(m);
  };
  std::vector<int> available;
  for (int b = 0; b < bandCount; ++b) {
    const double fc = centerOf(b);
    out[size_t(b)].bandCenterHz = fc;
    if (fractionalOctaveBandAvailable(rateHz, fc, bandwidth))
      available.push_back(b);
    else
      setAllNaN(out[size_t(b)], std::string(thirds ? "third-octave" : "octave") +
                                    " band above the sample rate's limit (" + fmt1(rateHz) + " Hz)");
  }
  if (thirds) {
    for (int b : available) {
      size_t guard = 0;
      fractionalOctaveBandFilterInto(src.data(), n, rateHz, centerOf(b), bandwidth, y, &guard);
      finishBand(b, y, guard);
      out[size_t(b)].bandCenterHz = centerOf(b);
    }
  } else {
    for (size_t i = 0; i < available.size(); i += 2) {
      const int b = available[i];
      const double fc = kBandCentersHz[size_t(b)];
      if (i + 1 < available.size()) {
        const int b2 = available[i + 1];
        const size_t guard = octaveBandGuardSamples(rateHz, std::min(fc, kBandCentersHz[size_t(b2)]));
        octaveBandFilterPairInto(src.data(), n, rateHz, fc, kBandCentersHz[size_t(b2)], guard, y, y2);
        finishBand(b, y, guard);
        finishBand(b2, y2, guard);
        out[size_t(b2)].bandCenterHz = kBandCentersHz[size_t(b2)];
      } else {
        size_t guard = 0;
        octaveBandFilterInto(src.data(), n, rateHz, fc, y, &guard);
        finishBand(b, y, guard);
      }
      out[size_t(b)].bandCenterHz = fc;
    }
  }
  y.assign(src.begin(), src.end());
  applyWindow(y, 0);
  for (double& v : y) v *= v;
  BandMetrics& bb = out[size_t(bandCount)];
  bb = analyzeEnergy(y.data(), n, rateHz, (long long)onset, 0, options.noise);
  cutByWindow(bb);
  bb.bandCenterHz = 0.0;
  return out;
}

Result<IrAnalysis> analyzeAudio(const AudioBuffer& audio, const AnalysisOptions& options, int onlyChannel) {
  if (audio.channelCount() == 0 || audio.frameCount() == 0) return invalidArgument("audio has no samples");
  if (onlyChannel >= int(audio.channelCount()))
    return invalidArgument("channel " + std::to_string(onlyChannel) + " does not exist (audio has " +
                           std::to_string(audio.channelCount()) + " channels, numbered from 0)");
  IrAnalysis result;
  result.sampleRateHz = audio.sampleRateHz;
  result.frameCount = audio.frameCount();
  for (size_t c = 0; c < audio.channelCount(); ++c) {
    if (onlyChannel >= 0 && int(c) != onlyChannel) continue;
    auto r = analyzeIr(audio.channels[c], audio.sampleRateHz, options);
    if (!r) return Status(r.status().code(), "channel " + std::to_string(c) + ": " + r.status().message());
    result.channels.push_back(std::move(r.value()));
  }
  return result;
}

}  // namespace earshot::analysis
