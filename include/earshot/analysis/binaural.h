#pragma once
/** @file Binaural cues of a two-channel (left, right) impulse response: the
 *  direct sound's interaural time and level differences (ITD, ILD) and the
 *  interaural cross-correlation coefficient (IACC) of the early and late parts
 *  per octave band (125 Hz .. 8 kHz) and broadband.
 *
 *  Definitions (times count from the direct sound, the ISO 3382-1 onset: the
 *  first frame where either ear's energy is within 20 dB of the larger ear's
 *  maximum; room_acoustics.h uses the same rule per channel):
 *  - Direct-sound window: [onset - directBeforeS, onset + directAfterS]
 *    (default -1 ms .. +2.5 ms: the whole head-related response of either ear
 *    for any ITD up to 1 ms). A reflection whose path is less than
 *    343 m/s x 2.5 ms = 0.86 m longer than the direct one (e.g. the floor
 *    reflection of a distant source) falls inside and biases ITD and ILD;
 *    shorten directAfterS for such geometry.
 *  - ITD = arrival(right) - arrival(left), seconds: positive when the left ear
 *    leads (source on the left). The lag in [-maxLagS, +maxLagS] maximising
 *    the cross-correlation sum_t l(t) r(t + lag) of the two ears' direct-sound
 *    windows after a zero-phase low-pass at itdLowPassHz (ITD is a
 *    low-frequency cue; the windowed segments are filtered with their ringing,
 *    so the window does not bias the lag). Refined between samples by
 *    band-limited (Kaiser-windowed sinc) interpolation of the correlation and
 *    a golden-section search: a fractional delay resolves to ~0.001 us at
 *    48 kHz (see tests/analysis/binaural_test.cpp).
 *  - ILD = 10 log10(E_left / E_right), dB, over the direct-sound window,
 *    unfiltered: positive when the left ear is louder.
 *  - IACC (ISO 3382-1:2009 Annex A.3; Hidaka, Beranek & Okano, JASA 98(2),
 *    1995): IACF(tau) = sum_t l(t) r(t + tau) / sqrt(sum l^2 sum r^2), both
 *    ears cut to the window [t1, t2) (r is zero outside it, as when the
 *    windowed segments are cross-correlated), IACC = max |IACF| over tau in
 *    [-maxLagS, +maxLagS], refined between samples as the ITD. Cutting both
 *    ears keeps IACC in [0, 1] and exactly 1 for identical ears; ISO's
 *    formula read literally takes r(t + tau) from outside the window and
 *    exceeds 1 when the energy changes over tau (a mono IR copied to both
 *    ears with reverberation time T: up to sqrt(exp(13.8 x 1 ms / T)), 1.014
 *    for T = 0.5 s, at tau = -1 ms instead of 0).
 *    Early: [t1, t2) = [0, earlyEndS) (default 80 ms; in octave bands t1 is
 *    moved back by the zero-phase filter's pre-ringing so that the direct
 *    sound counts whole, as C80 does in room_acoustics). Late: [earlyEndS,
 *    lateEndS) (default to the end of the IR; Hidaka et al. use 750 ms).
 *    Octave bands use the zero-phase filter of octave_filter.h on each ear.
 *  A value that cannot be computed is NaN with a one-line reason: band above
 *  the sample rate's limit, an ear without energy in the window, or (late
 *  IACC in a band) late energy below the octave filter's own ringing (-50 dB
 *  of the band's total). ILD is +-inf when one ear is silent in the window.
 *
 *  Cost: O((bands + 1) x samples x lags), lags = 2 (maxLagS fs + 33); about
 *  60 ms for a 2 s IR at 48 kHz (twice analyzeAudio's for both ears).
 *  Threading: pure function; any thread. */
#include <array>
#include <limits>
#include <string>

#include "earshot/analysis/room_acoustics.h"
#include "earshot/core/audio_buffer.h"
#include "earshot/core/status.h"

namespace earshot::analysis {

/** Windows and filters of analyzeBinaural (see the file comment). */
struct BinauralAnalysisSettings {
  double directBeforeS = 0.001;   ///< direct-sound window starts this long before the onset, s (>= 0)
  double directAfterS = 0.0025;   ///< ... and ends this long after it, s (> 0)
  double itdLowPassHz = 1500.0;   ///< low-pass before the ITD correlation, Hz (> 0; none if >= 0.45 fs)
  double maxLagS = 0.001;         ///< ITD and IACC lag search range +-, s (in (0, 0.01])
  double earlyEndS = 0.080;       ///< early/late boundary after the onset, s (> 0)
  double lateEndS = std::numeric_limits<double>::infinity();  ///< late window end after the onset, s
};

/** IACC of one octave band (or broadband) in the early and late windows. */
struct IaccBand {
  double bandCenterHz = 0.0;  ///< octave centre; 0 = broadband (unfiltered)
  double early = kNaN;        ///< IACC_E in [0, ~1]
  double earlyLagS = kNaN;    ///< tau of the maximum, s (positive: left leads)
  double late = kNaN;         ///< IACC_L in [0, ~1]
  double lateLagS = kNaN;     ///< tau of the maximum, s
  std::string earlyReason;    ///< why `early` is NaN (empty when it has a value)
  std::string lateReason;     ///< why `late` is NaN
};

/** Binaural cues of one two-channel IR. */
struct BinauralMetrics {
  double onsetS = kNaN;          ///< direct sound (ISO onset over both ears) after emission, s
  double directStartS = kNaN;    ///< direct-sound window start after emission, s (clamped to the IR)
  double directEndS = kNaN;      ///< direct-sound window end (exclusive), s
  double itdS = kNaN;            ///< arrival(right) - arrival(left), s; positive: left ear leads
  double itdPeakCorrelation = kNaN;  ///< normalised low-passed cross-correlation at the ITD, in [-1, 1]
  bool itdAtSearchLimit = false;     ///< the maximum lies at +-maxLagS (the true lag may be outside)
  std::string itdReason;         ///< why itdS is NaN
  double ildDb = kNaN;           ///< 10 log10(E_left / E_right) in the direct window, dB; positive: left louder
  /** Element b < kNumBands: octave kBandCentersHz[b]; kBroadbandIndex: unfiltered. */
  std::array<IaccBand, kAnalysisBandCount> iacc;
  double iaccE3 = kNaN;  ///< mean early IACC of the 500 Hz, 1 kHz and 2 kHz bands (Hidaka et al.)
  double iaccL3 = kNaN;  ///< mean late IACC of the same three bands
};

/** Binaural cues of `ir` (channels[0] = left, [1] = right, equal lengths).
 *  Errors (invalid argument, naming the problem): not exactly 2 channels,
 *  channels of different lengths, no samples, rate outside [1000, 1e6] Hz, a
 *  non-finite sample (channel and index), all samples zero, settings out of
 *  range (naming the field). */
Result<BinauralMetrics> analyzeBinaural(const AudioBuffer& ir, const BinauralAnalysisSettings& settings = {});

}  // namespace earshot::analysis
