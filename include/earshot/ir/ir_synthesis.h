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
 *  Conventions (DESIGN.md): time 0 = emission, 1/r amplitude, float, no
 *  normalisation. */
#include <cstdint>

#include "earshot/core/audio_buffer.h"
#include "earshot/core/status.h"
#include "earshot/propagation/direct_path.h"
#include "earshot/propagation/energy_histogram.h"

namespace earshot {

struct IrSynthesisSettings {
  double sampleRateHz = 48000.0;  ///< [8000, 384000]
  double lengthSeconds = 0.0;     ///< > 0: exact length; 0: automatic (direct + reflections + 50 ms)
  uint64_t seed = 1;              ///< noise seed
};

/** Validates settings (message names the field). */
Status validate(const IrSynthesisSettings& settings);

/** Length in samples that synthesizeOmniIr will produce. */
size_t irLengthSamples(const DirectPath* direct, const EnergyHistogram* reflections, const IrSynthesisSettings& settings);

/** A 1-channel pressure IR. Either input may be null (then omitted). */
Result<AudioBuffer> synthesizeOmniIr(const DirectPath* direct, const EnergyHistogram* reflections,
                                     const IrSynthesisSettings& settings);

}  // namespace earshot
