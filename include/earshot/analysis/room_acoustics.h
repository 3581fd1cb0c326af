#pragma once
/** @file ISO 3382-1 room-acoustic parameters of an impulse response: EDT, T20,
 *  T30 (Schroeder decay with Lundeby noise-floor treatment), C50, C80, D50 and
 *  centre time Ts, per octave band (125 Hz .. 8 kHz) and broadband.
 *
 *  Conventions: time 0 of an IR is the emission. The direct sound is the first
 *  sample whose energy is within 20 dB of the IR's maximum (ISO 3382-1 onset);
 *  every metric is measured from there. A metric that cannot be computed (decay
 *  range too short, band above Nyquist, silent signal) is NaN and carries a
 *  one-line reason; a valid pure impulse gives C50 = C80 = +inf.
 *
 *  Threading: all functions are pure (no shared state); any thread may call
 *  them concurrently. */
#include <array>
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "earshot/core/audio_buffer.h"
#include "earshot/core/bands.h"
#include "earshot/core/status.h"

namespace earshot::analysis {

/** The parameters we report, in table order. */
enum class Metric { kEdt = 0, kT20, kT30, kC50, kC80, kD50, kTs };
constexpr int kMetricCount = 7;
constexpr std::array<Metric, kMetricCount> kAllMetrics = {Metric::kEdt, Metric::kT20, Metric::kT30, Metric::kC50,
                                                         Metric::kC80, Metric::kD50, Metric::kTs};

/** "EDT", "T20", "T30", "C50", "C80", "D50", "Ts". */
const char* metricName(Metric metric);
/** Unit of a metric as printed: "s", "dB" or "" (D50). */
const char* metricUnit(Metric metric);
/** Parses a metric name (case-insensitive: "edt", "T30", "ts"). */
Result<Metric> parseMetric(const std::string& name);

/** Just-noticeable differences (ISO 3382-1 Table A.1; T20/T30 5 % by common use). */
constexpr double kJndDecayRelative = 0.05;  ///< EDT, T20, T30: 5 % of the reference value
constexpr double kJndClarityDb = 1.0;       ///< C50, C80
constexpr double kJndDefinition = 0.05;     ///< D50 (absolute)
constexpr double kJndCentreTimeS = 0.010;   ///< Ts

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/** Parameters of one band (or broadband) of one channel. */
struct BandMetrics {
  double bandCenterHz = 0.0;  ///< octave centre; 0 = broadband (unfiltered)
  double edtS = kNaN;         ///< early decay time (0 .. -10 dB fit, x6), seconds
  double t20S = kNaN;         ///< reverberation time from the -5 .. -25 dB fit, seconds
  double t30S = kNaN;         ///< reverberation time from the -5 .. -35 dB fit, seconds
  double c50Db = kNaN;        ///< clarity 50 ms, dB (+inf if no late energy)
  double c80Db = kNaN;        ///< clarity 80 ms, dB (+inf if no late energy)
  double d50 = kNaN;          ///< definition 50 ms, energy fraction in [0, 1]
  double tsS = kNaN;          ///< centre time, seconds after the direct sound
  double onsetS = kNaN;       ///< direct-sound time (ISO onset) after emission, seconds
  double decayEndS = kNaN;    ///< end of the decay used (Lundeby cross-point or end of data), seconds
  bool noiseFloorFound = false;   ///< true if Lundeby found a noise floor (then the tail is compensated)
  double noiseFloorDb = kNaN;     ///< noise level relative to the decay's initial level, dB (NaN if none)
  double dynamicRangeDb = kNaN;   ///< usable decay range of the EDC, dB (positive)
  /** Why a metric is NaN (empty when it has a value). Indexed by Metric. */
  std::array<std::string, kMetricCount> naReason;

