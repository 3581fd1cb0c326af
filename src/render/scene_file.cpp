// Scene-file parser. The format is docs/scene-format.md; the JSON Schema
// samples/scene.schema.json lists the same keys (tests/render checks both
// against sceneFileKeys()). Every check names the file and the JSON path.
#include "earshot/render/scene_file.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <tuple>

#include "earshot/materials/material.h"
#include "json_reader.h"

namespace earshot {

namespace fs = std::filesystem;
using json = nlohmann::json;
using render_detail::jsonIndexPath;
using render_detail::jsonKeyPath;
using render_detail::jsonQuoted;

namespace {

constexpr uintmax_t kMaxTextFileBytes = uintmax_t(64) << 20;

const std::vector<std::string> kSceneKeys = {"$schema", "description", "geometry", "materials", "material_map",
                                             "listener", "sources", "settings"};
const std::vector<std::string> kListenerKeys = {"position", "forward", "up", "path"};
const std::vector<std::string> kSourceKeys = {"name", "audio", "position", "forward", "up", "path",
                                              "gain_db", "directivity", "start", "directivity_sharpness",
                                              "direct_gain_db", "reflections_gain_db", "distance_model",
                                              "min_distance", "max_distance", "rolloff", "occlusion", "radius",
                                              "transmission", "priority", "distance_table",
                                              "directivity_bands"};
const std::vector<std::string> kKeyframeKeys = {"t", "position", "forward", "up"};
const std::vector<std::string> kSettingsKeys = {"sample_rate", "quality", "rays", "bounces", "hrtf", "seed",
                                                "update_rate_hz", "duration", "air", "speed_of_sound",
                                                "ambisonic_order", "output", "trace"};
const std::vector<std::string> kAirKeys = {"temperature_c", "humidity_pct", "pressure_kpa"};

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

// Levenshtein distance, for "did you mean" hints.
size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diag = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

// The closest candidate within maxDistance edits, or "" (for "did you mean" hints).
template <class Names>
std::string closest(const std::string& word, const Names& candidates, size_t maxDistance) {
  std::string best;
  size_t bestD = maxDistance + 1;
  for (const auto& c : candidates) {
    size_t d = editDistance(word, c);
    if (d < bestD) {
      bestD = d;
      best = c;
    }
  }
  return best;
}

// "string \"48k\"", "number 3", "array", ...: what the file holds, for "got ...".
std::string describe(const json& v) {
  std::string s = v.dump(-1, ' ', false, json::error_handler_t::replace);
  if (s.size() > 40) s = s.substr(0, 37) + "...";
  if (v.is_string()) return "string " + s;
  if (v.is_number()) return "number " + s;
  if (v.is_boolean()) return "boolean " + s;
  if (v.is_null()) return "null";
  return v.type_name();
}

Result<std::string> readTextFile(const std::string& path, const std::string& what) {
  return readInputFile(path, what, kMaxTextFileBytes);
}

struct Range {
  double lo, hi;
  bool loOpen;       // lo itself excluded
  const char* unit;  // " Hz", " s", ... (may be "")
};

class SceneReader {
 public:
  SceneReader(std::string file, std::string baseDir, const SceneParseOptions& options,
              std::vector<std::string>* warnings)
      : mFile(std::move(file)), mBase(std::move(baseDir)), mOptions(options), mWarnings(warnings) {}

  Result<SceneDescription> read(const json& root);

 private:
  Status fail(const std::string& path, const std::string& what, StatusCode code = StatusCode::kInvalidArgument) const {
    return {code, mFile + ": " + (path.empty() ? "" : path + ": ") + what};
  }
  // A Status from a helper that already names the path (Trajectory, loadMaterials): prefix the file.
  Status prefixed(const Status& s, const std::string& path = "") const {
    return {s.code(), mFile + ": " + (path.empty() ? "" : path + ": ") + s.message()};
  }

