#pragma once
/** @file Zero-phase octave-band filter for IR analysis.
 *
 *  Design: a 4th-order Butterworth high-pass and a 4th-order Butterworth
 *  low-pass (bilinear transform with pre-warping, two biquads each), run
 *  forward then backward over the signal (zero phase, magnitude squared:
 *  8th-order skirts). The cut-offs are widened so that the squared response is
 *  -3 dB at the nominal octave edges fc/sqrt(2) and fc*sqrt(2) (IEC 61260
 *  base-2 octaves), so adjacent bands cross at half power; the cut-offs are
 *  placed on the pre-warped frequency axis so this holds up to Nyquist. The
 *  centre gain is -0.44 dB (the skirts of the high- and low-pass overlap);
 *  energy ratios and decay rates do not depend on it.
 *
 *  Why zero phase: the filter's ringing is then symmetric about every arrival
 *  instead of trailing it, so energy ratios (C50, D50, Ts) are not biased late
 *  and a short decay is not lengthened by the filter's own decay (ISO 3382-1
 *  warns that at 125 Hz a causal octave filter's ringing limits the shortest
 *  measurable EDT; cf. Jacobsen & Rindel 1987, time-reversed filtering). The
 *  pre-ringing sits before the direct sound; `preGuardSamples` says how far.
 *  Measured EDT bias on an exponentially decaying 125 Hz tone (analyzeIr):
 *  +0.8 % at EDT = 0.2 s, +3.8 % at 0.1 s (under 1 JND), +30 % at 0.05 s; it
 *  scales with 1 / fc (250 Hz: +3.8 % at 0.05 s). T20/T30 stay within 1.5 %
 *  down to T = 8 / fc. analyzeIr reports shorter values as n/a. (The limit
 *  usually quoted for a causal octave filter is B T > 16, i.e. T > 0.18 s at
 *  125 Hz.) The filter's own impulse response has T30 = 4.3 / fc.
 *
 *  Threading: pure functions; any thread. */
#include <cstddef>
#include <vector>

namespace earshot::analysis {

/** Zero-phase octave-band filtering of `count` samples (not owned). Returns
 *  `preGuardSamples + count + postGuardSamples` samples: the output sample
 *  preGuardSamples + i is aligned with input sample i; the guards hold the
 *  filter's pre- and post-ringing. Requires octaveBandAvailable(rateHz,
 *  centerHz). */
std::vector<double> octaveBandFilter(const float* signal, size_t count, double rateHz, double centerHz,
                                     size_t* preGuardSamples);

/** As octaveBandFilter, into `out` (resized; its capacity is reused). */
void octaveBandFilterInto(const float* signal, size_t count, double rateHz, double centerHz,
                          std::vector<double>& out, size_t* preGuardSamples);

/** Two bands at once (about twice as fast as two calls), both with the same
 *  `guard` samples before and after (pass the larger band's guard, i.e. of the
 *  lower centre frequency). */
void octaveBandFilterPairInto(const float* signal, size_t count, double rateHz, double centerA, double centerB,
                              size_t guard, std::vector<double>& outA, std::vector<double>& outB);

/** True when the octave's upper edge centerHz * sqrt(2) lies below 0.45 rateHz. */
bool octaveBandAvailable(double rateHz, double centerHz);

/** Extent of the filter's ringing on each side of an impulse (samples), where
 *  the energy outside is below -50 dB of the total. */
size_t octaveBandGuardSamples(double rateHz, double centerHz);

/** Fractional-octave bands, `bandwidthOctaves` wide (1/3: third octaves):
 *  edges at centre x 2^(-+bandwidth / 2), -3 dB there, 0 dB at the centre.
 *  Bandwidth 1 is the octave filter above; narrower bands are weighted in
 *  the frequency domain (zero phase) by a Butterworth band-pass's shape on
 *  the pre-warped axis with the skirts of a sixth-order band-pass run
 *  forward and backward: a third octave passes its neighbours' centres at
 *  about -36 dB. Same output layout (guards) as octaveBandFilter. */
bool fractionalOctaveBandAvailable(double rateHz, double centerHz, double bandwidthOctaves);
size_t fractionalOctaveBandGuardSamples(double rateHz, double centerHz, double bandwidthOctaves);
void fractionalOctaveBandFilterInto(const float* signal, size_t count, double rateHz, double centerHz,
                                    double bandwidthOctaves, std::vector<double>& out, size_t* preGuardSamples);

}  // namespace earshot::analysis
