// Tail completion: method and references in tail_completion.h.
#include "earshot/propagation/tail_completion.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace earshot {

namespace {
constexpr double kNepersPer60Db = 13.815510557964274;  // ln(10^6)
constexpr double kFitWindowSeconds = 0.05;
constexpr double kProbeSpreadFraction = 0.1;
}  // namespace

namespace {
Status validateTailSettings(const TailCompletionSettings& settings) {
  if (!(settings.lengthSeconds >= 0 && settings.lengthSeconds <= 600))
    return invalidArgument("tail length " + std::to_string(settings.lengthSeconds) + " s is outside [0, 600]");
  if (!(settings.dynamicRangeDb > 0 && settings.dynamicRangeDb <= 200))
    return invalidArgument("tail dynamic range " + std::to_string(settings.dynamicRangeDb) + " dB is outside (0, 200]");
  return Status::ok();
}
}  // namespace

Result<TailRates> tailRates(const TailData& tail, double dt, size_t traced, const TailCompletionSettings& settings) {
  EARSHOT_RETURN_IF_ERROR(validateTailSettings(settings));
  if (!(dt > 0)) return invalidArgument("tail rates: histogram bin is not positive");
  const RayTail& rays = tail.rays();
  TailRates r;
  r.binSeconds = dt;
  r.tracedBins = traced;
  r.settings = settings;
  TailInfo& info = r.info;
  const BandArrayD m = airEnergyAttenuationPerMeter(settings.air);  // energy, 1/m

  // 1. Decay rates: solve the renewal equation F(delta) = 1 by bisection
  // (F increases with delta).
  BandArrayD& delta = info.decayRatePerSecond;
  bool haveRates = !rays.pathEnergy.empty();
  for (int b = 0; b < kNumBands && haveRates; ++b) {
    double total = 0, kept = 0, length = 0;
    for (size_t i = 0; i < rays.pathEnergy.size(); ++i) {
      total += rays.pathEnergy[i][b];
      kept += rays.pathRetained[i][b];
      length += rays.pathRetained[i][b] * freePathBinCenter(i);
    }
    if (!(total > 0)) {
      haveRates = false;
      break;
    }
    info.meanLoss[b] = 1.0 - kept / total;
    info.meanFreePathMeters[b] = kept > 0 ? length / kept : 0.0;
    std::vector<std::pair<double, double>> paths;  // (free path, energy kept), non-empty bins only
    for (size_t i = 0; i < rays.pathRetained.size(); ++i)
      if (rays.pathRetained[i][b] > 0) paths.emplace_back(freePathBinCenter(i), rays.pathRetained[i][b]);
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
    info.t60Seconds[b] = kNepersPer60Db / delta[b];
  }

  // 2. Virtual energy in flight of the cut rays, per band. Every cut ray
  // carries on at the population's rate delta (air included; the energy it
  // was cut with lacks the air of its path so far, applied when it joins).
  // NOTE: between parallel walls a specular ray keeps its direction class
  // and its own rate, and a flat room's specular decay is a mixture of
  // exponentials slower than this (tests/regression, known gaps); per-ray
  // rates fit that case but lengthen the tail of furnished rooms absurdly
  // (T30 5 s at 125 Hz in the furnished sample), where furniture scrambles
  // directions.
  double lastCut = 0;
  for (const CutRay& c : rays.cutRays) lastCut = std::max(lastCut, double(c.pathMeters) / settings.speedOfSound);
  r.anyCut = !rays.cutRays.empty() && haveRates;
  double slowest = 1e30;
  for (int b = 0; b < kNumBands; ++b) slowest = std::min(slowest, delta[b]);

  // Length of the histogram to fill (0: where the traced histogram ends).
  if (settings.lengthSeconds > 0) {
    r.bins = std::max<size_t>(1, size_t(std::ceil(settings.lengthSeconds / dt)));
  } else if (r.anyCut) {
    // The probes' decay may be slower than the population's rate: cover
    // where they were still in flight, and where the last of them ended.
    double lastProbe = 0;
    for (size_t i = 0; i < rays.probeAlive.size(); ++i)
      for (int b = 0; b < kNumBands; ++b)
        if (rays.probeAlive[i][b] > 0) lastProbe = double(i + 1) * dt;
    for (const CutRay& c : rays.probeEnds)
      lastProbe = std::max(lastProbe, double(c.pathMeters) / settings.speedOfSound);
    const double wanted = std::max(lastCut, lastProbe) + settings.dynamicRangeDb / 10.0 * std::log(10.0) / slowest;
    const double end = std::min(settings.maxAutoSeconds, wanted);
    if (!(wanted <= settings.maxAutoSeconds)) r.info.cappedAtSeconds = settings.maxAutoSeconds;
    r.bins = std::max(traced, size_t(std::ceil(end / dt)));
  }

  if (r.anyCut) {
    // Energy (air applied) joining the virtual population in each bin: rays
    // cut by the bounce limit (and all of it), or probes stopped by their
    // own limits. One exponential per ray and band.
    const size_t bins = r.bins;
    // A probe the trace's end stopped ends on the segment that crossed it,
    // a free path later: its energy joins where it stopped being counted in
    // flight (the last traced bin), not then. Joined late, the first ~10 ms
    // after the end held neither (the 100 ms after a 4 s trace read ~1 dB
    // low in a concrete room).
    auto join = [&](const std::vector<CutRay>& ends, std::vector<BandArrayD>& joining, BandArrayD* total,
                    size_t latest) {
      joining.assign(bins, BandArrayD{});
      for (const CutRay& c : ends) {
        const size_t bin = std::min(latest, size_t(double(c.pathMeters) / settings.speedOfSound / dt));
        for (int b = 0; b < kNumBands; ++b) {
          const double e = double(c.energy[b]) * std::exp(-m[b] * c.pathMeters);
          if (total) (*total)[b] += e;
          if (bin < bins) joining[bin][b] += e;
        }
      }
    };
    join(rays.cutRays, r.cut, &r.cutTotal, SIZE_MAX);
    join(rays.probeEnds, r.probeEnds, nullptr, rays.probeAlive.empty() ? SIZE_MAX : rays.probeAlive.size() - 1);
  }
  return r;
}

