#pragma once
/** @file Completing the late tail beyond the traced bounces.
 *
 *  12 bounces cover ~0.15 s of a 1.4 s reverb in a 10x7x3 m room; a tracer
 *  that stops there truncates the IR. Instead, every ray stopped by the
 *  bounce limit carries on "virtually", decaying at the population's rate:
 *  the root delta of the renewal (Lotka) equation
 *  sum_k w_k rho_k exp(-m l_k) exp(delta l_k / c) = sum_k w_k over the later
 *  reflections (energy w, free path l, fraction kept rho, air m). With one
 *  free path length this is Eyring's law; with the real spread of free paths
 *  it is the slower decay Kuttruff derives (Room Acoustics, 5th ed., sec.
 *  5.5), ~7 % slower than Eyring's at alpha 0.3 in a flat 10x7x3 m room, as a
 *  full trace shows. The virtual energy in flight V(t) is detected as the
 *  traced energy in flight A(t) is: the completed histogram is
 *  H(t) + kappa V(t), kappa being the detections per unit energy in flight
 *  measured in the traced part (after the image-source paths). The completed
 *  part carries no direction (a late diffuse field).
 *
 *  Tail probes (ReflectionSettings::tailProbes) measure instead of assume:
 *  cut rays (by default every one) carry on until 60 dB down, and what they
 *  deposit in the receiver sphere, scaled from the energy they were cut
 *  with to all cut rays, is the tail; kappa V(t) fills in only beyond where
 *  a probe ended (at the population's rate). A specular room decays as a
 *  mixture of exponentials (between parallel walls each direction class of
 *  rays at its own rate), slower late than any one rate, and its late field
 *  gathers where the slowest classes fly (a flutter's axis), which one kappa
 *  misses by 10 - 25 % in late windows (the multiband box of
 *  tests/regression). Measured there, 16 seeds at the default budget with
 *  flutter cones: RMS error of the converged T20s 0.30 JND and of T30 at
 *  4 kHz 0.33 (energy in flight x kappa: 1.1 and 0.9). Without probes, V(t)
 *  is all cut rays at delta.
 *
 *  kappa is measured where the trace is complete (virtual energy under 10 %
 *  of the traced). With few bounces no bin after the image sources is (8
 *  bounces in a 10x7x3 m room cut the rays about when the last second-order
 *  image source arrives); kappa then comes from the probes' own detections
 *  per energy in flight, else from the traced rays still in flight there.
 *  The probes are smoothed within the traced histogram (a window folds
 *  back at its end), and probes the histogram's end stopped join V(t) there,
 *  so the tail carries on past the end without a step. */
#include <array>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/propagation/air_absorption.h"
#include "earshot/propagation/energy_histogram.h"
#include "earshot/propagation/reflection_tracer.h"

namespace earshot {

struct TailCompletionSettings {
  double lengthSeconds = 0.0;    ///< > 0: the histogram ends exactly there; 0: automatic
  /** Automatic length: until every band's Schroeder decay (remaining energy)
   *  has fallen this far; an open scene whose rays escape gets a short IR. */
  double dynamicRangeDb = 60.0;
  double maxAutoSeconds = 30.0;  ///< cap of the automatic length
  double speedOfSound = 343.0;
  AirConditions air;
  /** Detections before this time are not used to calibrate kappa (the early
   *  specular paths rendered as image sources are missing from them). */
  double calibrationStartSeconds = 0.0;
  /** Every field but calibrationStartSeconds, which TailRates do not use, equal. */
  bool sameRatesAs(const TailCompletionSettings& o) const {
    return lengthSeconds == o.lengthSeconds && dynamicRangeDb == o.dynamicRangeDb &&
           maxAutoSeconds == o.maxAutoSeconds && speedOfSound == o.speedOfSound && air.enabled == o.air.enabled &&
           air.temperatureC == o.air.temperatureC && air.humidityPercent == o.air.humidityPercent &&
           air.pressureKpa == o.air.pressureKpa && air.bandShiftOctaves == o.air.bandShiftOctaves;
  }
};

struct TailInfo {
  bool extended = false;             ///< rays were cut and their virtual energy added
  BandArrayD startSeconds{};         ///< where the traced energy in flight falls below the virtual
  BandArrayD decayRatePerSecond{};   ///< the population's rate delta (energy, nepers per second, air included)
  BandArrayD t60Seconds{};           ///< 13.8155 / delta
  BandArrayD kappa{};                ///< detections per unit energy in flight
  BandArrayD meanLoss{};             ///< energy-weighted loss per reflection
  BandArrayD meanFreePathMeters{};   ///< energy-weighted mean free path
  /** Per band: the tail is what the tail probes deposited
   *  (ReflectionSettings::tailProbes), not kappa x the population's rate. */
  std::array<bool, kNumBands> probed{};
  double lengthSeconds = 0.0;        ///< of the returned histogram
  /** The automatic length stopped at maxAutoSeconds before the slowest
   *  band had decayed by dynamicRangeDb (a room that hardly absorbs): that
   *  cap, else 0. The IR then ends abruptly. */
  double cappedAtSeconds = 0.0;
};

/** Returns the completed histogram (a new, possibly longer one). */
/** What completeTail derives from the rays' tail data alone: the decay
 *  rates (the renewal equation) and the energy the cut rays and the
 *  probes' ends join the virtual population with, per bin. The same for
 *  every source of a shared trace (they share one RayTail, the listener's
 *  rays'): made once there (tailRates) and given to each source's
 *  completeTail. */
struct TailRates {
  double binSeconds = 0.0;           ///< of the histograms they serve
  size_t tracedBins = 0;
  TailCompletionSettings settings;   ///< they were made with
  TailInfo info;                     ///< the rate fields: decayRatePerSecond (delta), t60Seconds, meanLoss, meanFreePathMeters
  bool anyCut = false;
  size_t bins = 0;                   ///< the completed length; 0: where each histogram's last detection is
  BandArrayD cutTotal{};             ///< all the energy the rays were cut with (air applied)
  std::vector<BandArrayD> cut, probeEnds;  ///< per bin: energy joining (air applied)
};

/** The rates of `tail` (its rays(); probeDetected is not read) for
 *  histograms of `tracedBins` bins of `binSeconds`. */
Result<TailRates> tailRates(const TailData& tail, double binSeconds, size_t tracedBins,
                            const TailCompletionSettings& settings);

/** `rates` (optional): tailRates of this `tail` and settings, made once for
 *  many histograms; ignored (made again) when made for another bin, length
 *  or settings. The result is the same bits either way. */
Result<EnergyHistogram> completeTail(const EnergyHistogram& histogram, const TailData& tail,
                                     const TailCompletionSettings& settings, TailInfo* info = nullptr,
                                     const TailRates* rates = nullptr);

}  // namespace earshot
