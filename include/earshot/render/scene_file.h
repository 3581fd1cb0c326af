#pragma once
/** @file The scene file of `earshot render` (JSON; docs/scene-format.md,
 *  samples/scene.schema.json): geometry, materials, listener and sources
 *  with their dry audio and trajectories, and render settings. Parsing only:
 *  no geometry or audio is loaded here (files are checked to exist, and the
 *  material map against the materials). */
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/io/input_file.h"
#include "earshot/render/trajectory.h"

namespace earshot {

/** Source directivity. The pattern's axis is the source's forward vector. */
enum class SourceDirectivity {
  kOmni,      ///< gain 1 in every direction
  kCardioid,  ///< gain (1 + cos(angle from forward)) / 2: 1 ahead, 0.5 sideways, 0 behind
};

/** Pressure gain of a directivity pattern for a direction at `cosAngle`
 *  (cosine of the angle between the source's forward vector and the
 *  direction of emission, in [-1, 1]). Pure function. */
inline double directivityGain(SourceDirectivity d, double cosAngle) {
  return d == SourceDirectivity::kCardioid ? 0.5 * (1.0 + cosAngle) : 1.0;
}

/** "omni" / "cardioid". */
const char* directivityName(SourceDirectivity d);

struct SceneListener {
  Trajectory trajectory;
};

struct SceneSource {
  std::string name;         ///< unique within the scene, non-empty
  std::string audioPath;    ///< dry audio file, resolved against the scene file's directory
  Trajectory trajectory;    ///< forward is the directivity axis
  double gainDb = 0.0;      ///< applied to the dry audio, [-120, 60] dB
  SourceDirectivity directivity = SourceDirectivity::kOmni;
  double startSeconds = 0.0;  ///< scene time at which the dry audio's first sample plays, >= 0
  // Per-source controls (the runtime's SourceSettings; docs/scene-format.md).
  double directivityAlpha = 0.0;       ///< pattern (1 - a) + a cos: "directivity" as a name or a number
  double directivitySharpness = 1.0;   ///< [1, 16]
  std::vector<double> directivityBands;  ///< "directivity_bands": 7 alphas (125 Hz .. 8 kHz), or empty
  double directGainDb = 0.0;           ///< [-120, 60]
  double reflectionsGainDb = 0.0;      ///< [-120, 60]
  std::string distanceModel = "physical";  ///< physical | inverse | linear | exponential
  double minDistance = 1.0, maxDistance = 100.0, rolloff = 1.0;
  std::vector<std::pair<double, double>> distanceTable;  ///< distance_model "table": (m, gain) points
  std::string occlusion = "ray";       ///< ray | off | volumetric
  double radius = 0.5;                 ///< volumetric occlusion's sphere, metres
  bool transmission = true;
  int priority = 0;                    ///< [0, 1000]
};

/** Air absorption (ISO 9613-1); the engine's AirConditions takes these values. */
struct SceneAir {
  bool enabled = true;            ///< false: "air": "off"
  double temperatureC = 20.0;     ///< [-20, 50] C
  double humidityPercent = 50.0;  ///< [0, 100] %
  double pressureKpa = 101.325;   ///< [50, 120] kPa
};

/** settings.ambisonic_order when the scene does not say. */
constexpr int kDefaultSceneAmbisonicOrder = 1;

struct SceneSettings {
  double sampleRateHz = 48000.0;         ///< output rate, [8000, 192000] Hz
  std::string quality = "balanced";      ///< a name of sceneQualityNames() (ir's qualityPreset())
  std::optional<uint32_t> rays;          ///< overrides the preset's ray count, [1, 1e8]
  std::optional<uint32_t> bounces;       ///< overrides the preset's bounce count, [0, 100000]
  std::string hrtfPath;                  ///< SOFA file, resolved; empty: the built-in default set
  uint64_t seed = 1;                     ///< same seed, same output
  double updateRateHz = 20.0;            ///< acoustic (IR) updates per second of scene time, (0, 1000]
  std::optional<double> durationSeconds; ///< length of the output, (0, 86400]; unset: the renderer decides
  SceneAir air;
  double speedOfSound = 343.0;           ///< m/s, [100, 2000]
  /** Reflections (runtime::EngineSettings::ambisonicOrder): 1-3 world-frame
   *  ambisonic reflections rotated by the head every block (a head turn
   *  costs no simulation); 0 a binaural IR per source, simulated again when
   *  the head turns. */
  int ambisonicOrder = kDefaultSceneAmbisonicOrder;
  /** "binaural" (left, right) or "ambisonic": the AmbiX channels (ACN,
   *  SN3D) of ambisonicOrder in the listener's frame, for any ambisonic
   *  player. */
  std::string output = "binaural";
  /** How the sources' reflections are traced (runtime::EngineSettings::
   *  traceMode): "shared", one listener-centred trace for every source
   *  simulated together; "per-source", a trace from each; "auto", shared
   *  for 3 sources or more. */
  std::string trace = "auto";
};

/** A parsed scene file. Paths are resolved against the scene file's
 *  directory (lexically normalised; absolute paths are kept). */
struct SceneDescription {
  std::string sceneFile;      ///< as given to the parser (its display name)
  std::string geometryPath;   ///< glTF (.gltf/.glb); empty: free field
  std::string materialsPath;  ///< materials JSON; empty: the built-in default set
  /** glTF material name -> acoustic material name, as loadGltf() takes it:
   *  from the inline object, or read from materialMapPath. */
  std::map<std::string, std::string> materialMap;
  std::string materialMapPath;  ///< the map's file when given as a path; empty when inline or absent
  SceneListener listener;
  std::vector<SceneSource> sources;  ///< at least one
  SceneSettings settings;
};

struct SceneParseOptions {
  /** Unknown keys are errors (default: a warning each, naming the key's path). */
  bool strict = false;
  /** Check that referenced files exist, read the materials file and a
   *  material map given as a path, and check the map's acoustic names
   *  against the materials. false: no file is opened (fuzzing, tools that
   *  only rewrite scenes); a map given as a path is then left unread. */
  bool checkFiles = true;
  /** File references (geometry, materials, material_map, audio, hrtf) may
   *  lead outside the scene file's folder (absolute paths, ..; symlinks are
   *  resolved first). Default: refused (input_file.h), unless the process
   *  defaults say otherwise (`earshot --allow-outside-paths`). */
  bool allowOutsidePaths = defaultInputLimits().allowOutsidePaths;
};

/** Reads and parses a scene file; see parseSceneText. A missing file is
 *  kNotFound; one over 64 MB is kOutOfRange. Thread-safe (no shared state
 *  but defaultMaterials(), itself thread-safe). */
Result<SceneDescription> loadSceneFile(const std::string& path, const SceneParseOptions& options = {},
                                       std::vector<std::string>* warnings = nullptr);

/** Parses scene-file text. Relative paths resolve against `baseDirectory`;
 *  `displayName` (normally the file's path) starts every message.
 *
 *  Errors are one line naming the file, the JSON path and what was expected:
 *  `scene.json: settings.sample_rate: expected a number, got string "48k"`,
 *  `scene.json: sources[0].path[2].t: 1 is not after ...`,
 *  `scene.json:4:7: malformed JSON: ...` (line and column). Checked: types,
 *  required keys, duplicate keys, ranges (documented on each field; numbers
 *  that overflow a double, like 1e999, and huge ones), negative times,
 *  keyframe order, zero or parallel forward/up, quality names, unique source
 *  names, referenced files (see SceneParseOptions::checkFiles), acoustic
 *  material names in the material map.
 *  Unknown keys: with options.strict an error, else a warning appended to
 *  `warnings` (may be null), e.g. `scene.json: sources[1].gian_db: unknown
 *  key (did you mean "gain_db"?)`. Thread-safe. */
Result<SceneDescription> parseSceneText(const std::string& text, const std::string& baseDirectory,
                                        const std::string& displayName, const SceneParseOptions& options = {},
                                        std::vector<std::string>* warnings = nullptr);

/** The keys the parser accepts in each kind of object, so the JSON Schema
 *  (samples/scene.schema.json) and the docs can be checked against it.
 *  `object` is "scene" (top level), "listener", "source", "keyframe",
 *  "settings" or "air". */
struct SceneObjectKeys {
  std::string object;
  std::vector<std::string> keys;
};
const std::vector<SceneObjectKeys>& sceneFileKeys();

/** Quality names the scene file accepts: "draft", "balanced", "high",
 *  "reference" (the presets of earshot/ir/ir_pipeline.h's qualityPreset()). */
const std::vector<std::string>& sceneQualityNames();

}  // namespace earshot
