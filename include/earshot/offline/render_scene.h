#pragma once
/** @file Offline rendering of a scene file to binaural audio: the runtime's
 *  update path (runtime/engine.h) driven by the scene's trajectories instead
 *  of a game. Scene time advances in blocks of the engine's block size; at
 *  every block the sources' and listener's poses are set from their
 *  trajectories (so the direct sound's delay, level and HRTF follow motion
 *  sample-accurately across blocks: Doppler, no clicks), and at the scene's
 *  update rate the reflections are simulated again for every source whose
 *  pose or the listener's changed by more than RenderOptions::minMoveMeters /
 *  minTurnDegrees since its last simulation (crossfaded in the convolver).
 *
 *  A source that does not move, heard by a listener that does not move, is
 *  simulated once, with the direct sound inside its IR: its output is then
 *  exactly its dry signal convolved with the IR `earshot ir` computes for the
 *  same positions and settings (an IR that ends within the render's 10 s
 *  cut; a longer one is simulated only up to it).
 *
 *  Directivity: a cardioid source is the engine's power-normalised cardioid
 *  about its trajectory's forward vector (runtime SourceSettings): the
 *  direct sound follows the pattern toward the listener every block, each
 *  reflection its own emission direction (a source facing away still fills
 *  the room); a directional source is simulated again when it turns more
 *  than minTurnDegrees.
 *
 *  Threading: renderScene() is a blocking call; it uses settings.threads (or
 *  the options' override) worker threads for tracing. Same scene, options
 *  and seed give bit-identical output whatever the thread count. */
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "earshot/core/audio_buffer.h"
#include "earshot/core/status.h"
#include "earshot/render/scene_file.h"

namespace earshot {

struct RenderOptions {
  std::optional<std::string> quality;  ///< overrides the scene's quality preset
  std::optional<uint64_t> seed;        ///< overrides the scene's seed
  unsigned threads = 0;                ///< tracing threads; 0: all cores
  double fromSeconds = 0.0;            ///< first scene time rendered, >= 0
  std::optional<double> toSeconds;     ///< end of the render (exclusive); unset: the scene's duration
  /** Reverberation carried into `fromSeconds`: rendering starts this much
   *  earlier (not before 0) and the pre-roll is dropped. */
  double preRollSeconds = 2.0;
  /** At an update, a source's reflections are simulated again only if it or
   *  the listener moved more than this (metres) or the listener turned more
   *  than minTurnDegrees since its last simulation; 0 and 0: at any change.
   *  The direct sound follows every block regardless. */
  double minMoveMeters = 0.25;
  double minTurnDegrees = 5.0;
  /** Overrides the scene's settings.ambisonic_order. With ambisonic
   *  reflections (1-3) a head turn never re-simulates (minTurnDegrees is not
   *  used); with 0 (binaural) it does. */
  std::optional<int> ambisonicOrder;
  /** Called now and then with the fraction done (0..1); from the calling thread. */
  std::function<void(double fraction)> progress;
  /** Overrides the scene's settings.output ("binaural" or "ambisonic": the
   *  AmbiX channels of the reflections' order in the listener's frame). */
  std::optional<std::string> outputFormat;
  /** Overrides settings.trace: "auto", "shared" or "per-source". */
  std::optional<std::string> trace;
  /** Set: each rendered block goes here (outputChannels() planar channels:
   *  left, right or the AmbiX channels; frames), in order, and
   *  RenderResult::audio stays empty, so a render of any length needs no
   *  memory for its output (`earshot render` streams to its WAV). A non-ok
   *  Status stops the render with it. Unset: the output is collected in
   *  RenderResult::audio, within the memory limit. */
  std::function<Status(const float* const* channels, size_t frames)> sink;
};

struct RenderResult {
  AudioBuffer audio;            ///< 2 channels (left, right) or the AmbiX channels, at the scene's rate
  double audioSeconds = 0.0;
  double wallSeconds = 0.0;
  double simulationSeconds = 0.0;  ///< tracing and IR synthesis (wall)
  double audioProcessSeconds = 0.0;  ///< convolution and direct sound (wall)
  uint64_t simulations = 0;     ///< source IRs simulated
  double peak = 0.0;            ///< largest |sample|
  bool clipped = false;         ///< some |sample| > 1 (the WAV is float: nothing is cut, but players will clip)
  std::vector<std::string> log; ///< what was loaded and how (resampling, modes, durations)
};

/** Renders `scene`. Errors name the file and what is wrong (unreadable
 *  geometry, audio, HRTF; a time window outside the scene). Before
 *  allocating, what the render holds in memory (every source's convolution
 *  state for 10 s IRs, ~26 bytes per IR frame: 12.5 MB a source at 48 kHz;
 *  the dry audio; the output when there is no sink) is estimated and refused
 *  past defaultInputLimits().maxMemoryBytes; with a sink, an output longer
 *  than a WAV holds (kMaxWavBytes) is refused before rendering. */
Result<RenderResult> renderScene(const SceneDescription& scene, const RenderOptions& options);

/** The scene's length when settings.durationSeconds is unset: the last dry
 *  sample's time (start + length) over all sources, plus 2 s of reverberation. */
/** The channels renderScene() writes for `scene` with `options`: 2, or
 *  (order+1)^2 for ambisonic output; an error for ambisonic output without
 *  ambisonic reflections or an unknown format. */
Result<size_t> renderOutputChannels(const SceneDescription& scene, const RenderOptions& options);

double defaultSceneDuration(const SceneDescription& scene, const std::vector<double>& dryLengthsSeconds);

}  // namespace earshot
