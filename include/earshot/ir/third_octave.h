#pragma once
/** @file Third-octave IRs (issue 20): the engine's octave pipeline run three
 *  times, its bands shifted by -1/3, 0 and +1/3 of an octave, and the three
 *  IRs combined into one whose every third octave carries its own band.
 *
 *  Pass p (thirdOctavePassShift) traces, finds image sources and
 *  synthesises with materials resampled at its bands
 *  (MaterialTable::atBandShift: a file given in third octaves is used as
 *  such), air absorption at its bands and the band filters shifted with
 *  them; its octave band b is third-octave band j = 3 b + p (bands.h).
 *  Within a third of an octave of its centre a pass's IR carries that band
 *  alone (the late noises cross over in a third of an octave at the
 *  octave edges, band_filter_bank.h), so the combined IR is
 *  sum_p M_p * IR_p, where M_p sums the zero-phase weights of pass p's third
 *  octaves: raised-cosine crossovers kThirdOctaveCrossoverOctaves wide at
 *  the third octaves' edges, summing to one at every frequency (what the
 *  passes share, e.g. a direct sound of equal band gains, comes through
 *  unchanged). The three passes share the seed and noise key; their late
 *  noises are the same white noise, so the crossovers join coherent
 *  signals.
 *
 *  Cost: three IRs and a transform of the IR per pass and channel. Omni,
 *  binaural (the HRTF model's diffuse-field band energies at each pass's
 *  bands: BinauralModel::relativeBandEnergy) and ambisonic receivers. */
#include <array>

#include "earshot/core/bands.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/materials/material.h"

namespace earshot {

/** Width of the crossovers between neighbouring third octaves, in octaves:
 *  each band keeps a sixth of an octave that is its own, and the
 *  crossovers stay where both passes carry their band alone. */
constexpr double kThirdOctaveCrossoverOctaves = 1.0 / 6.0;

/** Weight of third-octave band j (0 .. kNumThirdOctaveBands - 1) at `hz`:
 *  in [0, 1], summing to one over the bands at every frequency. */
double thirdOctaveBandWeight(int j, double hz);

/** M_p: the weight of pass p's IR at `hz` (the sum of its bands' weights). */
double thirdOctavePassWeight(int pass, double hz);

struct ThirdOctaveIrResult {
  /** The combined IR: the passes' channels, the longest pass's length (the
   *  others padded with silence). */
  AudioBuffer ir;
  /** Each pass's own result (its octave-band IR, histogram, report data):
   *  third-octave band j is passes[j % 3]'s band j / 3. */
  std::array<OmniIrResult, kThirdOctavePasses> passes;
  double combineMs = 0.0;  ///< the combination's time
};

/** A third-octave IR of one source/listener pair: computeIr per pass (each
 *  on all of pool's threads), then combined. `settings.air.bandShiftOctaves`
 *  must be 0 (each pass sets its own); a per-band directivity is
 *  resampled to each pass's bands as materials are. Bit-identical for the
 *  same inputs whatever the thread count (as computeIr). */
Result<ThirdOctaveIrResult> computeIrThirdOctave(const RayTracer& tracer, const MaterialTable& materials,
                                                 const Vec3d& source, const Vec3d& listener,
                                                 const OmniIrSettings& settings, ThreadPool& pool,
                                                 const BinauralReceiver* binaural = nullptr,
                                                 const AmbisonicReceiver* ambisonic = nullptr);

/** Third-octave band j's traced decay (tracedDecay of its pass, at its band). */
struct ThirdOctaveDecay {
  std::array<double, kNumThirdOctaveBands> edtSeconds{}, t20Seconds{}, t30Seconds{};
};
ThirdOctaveDecay tracedDecay(const ThirdOctaveIrResult& result);

}  // namespace earshot