  Status checkKeys(const json& obj, const std::string& path, const std::vector<std::string>& allowed) {
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      if (std::find(allowed.begin(), allowed.end(), it.key()) != allowed.end()) continue;
      const std::string hint = closest(it.key(), allowed, 2);
      const std::string msg = "unknown key" + (hint.empty() ? "" : " (did you mean \"" + hint + "\"?)");
      if (mOptions.strict) return fail(jsonKeyPath(path, it.key()), msg);
      if (mWarnings) mWarnings->push_back(mFile + ": " + jsonKeyPath(path, it.key()) + ": " + msg);
    }
    return Status::ok();
  }

  Status expectObject(const json& v, const std::string& path, const std::string& expected) const {
    if (!v.is_object()) return fail(path, "expected " + expected + ", got " + describe(v));
    return Status::ok();
  }

  Result<double> number(const json& v, const std::string& path, const Range& r) const {
    if (!v.is_number()) return fail(path, "expected a number, got " + describe(v));
    const double d = v.get<double>();
    if (!std::isfinite(d)) return fail(path, "not a finite number");
    if (d < r.lo || d > r.hi || (r.loOpen && d == r.lo))
      return fail(path, fmt(d) + r.unit + " is outside " + (r.loOpen ? "(" : "[") + fmt(r.lo) + ", " + fmt(r.hi) + "]" +
                            r.unit, StatusCode::kOutOfRange);
    return d;
  }

  // Seconds from the start of the scene: >= 0 with a message that says so.
  Result<double> time(const json& v, const std::string& path) const {
    if (v.is_number() && std::isfinite(v.get<double>()) && v.get<double>() < 0)
      return fail(path, fmt(v.get<double>()) + " s is negative (times are seconds from the start of the scene, >= 0)");
    return number(v, path, {0.0, kMaxSceneSeconds, false, " s"});
  }

  Result<uint64_t> wholeNumber(const json& v, const std::string& path, uint64_t lo, uint64_t hi) const {
    if (v.is_number_unsigned()) {
      uint64_t u = v.get<uint64_t>();
      if (u < lo || u > hi)
        return fail(path, std::to_string(u) + " is outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]",
                    StatusCode::kOutOfRange);
      return u;
    }
    if (v.is_number_integer())
      return fail(path, std::to_string(v.get<int64_t>()) + " is outside [" + std::to_string(lo) + ", " +
                            std::to_string(hi) + "]", StatusCode::kOutOfRange);
    if (v.is_number_float()) {
      const double d = v.get<double>();
      if (!(std::isfinite(d) && d == std::floor(d)))
        return fail(path, "expected a whole number, got " + describe(v));
      // double(hi) may round up past hi (2^64 for the seed): uint64_t(d) needs d < 2^64.
      if (d < double(lo) || d > double(hi) || d >= 18446744073709551616.0)
        return fail(path, fmt(d) + " is outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]",
                    StatusCode::kOutOfRange);
      return uint64_t(d);
    }
    return fail(path, "expected a whole number, got " + describe(v));
  }

  Result<std::string> text(const json& v, const std::string& path, const std::string& expected) const {
    if (!v.is_string()) return fail(path, "expected " + expected + ", got " + describe(v));
    std::string s = v.get<std::string>();
    if (s.empty()) return fail(path, "expected " + expected + ", got an empty string");
    return s;
  }

  Result<Vec3d> vec3(const json& v, const std::string& path) const {
    const std::string expected = "[x, y, z] (3 numbers)";
    if (!v.is_array()) return fail(path, "expected " + expected + ", got " + describe(v));
    if (v.size() != 3)
      return fail(path, "expected " + expected + ", got an array of " + std::to_string(v.size()));
    double c[3];
    for (size_t i = 0; i < 3; ++i) {
      auto r = number(v[i], jsonIndexPath(path, i), {-kMaxCoordinateMeters, kMaxCoordinateMeters, false, ""});
      if (!r) return r.status();
      c[i] = *r;
    }
    return Vec3d{c[0], c[1], c[2]};
  }