Result<EnergyHistogram> completeTail(const EnergyHistogram& h, const TailData& tail,
                                     const TailCompletionSettings& settings, TailInfo* infoOut,
                                     const TailRates* given) {
  EARSHOT_RETURN_IF_ERROR(validateTailSettings(settings));
  const double dt = h.binSeconds();
  const size_t traced = h.binCount();
  TailRates own;
  const TailRates* rates = given;
  if (!rates || rates->binSeconds != dt || rates->tracedBins != traced || !rates->settings.sameRatesAs(settings)) {
    auto made = tailRates(tail, dt, traced, settings);
    if (!made.isOk()) return made.status();
    own = std::move(made.value());
    rates = &own;
  }
  const RayTail& rays = tail.rays();
  TailInfo info = rates->info;
  const BandArrayD& delta = rates->info.decayRatePerSecond;
  const bool anyCut = rates->anyCut;
  const size_t bins = rates->bins > 0 ? rates->bins : size_t(std::max(1L, h.lastNonEmptyBin() + 1));

  std::vector<BandArrayD> virtualEnergy(bins, BandArrayD{});
  // Of it, the part carried on at the population's rate (beyond the probes'
  // ends, or all of it without probes), and what the probes deposited, scaled.
  std::vector<BandArrayD> extrapolated(bins, BandArrayD{}), probeDeposits(bins, BandArrayD{});
  if (anyCut) {
    // With tail probes: their measured energy in flight, scaled from the
    // energy they were cut with to all cut rays' (beyond the probes' own
    // end, at the population's rate). Without: every cut ray at that rate.
    // The bands side by side in one pass over the bins (seven independent
    // recurrences; band by band, each pass waited on its one chain).
    bool probed[kNumBands];
    double scale[kNumBands], step[kNumBands], v[kNumBands];
    for (int b = 0; b < kNumBands; ++b) {
      probed[b] = !rays.probeAlive.empty() && rays.probeCutEnergy[b] > 0;
      scale[b] = probed[b] ? rates->cutTotal[b] / rays.probeCutEnergy[b] : 1.0;
      step[b] = std::exp(-delta[b] * dt);
      v[b] = 0;
      info.probed[b] = probed[b];
    }
    for (size_t i = 0; i < bins; ++i) {
      const bool alive = i < rays.probeAlive.size(), detected = i < tail.probeDetected.size();
      for (int b = 0; b < kNumBands; ++b) {
        v[b] *= step[b];
        const double measured = probed[b] && alive ? rays.probeAlive[i][b] : 0.0;
        virtualEnergy[i][b] = scale[b] * (measured + v[b]);  // a ray cut in bin i is in flight from bin i + 1
        extrapolated[i][b] = scale[b] * v[b];
        if (probed[b] && detected) probeDeposits[i][b] = scale[b] * tail.probeDetected[i][b];
        v[b] += (probed[b] ? rates->probeEnds : rates->cut)[i][b];
      }
    }
  }

  // The probes' deposits are few late, a burst wherever one long-lived ray
  // crossed the sphere: spread each bin's energy evenly over +-
  // kProbeSpreadFraction of its time (energy and mean arrival time kept), a
  // shape a synthesised reverb can follow without false noise floors.
  // Within the trace's histogram, where the probes were detected: a
  // window reaching past its end is folded back at the end (mirrored), so
  // a bin's energy stays before the end and a smooth profile stays smooth
  // there. Spread past the end, it left the last 0.3 s of a 4 s trace 2-3
  // dB low (measured in a concrete room, six seeds) and added to bins the
  // extrapolation fills anyway.
  if (!tail.probeDetected.empty()) {
    const size_t measured = std::min(bins, tail.probeDetected.size());
    std::vector<BandArrayD> diff(bins + 1, BandArrayD{});
    for (size_t j = 0; j < bins; ++j) {
      const size_t k = size_t(kProbeSpreadFraction * double(j));
      const size_t lo = j >= k ? j - k : 0, hi = std::min(bins, j + k + 1);
      if (j < measured && j + k + 1 > measured) {
        const size_t over = j + k + 1 - measured;  // <= k < measured - lo
        for (int b = 0; b < kNumBands; ++b) {
          const double share = probeDeposits[j][b] / double(measured + over - lo);
          diff[lo][b] += share;
          diff[measured][b] -= share;
          diff[measured - over][b] += share;
          diff[measured][b] -= share;
        }
        continue;
      }
      for (int b = 0; b < kNumBands; ++b) {
        const double share = probeDeposits[j][b] / double(hi - lo);
        diff[lo][b] += share;
        diff[hi][b] -= share;
      }
    }
    BandArrayD running{};
    for (size_t i = 0; i < bins; ++i)
      for (int b = 0; b < kNumBands; ++b) {
        running[b] += diff[i][b];
        probeDeposits[i][b] = std::max(0.0, running[b]);
      }
  }

  // 3. kappa: detections per unit energy in flight, where the trace is
  // complete (virtual energy under 10 % of the traced) and after the
  // image-source part.
  // Bins where the traced histogram, the energy in flight and the virtual
  // energy all exist (an open scene's filled length can be shorter).
  const size_t usable = std::min({traced, bins, rays.alive.size()});
  const size_t calib0 = std::min(usable, size_t(settings.calibrationStartSeconds / dt));
  for (int b = 0; b < kNumBands; ++b) {
    size_t end = calib0;
    while (end < usable && rays.alive[end][b] > 0 && virtualEnergy[end][b] < 0.1 * rays.alive[end][b]) ++end;
    size_t begin = calib0;
    if (end > begin + size_t(kFitWindowSeconds / dt)) begin = end - size_t(kFitWindowSeconds / dt);
    double detected = 0, inFlight = 0;
    for (size_t i = begin; i < end; ++i) {
      detected += h.energy(i, b);
      inFlight += rays.alive[i][b];
    }
    info.kappa[b] = inFlight > 0 ? detected / inFlight : 0.0;
    if (!(inFlight > 0) && info.probed[b] && !tail.probeDetected.empty()) {
      // No bin past the image sources where the trace is complete (few
      // bounces: the rays are cut about when the last image source
      // arrives). The same ratio from the probes, which are detected and
      // counted in flight alike past their cut; without it the tail past
      // the probes' end (the histogram's length, maxTimeSeconds) was lost.
      const size_t probeBins = std::min({traced, bins, rays.probeAlive.size(), tail.probeDetected.size()});
      double probeDetected = 0, probeInFlight = 0;
      for (size_t i = calib0; i < probeBins; ++i) {
        probeDetected += tail.probeDetected[i][b];
        probeInFlight += rays.probeAlive[i][b];
      }
      info.kappa[b] = probeInFlight > 0 ? probeDetected / probeInFlight : 0.0;
    }
    if (!(info.kappa[b] > 0)) {
      // No probes either (tailProbes 0): the traced rays still in flight
      // after the image sources, though most were cut (the first
      // kFitWindowSeconds where any are). Without it the whole tail after
      // the cut was lost (0.3 s for a 14 s room at 8 bounces).
      detected = inFlight = 0;
      size_t taken = 0;
      for (size_t i = calib0; i < usable && taken < size_t(kFitWindowSeconds / dt) + 1; ++i) {
        if (!(rays.alive[i][b] > 0)) continue;
        detected += h.energy(i, b);
        inFlight += rays.alive[i][b];
        ++taken;
      }
      info.kappa[b] = inFlight > 0 ? detected / inFlight : 0.0;
    }
    size_t start = traced;
    for (size_t i = 0; i < usable; ++i)
      if (virtualEnergy[i][b] > rays.alive[i][b] && virtualEnergy[i][b] > 0) {
        start = i;
        break;
      }
    info.startSeconds[b] = double(start) * dt;
  }
  info.extended = anyCut;

  EnergyHistogram out(dt, bins);
  for (size_t i = 0; i < bins; ++i) {
    BandArrayD e{};
    double meanIn = 0, meanOut = 0;
    for (int b = 0; b < kNumBands; ++b) {
      const double tracedEnergy = i < traced ? h.energy(i, b) : 0.0;
      // Probed bands: what the probes deposited, which follows whatever
      // shape the late field takes (a flutter gathers it on its axis, where
      // one detections-per-energy ratio misses it by 10 - 25 %), and kappa
      // only for the extrapolated rest. Unprobed: kappa x energy in flight.
      e[b] = tracedEnergy + (info.probed[b] && !tail.probeDetected.empty()
                                 ? probeDeposits[i][b] + info.kappa[b] * extrapolated[i][b]
                                 : info.kappa[b] * virtualEnergy[i][b]);
      meanIn += tracedEnergy;
      meanOut += e[b];
    }
    // Direction: the traced detections keep theirs; the virtual part has none.
    Vec3d dir = (i < traced && meanIn > 0) ? h.directionSum(i) : Vec3d{};
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
