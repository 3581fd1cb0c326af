// libFuzzer target: parseSceneText (the `earshot render` scene file) on
// arbitrary text with checkFiles = false, so no file is opened: the SAX JSON
// reader with paths, key checks, numbers and ranges, poses and keyframed
// trajectories. Each input is parsed twice, lenient (unknown keys warn) and
// strict (unknown keys fail), and the two must agree.
#include <cmath>
#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "earshot/render/scene_file.h"
#include "fuzz_temp_file.h"

namespace {

using namespace earshot;

constexpr char kName[] = "fuzz.json";

// Messages are one line that starts with the file's display name.
bool wellFormedMessage(const std::string& m) {
  return m.rfind(kName, 0) == 0 && m.size() > sizeof kName && m.find('\n') == std::string::npos &&
         m.find('\r') == std::string::npos;
}

bool unit(const Vec3d& v) { return isFinite(v) && std::abs(length(v) - 1.0) < 1e-9; }

void checkPose(const Pose& p) {
  EARSHOT_FUZZ_CHECK(isFinite(p.position) && isFinite(p.velocity));
  EARSHOT_FUZZ_CHECK(unit(p.forward) && unit(p.up));
  EARSHOT_FUZZ_CHECK(std::abs(dot(p.forward, p.up)) < 1e-9);
}

// Keyframes as documented, and poses between and beyond them well defined.
void checkTrajectory(const Trajectory& tr) {
  const std::vector<Keyframe>& keys = tr.keyframes();
  EARSHOT_FUZZ_CHECK(!keys.empty());
  for (size_t i = 0; i < keys.size(); ++i) {
    const Keyframe& k = keys[i];
    EARSHOT_FUZZ_CHECK(std::isfinite(k.t) && k.t >= 0.0 && k.t <= kMaxSceneSeconds);
    if (i > 0) EARSHOT_FUZZ_CHECK(k.t > keys[i - 1].t);
    EARSHOT_FUZZ_CHECK(isFinite(k.position));
    for (int a = 0; a < 3; ++a) EARSHOT_FUZZ_CHECK(std::abs(k.position[a]) <= kMaxCoordinateMeters);
    EARSHOT_FUZZ_CHECK(unit(k.forward) && unit(k.up) && std::abs(dot(k.forward, k.up)) < 1e-9);
    checkPose(tr.at(k.t));
    if (i > 0) checkPose(tr.at(0.5 * (keys[i - 1].t + k.t)));
  }
  checkPose(tr.at(-1.0));
  checkPose(tr.at(tr.endSeconds() + 1.0));
  EARSHOT_FUZZ_CHECK(tr.isStatic() == (keys.size() == 1));
}

// An accepted scene holds what scene_file.h promises for each field.
void checkScene(const SceneDescription& s) {
  EARSHOT_FUZZ_CHECK(s.sceneFile == kName);
  checkTrajectory(s.listener.trajectory);
  EARSHOT_FUZZ_CHECK(!s.sources.empty());
  std::set<std::string> names;
  for (const SceneSource& src : s.sources) {
    EARSHOT_FUZZ_CHECK(!src.name.empty() && names.insert(src.name).second);
    EARSHOT_FUZZ_CHECK(!src.audioPath.empty());
    EARSHOT_FUZZ_CHECK(std::isfinite(src.gainDb) && src.gainDb >= -120.0 && src.gainDb <= 60.0);
    EARSHOT_FUZZ_CHECK(std::isfinite(src.startSeconds) && src.startSeconds >= 0.0 &&
                       src.startSeconds <= kMaxSceneSeconds);
    checkTrajectory(src.trajectory);
  }
  for (const auto& [gltfName, acoustic] : s.materialMap) EARSHOT_FUZZ_CHECK(!acoustic.empty());
  const SceneSettings& st = s.settings;
  EARSHOT_FUZZ_CHECK(st.sampleRateHz >= 8000.0 && st.sampleRateHz <= 192000.0 &&
                     st.sampleRateHz == std::floor(st.sampleRateHz));
  bool knownQuality = false;
  for (const std::string& q : sceneQualityNames()) knownQuality |= q == st.quality;
  EARSHOT_FUZZ_CHECK(knownQuality);
  if (st.rays) EARSHOT_FUZZ_CHECK(*st.rays >= 1 && *st.rays <= 100000000u);
  if (st.bounces) EARSHOT_FUZZ_CHECK(*st.bounces <= 100000u);
  EARSHOT_FUZZ_CHECK(st.updateRateHz > 0.0 && st.updateRateHz <= 1000.0);
  if (st.durationSeconds)
    EARSHOT_FUZZ_CHECK(std::isfinite(*st.durationSeconds) && *st.durationSeconds > 0.0 &&
                       *st.durationSeconds <= kMaxSceneSeconds);
  EARSHOT_FUZZ_CHECK(st.air.temperatureC >= -20.0 && st.air.temperatureC <= 50.0);
  EARSHOT_FUZZ_CHECK(st.air.humidityPercent >= 0.0 && st.air.humidityPercent <= 100.0);
  EARSHOT_FUZZ_CHECK(st.air.pressureKpa >= 50.0 && st.air.pressureKpa <= 120.0);
  EARSHOT_FUZZ_CHECK(st.speedOfSound >= 100.0 && st.speedOfSound <= 2000.0);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  SceneParseOptions lenient;
  lenient.checkFiles = false;
  SceneParseOptions strict = lenient;
  strict.strict = true;

  std::vector<std::string> warnings;
  auto a = parseSceneText(text, "/scenes", kName, lenient, &warnings);
  auto b = parseSceneText(text, "/scenes", kName, strict);
  for (const std::string& w : warnings) {
    EARSHOT_FUZZ_CHECK(wellFormedMessage(w));
    EARSHOT_FUZZ_CHECK(w.find("unknown key") != std::string::npos);
  }
  if (!a.isOk()) EARSHOT_FUZZ_CHECK(wellFormedMessage(a.status().message()));
  if (!b.isOk()) EARSHOT_FUZZ_CHECK(wellFormedMessage(b.status().message()));

  // Strict differs from lenient only in failing on the keys lenient warns about.
  if (b.isOk()) EARSHOT_FUZZ_CHECK(a.isOk() && warnings.empty());
  if (a.isOk() && warnings.empty()) EARSHOT_FUZZ_CHECK(b.isOk());
  if (a.isOk() && !warnings.empty()) {
    EARSHOT_FUZZ_CHECK(!b.isOk());
    EARSHOT_FUZZ_CHECK(b.status().message().find("unknown key") != std::string::npos);
  }
  if (a.isOk()) checkScene(*a);
  if (a.isOk() && b.isOk()) {
    EARSHOT_FUZZ_CHECK(a->sources.size() == b->sources.size());
    EARSHOT_FUZZ_CHECK(a->listener.trajectory.keyframes().size() == b->listener.trajectory.keyframes().size());
    EARSHOT_FUZZ_CHECK(a->settings.seed == b->settings.seed && a->geometryPath == b->geometryPath);
  }
  return 0;
}