  // A path to an existing file (checked when options.checkFiles), resolved
  // relative to the scene file's folder and kept inside it (unless allowed).
  Result<std::string> filePath(const json& v, const std::string& path, const std::string& what) const {
    auto s = text(v, path, "a path to " + what + " (string)");
    if (!s) return s.status();
    auto r = resolveReference(mBase, mFile + ": " + path, *s, mOptions.allowOutsidePaths);
    if (!r) return r.status();
    std::string resolved = *r;
    if (mOptions.checkFiles) {
      std::error_code ec;
      if (!fs::exists(resolved, ec))
        return fail(path, what + " " + jsonQuoted(resolved) + " not found", StatusCode::kNotFound);
      if (fs::is_directory(resolved, ec))
        return fail(path, jsonQuoted(resolved) + " is a directory, expected " + what);
    }
    return resolved;
  }

  Result<Trajectory> pose(const json& obj, const std::string& path, bool& pathGiven);
  Status readListener(const json& v, SceneListener& out);
  Status readSource(const json& v, const std::string& path, SceneSource& out);
  Status readSettings(const json& v, SceneSettings& out);
  Status readAir(const json& v, SceneAir& out);
  Status readMaterialMap(const json& v, SceneDescription& out);
  Status checkMaterialNames(const SceneDescription& scene, const std::string& mapPath, const std::string& filePrefix);

