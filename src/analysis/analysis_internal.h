#pragma once
// Helpers shared by the analysis sources (private to the module; not API).
// Threading: pure functions; any thread.
#include <cstddef>
#include <vector>

namespace earshot::analysis::detail {

/** ISO 3382-1 onset over one or more channels of `frames` samples each (not
 *  owned): the first frame where any channel's energy is within 20 dB of the
 *  largest energy of all channels. Requires a non-zero sample (else returns
 *  `frames`). Defined in room_acoustics.cpp. */
size_t isoOnsetFrame(const float* const* channels, size_t channelCount, size_t frames);

/** Index of the first non-finite sample of x[0..count), or count if none. */
size_t firstNonFinite(const float* x, size_t count);

/** Zero-phase low-pass: a 4th-order Butterworth run forward then backward
 *  (8th-order skirt, -3 dB at cutoffHz, which must lie below 0.45 rateHz).
 *  Writes guard + count + guard samples to `out` (resized) and returns guard:
 *  out[guard + i] is aligned with signal[i]; the guards hold the ringing
 *  (energy beyond them below -50 dB, as octaveBandGuardSamples). Defined in
 *  octave_filter.cpp. */
size_t zeroPhaseLowPassInto(const float* signal, size_t count, double rateHz, double cutoffHz,
                            std::vector<double>& out);

}  // namespace earshot::analysis::detail
