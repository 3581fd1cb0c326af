#pragma once
/** @file Completing the late tail beyond the traced bounces.
 *
 *  12 bounces cover ~0.15 s of a 1.4 s reverb in a 10x7x3 m room; a tracer
 *  that stops there truncates the IR. Per band:
 *  1. Decay rate delta from the traced rays: the root of the renewal (Lotka)
 *     equation sum_k w_k rho_k exp(-m l_k) exp(delta l_k / c) = sum_k w_k
 *     over the reflections of the later half of the bounces (energy w_k,
 *     free path l_k before it, fraction kept rho_k, air m). With one free
 *     path length this is Eyring's law; with the real spread of free paths
 *     it is the slower decay Kuttruff derives (Room Acoustics, 5th ed.,
 *     sec. 5.5: a flat 10x7x3 m room with alpha = 0.3 decays ~7 % slower
 *     than Eyring's formula says, and so does a full trace).
 *  2. Completeness of each bin: rays stopped by the bounce limit would have
 *     carried on; their energy, decayed at delta, is "virtual" energy in
 *     flight V. A bin's detections are scaled by (A + V) / A, A being the
 *     traced energy in flight, while A / (A + V) >= 1/2.
 *  3. From the first bin below that, an exponential at rate delta, its level
 *     fitted (least squares with the known slope) to the preceding 50 ms.
 *  The completed bins carry no direction (a late diffuse field). */
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
};

struct TailInfo {
  bool extended = false;             ///< an exponential tail was appended in some band
  BandArrayD startSeconds{};         ///< where the extrapolation starts, per band
  BandArrayD decayRatePerSecond{};   ///< delta (energy, nepers per second)
  BandArrayD t60Seconds{};           ///< 13.8155 / delta
  BandArrayD meanLoss{};             ///< energy-weighted loss per reflection
  BandArrayD meanFreePathMeters{};   ///< energy-weighted mean free path
  double lengthSeconds = 0.0;        ///< of the returned histogram
};

/** Returns the completed histogram (a new, possibly longer one). */
Result<EnergyHistogram> completeTail(const EnergyHistogram& histogram, const TailData& tail,
                                     const TailCompletionSettings& settings, TailInfo* info = nullptr);

}  // namespace earshot