  std::string mFile, mBase;
  const SceneParseOptions& mOptions;
  std::vector<std::string>* mWarnings;
};

Result<Trajectory> SceneReader::pose(const json& obj, const std::string& path, bool& pathGiven) {
  const bool hasPosition = obj.contains("position"), hasPath = obj.contains("path");
  pathGiven = hasPath;
  if (hasPosition && hasPath)
    return fail(path, "give either \"position\" (static) or \"path\" (keyframes), not both");
  if (!hasPosition && !hasPath)
    return fail(jsonKeyPath(path, "position"), "missing (expected [x, y, z] in metres, or a keyframed \"path\")");
  // Object-level forward/up: the orientation of a static pose, or the
  // default of keyframes that leave theirs out (each keyframe's pair is then
  // checked, named by the keyframe).
  Vec3d forward = kDefaultForward, up = kDefaultUp;
  if (obj.contains("forward")) {
    auto f = vec3(obj["forward"], jsonKeyPath(path, "forward"));
    if (!f) return f.status();
    forward = *f;
  }
  if (obj.contains("up")) {
    auto u = vec3(obj["up"], jsonKeyPath(path, "up"));
    if (!u) return u.status();
    up = *u;
  }
  if (hasPosition) {
    auto p = vec3(obj["position"], jsonKeyPath(path, "position"));
    if (!p) return p.status();
    auto t = Trajectory::fromPose(*p, forward, up, path);
    if (!t) return prefixed(t.status());
    return t;
  }
  const std::string pathKey = jsonKeyPath(path, "path");
  const json& arr = obj["path"];
  if (!arr.is_array()) return fail(pathKey, "expected an array of keyframes {t, position, forward, up}, got " +
                                                describe(arr));
  if (arr.empty()) return fail(pathKey, "expected at least one keyframe, got an empty array");
  std::vector<Keyframe> keys;
  keys.reserve(arr.size());
  for (size_t i = 0; i < arr.size(); ++i) {
    const std::string kp = jsonIndexPath(pathKey, i);
    const json& k = arr[i];
    EARSHOT_RETURN_IF_ERROR(expectObject(k, kp, "a keyframe {t, position, forward, up}"));
    EARSHOT_RETURN_IF_ERROR(checkKeys(k, kp, kKeyframeKeys));
    Keyframe key;
    key.forward = forward;
    key.up = up;
    if (!k.contains("t")) return fail(jsonKeyPath(kp, "t"), "missing (expected the keyframe's time in seconds)");
    // Any finite t here: Trajectory reports negative, too late and out-of-order times by keyframe.
    const double big = std::numeric_limits<double>::max();
    auto t = number(k["t"], jsonKeyPath(kp, "t"), {-big, big, false, " s"});
    if (!t) return t.status();
    key.t = *t;
    if (!k.contains("position")) return fail(jsonKeyPath(kp, "position"), "missing (expected [x, y, z] in metres)");
    auto p = vec3(k["position"], jsonKeyPath(kp, "position"));
    if (!p) return p.status();
    key.position = *p;
    if (k.contains("forward")) {
      auto f = vec3(k["forward"], jsonKeyPath(kp, "forward"));
      if (!f) return f.status();
      key.forward = *f;
    }
    if (k.contains("up")) {
      auto u = vec3(k["up"], jsonKeyPath(kp, "up"));
      if (!u) return u.status();
      key.up = *u;
    }
    keys.push_back(key);
  }
  auto tr = Trajectory::fromKeyframes(std::move(keys), pathKey);
  if (!tr) return prefixed(tr.status());
  return tr;
}

Status SceneReader::readListener(const json& v, SceneListener& out) {
  EARSHOT_RETURN_IF_ERROR(expectObject(v, "listener", "an object {position, forward, up} or {path}"));
  EARSHOT_RETURN_IF_ERROR(checkKeys(v, "listener", kListenerKeys));
  bool keyed = false;
  auto t = pose(v, "listener", keyed);
  if (!t) return t.status();
  out.trajectory = std::move(*t);
  return Status::ok();
}

Status SceneReader::readSource(const json& v, const std::string& path, SceneSource& out) {
  EARSHOT_RETURN_IF_ERROR(expectObject(v, path, "a source object {name, audio, position, ...}"));
  EARSHOT_RETURN_IF_ERROR(checkKeys(v, path, kSourceKeys));
  if (!v.contains("name")) return fail(jsonKeyPath(path, "name"), "missing (expected the source's name)");
  auto name = text(v["name"], jsonKeyPath(path, "name"), "a name (string)");
  if (!name) return name.status();
  out.name = *name;
  if (!v.contains("audio")) return fail(jsonKeyPath(path, "audio"), "missing (expected a path to the dry audio file)");
  auto audio = filePath(v["audio"], jsonKeyPath(path, "audio"), "the dry audio file");
  if (!audio) return audio.status();
  out.audioPath = *audio;
  bool keyed = false;
  auto t = pose(v, path, keyed);
  if (!t) return t.status();
  out.trajectory = std::move(*t);
  if (v.contains("gain_db")) {
    auto g = number(v["gain_db"], jsonKeyPath(path, "gain_db"), {-120.0, 60.0, false, " dB"});
    if (!g) return g.status();
    out.gainDb = *g;
  }
  if (v.contains("directivity")) {
    // A pattern's name, or alpha of (1 - alpha) + alpha cos(angle).
    const std::string dp = jsonKeyPath(path, "directivity");
    static const std::vector<std::pair<std::string, double>> kPatterns = {
        {"omni", 0.0}, {"subcardioid", 0.25}, {"cardioid", 0.5}, {"supercardioid", 0.63},
        {"hypercardioid", 0.75}, {"figure8", 1.0}};
    const char* expected = "omni, subcardioid, cardioid, supercardioid, hypercardioid, figure8 or a number in [0, 1]";
    if (v["directivity"].is_number()) {
      auto a = number(v["directivity"], dp, {0.0, 1.0, false, ""});
      if (!a) return a.status();
      out.directivityAlpha = *a;
    } else {
      auto d = text(v["directivity"], dp, expected);
      if (!d) return d.status();
      auto it = std::find_if(kPatterns.begin(), kPatterns.end(), [&](const auto& p) { return p.first == *d; });
      if (it == kPatterns.end()) return fail(dp, std::string("expected ") + expected + ", got " + jsonQuoted(*d));
      out.directivityAlpha = it->second;
    }
    out.directivity = out.directivityAlpha == 0.0 ? SourceDirectivity::kOmni : SourceDirectivity::kCardioid;
  }
  if (v.contains("directivity_bands")) {
    // One alpha per octave band, 125 Hz .. 8 kHz, instead of "directivity".
    const std::string bp = jsonKeyPath(path, "directivity_bands");
    const json& t = v["directivity_bands"];
    if (!t.is_array() || t.size() != 7) return fail(bp, "expected 7 numbers in [0, 1] (125 Hz .. 8 kHz)");
    for (size_t b = 0; b < 7; ++b) {
      auto a = number(t[b], bp + "[" + std::to_string(b) + "]", {0.0, 1.0, false, ""});
      if (!a) return a.status();
      out.directivityBands.push_back(*a);
    }
  }
  if (v.contains("directivity_sharpness")) {
    auto k = number(v["directivity_sharpness"], jsonKeyPath(path, "directivity_sharpness"), {1.0, 16.0, false, ""});
    if (!k) return k.status();
    out.directivitySharpness = *k;
  }
  for (auto [key, field] : {std::pair{"direct_gain_db", &out.directGainDb}, {"reflections_gain_db", &out.reflectionsGainDb}})
    if (v.contains(key)) {
      auto g = number(v[key], jsonKeyPath(path, key), {-120.0, 60.0, false, " dB"});
      if (!g) return g.status();
      *field = *g;
    }
  if (v.contains("distance_model")) {
    const std::string dp = jsonKeyPath(path, "distance_model");
    auto m = text(v["distance_model"], dp, "physical, inverse, linear, exponential or table");
    if (!m) return m.status();
    if (*m != "physical" && *m != "inverse" && *m != "linear" && *m != "exponential" && *m != "table")
      return fail(dp, "expected physical, inverse, linear, exponential or table, got " + jsonQuoted(*m));
    out.distanceModel = *m;
  }
  if (v.contains("distance_table")) {
    // [[distance_m, gain], ...]: 1 to 16 points, distances ascending.
    const std::string tp = jsonKeyPath(path, "distance_table");
    const json& t = v["distance_table"];
    if (!t.is_array() || t.empty() || t.size() > 16)
      return fail(tp, "expected 1 to 16 points [distance_m, gain]");
    for (size_t i = 0; i < t.size(); ++i) {
      const std::string ip = tp + "[" + std::to_string(i) + "]";
      if (!t[i].is_array() || t[i].size() != 2) return fail(ip, "expected [distance_m, gain]");
      auto d = number(t[i][0], ip + "[0]", {0.0, 1e6, false, " m"});
      if (!d) return d.status();
      auto g = number(t[i][1], ip + "[1]", {0.0, 10.0, false, ""});
      if (!g) return g.status();
      if (i > 0 && !(*d > out.distanceTable.back().first)) return fail(ip, "distances must ascend");
      out.distanceTable.emplace_back(*d, *g);
    }
  }
  if (out.distanceModel == "table" && out.distanceTable.empty())
    return fail(jsonKeyPath(path, "distance_table"), "missing (distance_model is \"table\")");
  for (auto [key, field, range] : {std::tuple{"min_distance", &out.minDistance, Range{0.0, 1e6, true, " m"}},
                                   {"max_distance", &out.maxDistance, Range{0.0, 1e6, true, " m"}},
                                   {"rolloff", &out.rolloff, Range{0.0, 100.0, false, ""}},
                                   {"radius", &out.radius, Range{0.0, 100.0, true, " m"}}})
    if (v.contains(key)) {
      auto x = number(v[key], jsonKeyPath(path, key), range);
      if (!x) return x.status();
      *field = *x;
    }
  if (out.maxDistance < out.minDistance)
    return fail(jsonKeyPath(path, "max_distance"), fmt(out.maxDistance) + " is below min_distance " + fmt(out.minDistance));
  if (v.contains("occlusion")) {
    const std::string op = jsonKeyPath(path, "occlusion");
    auto o = text(v["occlusion"], op, "ray, off or volumetric");
    if (!o) return o.status();
    if (*o != "ray" && *o != "off" && *o != "volumetric")
      return fail(op, "expected ray, off or volumetric, got " + jsonQuoted(*o));
    out.occlusion = *o;
  }
  if (v.contains("transmission")) {
    if (!v["transmission"].is_boolean())
      return fail(jsonKeyPath(path, "transmission"), "expected true or false");
    out.transmission = v["transmission"].get<bool>();
  }
  if (v.contains("priority")) {
    auto p = wholeNumber(v["priority"], jsonKeyPath(path, "priority"), 0, 1000);
    if (!p) return p.status();
    out.priority = int(*p);
  }
  if (v.contains("start")) {
    auto s = time(v["start"], jsonKeyPath(path, "start"));
    if (!s) return s.status();
    out.startSeconds = *s;
  }
  return Status::ok();
}

Status SceneReader::readAir(const json& v, SceneAir& out) {
  const std::string path = "settings.air";
  if (v.is_string()) {
    if (v.get<std::string>() != "off")
      return fail(path, "expected \"off\" or an object {temperature_c, humidity_pct}, got " + describe(v));
    out.enabled = false;
    return Status::ok();
  }
  EARSHOT_RETURN_IF_ERROR(expectObject(v, path, "\"off\" or an object {temperature_c, humidity_pct}"));
  EARSHOT_RETURN_IF_ERROR(checkKeys(v, path, kAirKeys));
  out.enabled = true;
  if (v.contains("temperature_c")) {
    auto r = number(v["temperature_c"], path + ".temperature_c", {-20.0, 50.0, false, " C"});
    if (!r) return r.status();
    out.temperatureC = *r;
  }
  if (v.contains("humidity_pct")) {
    auto r = number(v["humidity_pct"], path + ".humidity_pct", {0.0, 100.0, false, " %"});
    if (!r) return r.status();
    out.humidityPercent = *r;
  }
  if (v.contains("pressure_kpa")) {
    auto r = number(v["pressure_kpa"], path + ".pressure_kpa", {50.0, 120.0, false, " kPa"});
    if (!r) return r.status();
    out.pressureKpa = *r;
  }
  return Status::ok();
}

Status SceneReader::readSettings(const json& v, SceneSettings& out) {
  EARSHOT_RETURN_IF_ERROR(expectObject(v, "settings", "an object"));
  EARSHOT_RETURN_IF_ERROR(checkKeys(v, "settings", kSettingsKeys));
  if (v.contains("sample_rate")) {
    auto r = number(v["sample_rate"], "settings.sample_rate", {8000.0, 192000.0, false, " Hz"});
    if (!r) return r.status();
    if (*r != std::floor(*r)) return fail("settings.sample_rate", fmt(*r) + " Hz is not a whole number of Hz");
    out.sampleRateHz = *r;
  }
  if (v.contains("quality")) {
    auto q = text(v["quality"], "settings.quality", "a quality name (string)");
    if (!q) return q.status();
    const auto& names = sceneQualityNames();
    if (std::find(names.begin(), names.end(), *q) == names.end())
      return fail("settings.quality",
                  "unknown quality " + jsonQuoted(*q) + " (expected draft, balanced, high or reference)");
    out.quality = *q;
  }
  if (v.contains("rays")) {
    auto r = wholeNumber(v["rays"], "settings.rays", 1, 100000000);
    if (!r) return r.status();
    out.rays = uint32_t(*r);
  }
  if (v.contains("bounces")) {
    auto r = wholeNumber(v["bounces"], "settings.bounces", 0, 100000);
    if (!r) return r.status();
    out.bounces = uint32_t(*r);
  }
  if (v.contains("hrtf")) {
    auto h = filePath(v["hrtf"], "settings.hrtf", "the HRTF (SOFA) file");
    if (!h) return h.status();
    out.hrtfPath = *h;
  }
  if (v.contains("seed")) {
    auto r = wholeNumber(v["seed"], "settings.seed", 0, std::numeric_limits<uint64_t>::max());
    if (!r) return r.status();
    out.seed = *r;
  }
  if (v.contains("update_rate_hz")) {
    auto r = number(v["update_rate_hz"], "settings.update_rate_hz", {0.01, 1000.0, false, " Hz"});
    if (!r) return r.status();
    out.updateRateHz = *r;
  }
  if (v.contains("ambisonic_order")) {
    auto r = wholeNumber(v["ambisonic_order"], "settings.ambisonic_order", 0, 3);
    if (!r) return r.status();
    out.ambisonicOrder = int(*r);
  }
  if (v.contains("output")) {
    auto f = text(v["output"], "settings.output", "\"binaural\" or \"ambisonic\"");
    if (!f) return f.status();
    if (*f != "binaural" && *f != "ambisonic")
      return fail("settings.output", quotedName(*f) + " is not \"binaural\" or \"ambisonic\"");
    out.output = *f;
  }
  if (v.contains("trace")) {
    auto f = text(v["trace"], "settings.trace", "\"auto\", \"shared\" or \"per-source\"");
    if (!f) return f.status();
    if (*f != "auto" && *f != "shared" && *f != "per-source")
      return fail("settings.trace", quotedName(*f) + " is not \"auto\", \"shared\" or \"per-source\"");
    out.trace = *f;
  }
  if (out.output == "ambisonic" && out.ambisonicOrder == 0)
    return fail("settings.output", "ambisonic output needs settings.ambisonic_order 1-3, not 0");
  if (v.contains("duration")) {
    if (v["duration"].is_number() && v["duration"].get<double>() < 0)
      return fail("settings.duration", fmt(v["duration"].get<double>()) + " s is negative (expected seconds > 0)");
    auto r = number(v["duration"], "settings.duration", {0.0, kMaxSceneSeconds, true, " s"});
    if (!r) return r.status();
    out.durationSeconds = *r;
  }
  if (v.contains("air")) EARSHOT_RETURN_IF_ERROR(readAir(v["air"], out.air));
  if (v.contains("speed_of_sound")) {
    auto r = number(v["speed_of_sound"], "settings.speed_of_sound", {100.0, 2000.0, false, " m/s"});
    if (!r) return r.status();
    out.speedOfSound = *r;
  }
  return Status::ok();
}

// Entries of a map object; `keyPrefix` names them ("material_map" inline,
// or "material_map: FILE:" for a map file).
Status readMapEntries(const json& obj, const std::string& file, const std::string& keyPrefix,
                      std::map<std::string, std::string>& out) {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    if (!it.value().is_string() || it.value().get<std::string>().empty())
      return invalidArgument(file + ": " + jsonKeyPath(keyPrefix, it.key()) +
                             ": expected an acoustic material name (string), got " +
                             (it.value().is_string() ? std::string("an empty string") : describe(it.value())));
    out[it.key()] = it.value().get<std::string>();
  }
  return Status::ok();
}

