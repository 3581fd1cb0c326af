#pragma once
/** @file From propagation results to a pressure impulse response.
 *
 *  Direct sound: a band-limited fractional-delay impulse, built in the
 *  frequency domain as (1/r) sum_b g_b W_b(f) exp(-j 2 pi f r/c), where W_b
 *  are the complementary band weights (band_filter_bank.h) and g_b the
 *  band's pressure factor (air, transmission): exact delay, no interpolation
 *  error below Nyquist.
 *  Reflections: one white Gaussian noise, multiplied per band by the square
 *  root of the histogram's energy density (linearly interpolated between bin
 *  centres), filtered by W_b and summed (Kuttruff, Room Acoustics, 5th ed.,
 *  sec. 9.7; Vorlaender, Auralization, sec. 11.4). With equal bands this is
 *  just the noise times the envelope: bands recombine flat.
 *  Conventions (docs/design.md): time 0 = emission, 1/r amplitude, float, no
 *  normalisation. */
#include <cstdint>
#include <vector>

#include "earshot/core/audio_buffer.h"
#include "earshot/core/status.h"
#include "earshot/propagation/direct_path.h"
#include "earshot/propagation/energy_histogram.h"

namespace earshot {

/** One discrete arrival (the direct sound, an image source): a band-limited
 *  fractional-delay impulse. */
struct Arrival {
  double delaySeconds = 0;
  double gain = 0;          ///< broadband pressure factor (spreading)
  BandArrayD bandGain{};    ///< per-band pressure factor (air, reflections, transmission)
  Vec3d direction;          ///< unit, from the listener toward the arrival (world frame)
};

/** The direct path as an arrival (inaudible paths give gain 0). */
Arrival toArrival(const DirectPath& direct);

struct IrSynthesisSettings {
  double sampleRateHz = 48000.0;  ///< [8000, 384000]
  double lengthSeconds = 0.0;     ///< > 0: exact length; 0: automatic (direct + reflections + 50 ms)
  uint64_t seed = 1;              ///< noise seed
  /** Where in the seed's noise the late reflections start reading: 0 reads
   *  it from its start; any other key from an offset that mix64(seed, key)
   *  decides. computeIr passes noiseKeyOf(source, listener), so IRs of
   *  different positions carry independent noise (position averages
   *  converge) while the same inputs still give the same bits. */
  uint64_t noiseKey = 0;
  /** The bands are the engine's octaves shifted by this (kBandCentersHz x
   *  2^shift): a third-octave pass (bands.h) sets -1/3 or +1/3. [-1, 1] */
  double bandShiftOctaves = 0.0;
  /** Ambisonic synthesis only, > 0: the channels after W are made for their
   *  first partialFrames samples only (zeros after), W whole. What the
   *  runtime's shared tail needs of a source whose tail it does not play:
   *  its own IR up to the split, and W's energy after it. 0: every channel
   *  whole. */
  size_t partialFrames = 0;
};

/** A key for IrSynthesisSettings::noiseKey from a source/listener pair: made
 *  of the positions' exact bits, the same when the two swap (reciprocity),
 *  never 0. */
uint64_t noiseKeyOf(const Vec3d& source, const Vec3d& listener);

/** Validates settings (message names the field). */
Status validate(const IrSynthesisSettings& settings);

/** Length in samples that synthesizeOmniIr will produce. */
size_t irLengthSamples(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                       const IrSynthesisSettings& settings);

/** A 1-channel pressure IR from discrete arrivals and a (late) energy
 *  histogram, which may be null. */
Result<AudioBuffer> synthesizeOmniIr(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                                     const IrSynthesisSettings& settings);

/** Convenience: the direct path (may be null) and a histogram. */
Result<AudioBuffer> synthesizeOmniIr(const DirectPath* direct, const EnergyHistogram* reflections,
                                     const IrSynthesisSettings& settings);

}  // namespace earshot