  double value(Metric metric) const;
  const std::string& reason(Metric metric) const { return naReason[size_t(metric)]; }
};

/** How the noise at the end of a measured IR is handled. */
enum class NoiseTreatment {
  kLundeby,  ///< Lundeby et al. 1995: truncate at the cross-point, add the exponential tail (default)
  kNone,     ///< integrate to the last non-zero sample (exact, noise-free data)
};

/** Whether the window's times count from the emission or from the direct sound. */
enum class WindowOrigin { kEmission, kDirectSound };

/** Whether the direct sound takes part in the metrics. */
enum class DirectSound { kInclude, kExclude };

/** Options of analyzeIr / analyzeBandSignal. Defaults follow ISO 3382-1. */
struct AnalysisOptions {
  NoiseTreatment noise = NoiseTreatment::kLundeby;
  /** Only samples with time in [windowStartS, windowEndS) are used (others are
   *  treated as silence); e.g. a reference exact only up to 0.75 s. */
  double windowStartS = 0.0;
  double windowEndS = std::numeric_limits<double>::infinity();
  WindowOrigin windowOrigin = WindowOrigin::kEmission;
  /** kExclude zeroes the broadband IR from `directBeforeS` before the onset
   *  to `directAfterS` after it (before band filtering); metrics still count
   *  time from the onset. */
  DirectSound direct = DirectSound::kInclude;
  double directBeforeS = 0.0005;
  double directAfterS = 0.0025;
  /** Octaves (kAnalysisBandCount results) or third octaves
   *  (kThirdOctaveAnalysisBandCount: thirdOctaveCenterHz(j), j < 21, then
   *  broadband). */
  enum class Bands { kOctave, kThirdOctave } bands = Bands::kOctave;
};

/** Parameters of a signal that is already band-limited (or broadband), with
 *  no further filtering: e.g. one channel of an exact per-band impulse train.
 *  `signal` is not owned and must hold `count` samples at `rateHz` (> 0).
 *  onsetSample: the direct sound's sample, or -1 to detect it (20 dB rule) in
 *  this signal. preGuardSamples: energy this many samples before the onset
 *  still counts in C50/C80/D50/Ts (the pre-ringing of a zero-phase filter,
 *  which is symmetric about each arrival); 0 for unfiltered data. The decay
 *  fits always start at the onset. Never fails: problems become NaN + reason. */
BandMetrics analyzeBandSignal(const float* signal, size_t count, double rateHz, long long onsetSample = -1,
                              size_t preGuardSamples = 0, NoiseTreatment noise = NoiseTreatment::kLundeby);
inline BandMetrics analyzeBandSignal(const std::vector<float>& signal, double rateHz) {
  return analyzeBandSignal(signal.data(), signal.size(), rateHz);
}

/** Number of results analyzeIr returns: kNumBands octave bands then broadband. */
constexpr int kAnalysisBandCount = kNumBands + 1;
constexpr int kBroadbandIndex = kNumBands;
/** With AnalysisOptions::Bands::kThirdOctave: 21 third octaves then broadband (last). */
constexpr int kThirdOctaveAnalysisBandCount = kNumThirdOctaveBands + 1;

/** ISO 3382-1 parameters of a one-channel IR: element b < kNumBands is the
 *  octave band kBandCentersHz[b] (zero-phase octave filter, see
 *  octave_filter.h), element kBroadbandIndex is the unfiltered IR (with
 *  third octaves, options.bands: 21 bands through 1/3-octave filters, which
 *  ring longer: EDT below 45 / fc and T20/T30 below 36 / fc are n/a;
 *  broadband last). The onset
 *  is detected once on the broadband IR and used for every band. A band's
 *  EDT below 12 / fc and T20/T30 below 8 / fc (125 Hz: 96 ms, 64 ms) are n/a:
 *  there the octave filter's own ringing biases them by over 1 JND. Errors
 *  (invalid argument): empty IR, rate not in [1000, 1e6] Hz, non-finite
 *  sample, all samples zero, a window that leaves no energy.
 *  Cost: O(bands x samples), ~11-14 ms for 2 s at 48 kHz (analysis_bench),
 *  half of it the filter. Memory: keeps two thread_local scratch buffers of
 *  ~8 bytes x samples each between calls (safe to call from many threads). */
Result<std::vector<BandMetrics>> analyzeIr(const std::vector<float>& ir, double rateHz,
                                           const AnalysisOptions& options = {});

/** Parameters of every channel of a (mono or binaural: left, right) IR.
 *  NOTE: binaural cues (ITD, ILD, IACC) are a separate analysis that can sit
 *  beside `channels` here without changing the per-channel results. */
struct IrAnalysis {
  double sampleRateHz = 0.0;
  size_t frameCount = 0;
  std::vector<std::vector<BandMetrics>> channels;  ///< channels[c][band], kAnalysisBandCount each
};

/** analyzeIr for each channel of `audio` (or only channel `onlyChannel` if
 *  >= 0; out of range is an error naming it). */
Result<IrAnalysis> analyzeAudio(const AudioBuffer& audio, const AnalysisOptions& options = {},
                                int onlyChannel = -1);

}  // namespace earshot::analysis