Status SceneReader::readMaterialMap(const json& v, SceneDescription& out) {
  const std::string expected = "an object {\"glTF material\": \"acoustic material\"} or a path to such a JSON file";
  if (v.is_object()) {
    EARSHOT_RETURN_IF_ERROR(readMapEntries(v, mFile, "material_map", out.materialMap));
    return checkMaterialNames(out, "material_map", mFile);
  }
  if (!v.is_string()) return fail("material_map", "expected " + expected + ", got " + describe(v));
  auto p = filePath(v, "material_map", "the material map file");
  if (!p) return p.status();
  out.materialMapPath = *p;
  if (!mOptions.checkFiles) return Status::ok();
  auto content = readTextFile(*p, "material map file");
  if (!content) return prefixed(content.status(), "material_map");
  auto j = render_detail::parseJsonWithPaths(*content, *p);
  if (!j) return prefixed(j.status(), "material_map");
  if (!j->is_object()) return fail("material_map", *p + ": expected " + expected.substr(0, expected.find(" or ")) +
                                                       ", got " + describe(*j), StatusCode::kParseError);
  // Entries of a map file are named `scene.json: material_map: map.json: door: ...`.
  const std::string prefix = mFile + ": material_map: " + *p;
  EARSHOT_RETURN_IF_ERROR(readMapEntries(*j, prefix, "", out.materialMap));
  return checkMaterialNames(out, "", prefix);
}

