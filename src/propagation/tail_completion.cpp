// Tail completion: method and references in tail_completion.h.
#include "earshot/propagation/tail_completion.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace earshot {

namespace {
constexpr double kNepersPer60Db = 13.815510557964274;  // ln(10^6)
constexpr double kFitWindowSeconds = 0.05;
}  // namespace

Result<EnergyHistogram> completeTail(const EnergyHistogram& h, const TailData& tail,
                                     const TailCompletionSettings& settings, TailInfo* infoOut) {
  if (!(settings.lengthSeconds >= 0 && settings.lengthSeconds <= 600))
    return invalidArgument("tail length " + std::to_string(settings.lengthSeconds) + " s is outside [0, 600]");
  if (!(settings.dynamicRangeDb > 0 && settings.dynamicRangeDb <= 200))
    return invalidArgument("tail dynamic range " + std::to_string(settings.dynamicRangeDb) + " dB is outside (0, 200]");
  TailInfo info;
  const double dt = h.binSeconds();
  const size_t traced = h.binCount();
  const BandArrayD m = airEnergyAttenuationPerMeter(settings.air);  // energy, 1/m

  // 1. Decay rates: solve the renewal equation F(delta) = 1 by bisection
  // (F increases with delta).
  BandArrayD delta{};
  bool haveRates = !tail.pathEnergy.empty();
  for (int b = 0; b < kNumBands && haveRates; ++b) {
    double total = 0, kept = 0, length = 0;
    for (size_t i = 0; i < tail.pathEnergy.size(); ++i) {
      total += tail.pathEnergy[i][b];
      kept += tail.pathRetained[i][b];
      length += tail.pathRetained[i][b] * freePathBinCenter(i);
    }
    if (!(total > 0)) {
      haveRates = false;
      break;
    }
    info.meanLoss[b] = 1.0 - kept / total;
    info.meanFreePathMeters[b] = kept > 0 ? length / kept : 0.0;
    std::vector<std::pair<double, double>> paths;  // (free path, energy kept), non-empty bins only
    for (size_t i = 0; i < tail.pathRetained.size(); ++i)
      if (tail.pathRetained[i][b] > 0) paths.emplace_back(freePathBinCenter(i), tail.pathRetained[i][b]);
    auto F = [&](double d) {
      double sum = 0;
      for (const auto& [l, kept] : paths) sum += kept * std::exp((d / settings.speedOfSound - m[b]) * l);
      return sum / total;
    };
    double lo = 0.0, hi = 1e6;
    if (!(kept > 0) || F(hi) < 1.0) {
      delta[b] = hi;  // nothing (or nearly nothing) survives a reflection
    } else if (F(lo) >= 1.0) {
      delta[b] = 1e-3;  // lossless: no decay to extrapolate
    } else {
      for (int it = 0; it < 100 && hi - lo > 1e-7 * hi; ++it) {
        const double mid = 0.5 * (lo + hi);
        (F(mid) < 1.0 ? lo : hi) = mid;
      }
      delta[b] = std::max(0.5 * (lo + hi), 1e-3);
    }
    info.decayRatePerSecond[b] = delta[b];
    info.t60Seconds[b] = kNepersPer60Db / delta[b];
  }

  // 2. Completeness and the start of extrapolation, per band.
  std::vector<BandArrayD> corrected(traced);
  BandArrayD level{};
  std::array<size_t, kNumBands> start{};
  for (int b = 0; b < kNumBands; ++b) {
    start[b] = traced;
    double virtualEnergy = 0;
    const double decay = std::exp(-delta[b] * dt);
    bool anyCut = false;
    for (size_t i = 0; i < traced; ++i) {
      if (i > 0) virtualEnergy = virtualEnergy * decay + (i - 1 < tail.cut.size() ? tail.cut[i - 1][b] : 0.0);
      anyCut |= virtualEnergy > 0;
      const double alive = i < tail.alive.size() ? tail.alive[i][b] : 0.0;
      if (anyCut && haveRates && !(alive > 0 && alive >= virtualEnergy)) {
        start[b] = i;
        break;
      }
      corrected[i][b] = h.energy(i, b) * (alive > 0 ? (alive + virtualEnergy) / alive : 1.0);
    }
    if (start[b] < traced) {
      // Level of the exponential, fitted to the window before the start.
      const size_t window = std::min(start[b], std::max<size_t>(1, size_t(kFitWindowSeconds / dt)));
      double num = 0, den = 0;
      for (size_t j = start[b] - window; j < start[b]; ++j) {
        const double shape = std::exp(-delta[b] * (double(j) - double(start[b])) * dt);
        num += corrected[j][b] * shape;
        den += shape * shape;
      }
      level[b] = den > 0 ? num / den : 0.0;
      info.extended = true;
    }
    info.startSeconds[b] = double(start[b]) * dt;
  }

  // 3. Length.
  size_t bins = traced;
  if (settings.lengthSeconds > 0) {
    bins = std::max<size_t>(1, size_t(std::ceil(settings.lengthSeconds / dt)));
  } else if (info.extended) {
    double end = 0;
    for (int b = 0; b < kNumBands; ++b)
      if (start[b] < traced && level[b] > 0)
        end = std::max(end, info.startSeconds[b] + settings.dynamicRangeDb / 10.0 * std::log(10.0) / delta[b]);
    end = std::min(end, settings.maxAutoSeconds);
    bins = std::max(bins, size_t(std::ceil(end / dt)));
  } else {
    // Nothing to extend: end after the last arrival.
    bins = size_t(std::max(1L, h.lastNonEmptyBin() + 1));
  }

  EnergyHistogram out(dt, bins);
  for (size_t i = 0; i < bins; ++i) {
    BandArrayD e{};
    double meanIn = 0, meanOut = 0;
    for (int b = 0; b < kNumBands; ++b) {
      if (i < start[b] && i < traced) {
        e[b] = corrected[i][b];
        meanIn += h.energy(i, b);
      } else if (start[b] < traced) {
        e[b] = level[b] * std::exp(-delta[b] * (double(i) - double(start[b])) * dt);
      }
      meanOut += e[b];
    }
    // Direction: the traced bin's, scaled with its energy; none where extrapolated.
    Vec3d dir{};
    if (i < traced && meanIn > 0) dir = h.directionSum(i) * (meanOut / meanIn);
    // add() weights the direction by the band mean; pass it normalised.
    const double mean = meanOut / kNumBands;
    out.add(i, e, mean > 0 ? dir / mean : Vec3d{});
  }
  if (settings.lengthSeconds == 0) {
    // Automatic length: where the Schroeder decay of every band has fallen
    // by the dynamic range (faint late arrivals of open scenes add nothing).
    const double floor = std::pow(10.0, -settings.dynamicRangeDb / 10.0);
    size_t keep = 1;
    for (int b = 0; b < kNumBands; ++b) {
      double total = 0;
      for (size_t i = 0; i < out.binCount(); ++i) total += out.energy(i, b);
      double remaining = total;
      for (size_t i = 0; i < out.binCount() && remaining > floor * total; ++i) {
        remaining -= out.energy(i, b);
        keep = std::max(keep, i + 1);
      }
    }
    if (keep < out.binCount()) {
      EnergyHistogram trimmed(dt, keep);
      std::copy(out.data().begin(), out.data().begin() + long(keep * EnergyHistogram::kStride), trimmed.data().begin());
      out = std::move(trimmed);
    }
  }
  info.lengthSeconds = out.durationSeconds();
  if (infoOut) *infoOut = info;
  return out;
}

}  // namespace earshot