// Every acoustic name in the map must be in the materials the scene uses.
Status SceneReader::checkMaterialNames(const SceneDescription& scene, const std::string& mapPath,
                                       const std::string& filePrefix) {
  if (scene.materialMap.empty()) return Status::ok();
  const MaterialTable* table = nullptr;
  Result<MaterialTable> loaded = MaterialTable();
  std::string tableName = "the default materials";
  if (scene.materialsPath.empty()) {
    table = &defaultMaterials();
  } else {
    if (!mOptions.checkFiles) return Status::ok();
    loaded = loadMaterials(scene.materialsPath);
    if (!loaded) return prefixed(loaded.status(), "materials");
    table = &*loaded;
    tableName = scene.materialsPath;
  }
  std::vector<std::string> names;
  for (const Material& m : table->all()) names.push_back(m.name);
  for (const auto& [gltfName, acoustic] : scene.materialMap) {
    if (table->find(acoustic)) continue;
    const std::string hint = closest(acoustic, names, 3);
    const std::string didYouMean = hint.empty() ? "" : "; did you mean " + jsonQuoted(hint) + "?";
    return Status(StatusCode::kNotFound, filePrefix + ": " + jsonKeyPath(mapPath, gltfName) +
                                             ": unknown acoustic material " + jsonQuoted(acoustic) + " (not in " +
                                             tableName + didYouMean + ")");
  }
  return Status::ok();
}

Result<SceneDescription> SceneReader::read(const json& root) {
  if (!root.is_object()) return fail("", "expected a JSON object at the top level, got " + describe(root));
  EARSHOT_RETURN_IF_ERROR(checkKeys(root, "", kSceneKeys));
  SceneDescription scene;
  scene.sceneFile = mFile;
  if (root.contains("$schema")) {
    auto s = text(root["$schema"], "$schema", "the schema's URI or path (string)");
    if (!s) return s.status();
  }
  if (root.contains("description") && !root["description"].is_string())
    return fail("description", "expected a string, got " + describe(root["description"]));
  if (root.contains("geometry")) {
    auto g = filePath(root["geometry"], "geometry", "the glTF geometry file");
    if (!g) return g.status();
    scene.geometryPath = *g;
  }
  if (root.contains("materials")) {
    auto m = filePath(root["materials"], "materials", "the materials file");
    if (!m) return m.status();
    scene.materialsPath = *m;
  }
  if (root.contains("material_map")) EARSHOT_RETURN_IF_ERROR(readMaterialMap(root["material_map"], scene));

  if (!root.contains("listener"))
    return fail("listener", "missing (expected {\"position\": [x, y, z], \"forward\": ..., \"up\": ...})");
  EARSHOT_RETURN_IF_ERROR(readListener(root["listener"], scene.listener));

  if (!root.contains("sources")) return fail("sources", "missing (expected an array of sources)");
  const json& sources = root["sources"];
  if (!sources.is_array()) return fail("sources", "expected an array of sources, got " + describe(sources));
  if (sources.empty()) return fail("sources", "expected at least one source, got an empty array");
  std::map<std::string, size_t> names;
  for (size_t i = 0; i < sources.size(); ++i) {
    const std::string sp = jsonIndexPath("sources", i);
    SceneSource s;
    EARSHOT_RETURN_IF_ERROR(readSource(sources[i], sp, s));
    auto [it, fresh] = names.emplace(s.name, i);
    if (!fresh)
      return fail(jsonKeyPath(sp, "name"), jsonQuoted(s.name) + " is already the name of sources[" +
                                               std::to_string(it->second) + "] (names must be unique)");
    scene.sources.push_back(std::move(s));
  }

  if (root.contains("settings")) EARSHOT_RETURN_IF_ERROR(readSettings(root["settings"], scene.settings));
  return scene;
}

}  // namespace

const char* directivityName(SourceDirectivity d) {
  return d == SourceDirectivity::kCardioid ? "cardioid" : "omni";
}

const std::vector<SceneObjectKeys>& sceneFileKeys() {
  static const std::vector<SceneObjectKeys> keys = {
      {"scene", kSceneKeys},       {"listener", kListenerKeys}, {"source", kSourceKeys},
      {"keyframe", kKeyframeKeys}, {"settings", kSettingsKeys}, {"air", kAirKeys},
  };
  return keys;
}

const std::vector<std::string>& sceneQualityNames() {
  static const std::vector<std::string> names = {"draft", "balanced", "high", "reference"};
  return names;
}

Result<SceneDescription> parseSceneText(const std::string& text, const std::string& baseDirectory,
                                        const std::string& displayName, const SceneParseOptions& options,
                                        std::vector<std::string>* warnings) {
  auto root = render_detail::parseJsonWithPaths(text, displayName);
  if (!root) return root.status();
  SceneReader reader(displayName, baseDirectory, options, warnings);
  return reader.read(*root);
}

Result<SceneDescription> loadSceneFile(const std::string& path, const SceneParseOptions& options,
                                       std::vector<std::string>* warnings) {
  auto content = readTextFile(path, "scene file");
  if (!content) return content.status();
  return parseSceneText(*content, fs::path(path).parent_path().string(), path, options, warnings);
}

}  // namespace earshot
