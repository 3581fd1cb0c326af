// Scene files: every bad input is one line naming the file, the JSON path and
// what was expected; the sample scenes load without warnings; the JSON Schema
// and the format doc list the keys the parser accepts.

// GCC 12 (the asan preset's -O2 with the sanitizers) warns
// -Wmaybe-uninitialized inside libstdc++'s std::regex (std::function's move
// of an automaton state): a false positive in library code this file only
// uses, so off for the file, before the includes that define it.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include "earshot/render/scene_file.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>

#include "../cli/cli_test_util.h"
#include "earshot/core/math.h"
#include "earshot/io/wav.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/propagation/air_absorption.h"
#include "earshot/render/dry_audio.h"
#include "earshot/scene/gltf_loader.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using testing::readFile;
using testing::TempDir;

const fs::path kSource = EARSHOT_SOURCE_DIR;

// A scene directory with a dry audio file; parses text as "scene.json" in it.
class SceneFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    AudioBuffer a(1, 480, 48000.0);
    ASSERT_TRUE(writeWavFloat(mDir / "dry.wav", a).isOk());
  }

  Result<SceneDescription> parse(const std::string& text, bool strict = false) {
    SceneParseOptions o;
    o.strict = strict;
    mWarnings.clear();
    return parseSceneText(text, mDir.path.string(), "scene.json", o, &mWarnings);
  }

  // The error of a scene that must fail: one line, starting with the file.
  std::string error(const std::string& text, bool strict = false) {
    auto r = parse(text, strict);
    EXPECT_FALSE(r.isOk()) << text;
    if (r.isOk()) return "";
    const std::string& m = r.status().message();
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    EXPECT_EQ(m.rfind("scene.json", 0), 0u) << m;
    return m;
  }

  // A valid scene with `sourceExtra` merged into its source and `extra` into the top level.
  static std::string scene(const std::string& sourceExtra = "", const std::string& extra = "") {
    return R"({"listener": {"position": [0, 0, 1.5]},
               "sources": [{"name": "a", "audio": "dry.wav", "position": [2, 0, 1.5])" +
           (sourceExtra.empty() ? "" : ", " + sourceExtra) + "}]" + (extra.empty() ? "" : ", " + extra) + "}";
  }

  TempDir mDir{"render_scene"};
  std::vector<std::string> mWarnings;
};

#define EXPECT_HAS(haystack, needle) EXPECT_NE((haystack).find(needle), std::string::npos) << (haystack)

TEST_F(SceneFileTest, MinimalSceneGetsTheDocumentedDefaults) {
  auto r = parse(scene());
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_TRUE(mWarnings.empty());
  const SceneDescription& s = *r;
  EXPECT_EQ(s.sceneFile, "scene.json");
  EXPECT_TRUE(s.geometryPath.empty());
  EXPECT_TRUE(s.materialsPath.empty());
  EXPECT_TRUE(s.materialMap.empty());
  ASSERT_EQ(s.sources.size(), 1u);
  EXPECT_EQ(s.sources[0].audioPath, (mDir.path / "dry.wav").string());
  EXPECT_EQ(s.sources[0].gainDb, 0.0);
  EXPECT_EQ(s.sources[0].startSeconds, 0.0);
  EXPECT_EQ(s.sources[0].directivity, SourceDirectivity::kOmni);
  Pose l = s.listener.trajectory.at(3.0);
  EXPECT_EQ(l.position, Vec3d(0, 0, 1.5));
  EXPECT_EQ(l.forward, kDefaultForward);
  EXPECT_EQ(l.up, kDefaultUp);
  EXPECT_EQ(s.settings.sampleRateHz, 48000.0);
  EXPECT_EQ(s.settings.quality, "balanced");
  EXPECT_FALSE(s.settings.rays.has_value());
  EXPECT_FALSE(s.settings.durationSeconds.has_value());
  EXPECT_TRUE(s.settings.hrtfPath.empty());
  EXPECT_EQ(s.settings.seed, 1u);
  EXPECT_TRUE(s.settings.air.enabled);
  EXPECT_EQ(s.settings.air.temperatureC, 20.0);
  EXPECT_EQ(s.settings.speedOfSound, 343.0);
  EXPECT_EQ(s.settings.trace, "auto");
}

TEST_F(SceneFileTest, EveryFieldIsRead) {
  fs::create_directories(mDir.path / "sub");
  AudioBuffer a(2, 10, 44100.0);
  ASSERT_TRUE(writeWavFloat(mDir / "sub/b.wav", a).isOk());
  std::ofstream(mDir / "map.json") << R"({"Brick wall": "brick", "floor": "carpet_thick"})";
  std::ofstream(mDir / "room.gltf") << "{}";
  std::ofstream(mDir / "set.sofa") << "x";
  auto r = parse(R"({
    "$schema": "../scene.schema.json", "description": "all of it",
    "geometry": "room.gltf", "material_map": "map.json",
    "listener": {"up": [0, 0, 1], "path": [
        {"t": 0, "position": [1, 1, 1.7], "forward": [1, 0, 0]},
        {"t": 4, "position": [3, 1, 1.7], "forward": [0, 1, 0]}]},
    "sources": [
      {"name": "a", "audio": "dry.wav", "position": [2, 0, 1.5], "forward": [0, 1, 0], "up": [0, 0, 1],
       "gain_db": -6.5, "directivity": "cardioid", "start": 1.25},
      {"name": "b", "audio": "sub/../sub/b.wav", "path": [{"t": 0.5, "position": [0, 0, 0]}]}],
    "settings": {"sample_rate": 44100, "quality": "high", "rays": 1000, "bounces": 0, "hrtf": "set.sofa",
                 "seed": 18446744073709551615, "update_rate_hz": 12.5, "duration": 9.5,
                 "air": {"temperature_c": -20, "humidity_pct": 100, "pressure_kpa": 90}, "speed_of_sound": 340,
                 "trace": "per-source"}
  })", /*strict=*/true);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const SceneDescription& s = *r;
  EXPECT_EQ(s.geometryPath, (mDir.path / "room.gltf").string());
  EXPECT_EQ(s.materialMapPath, (mDir.path / "map.json").string());
  EXPECT_EQ(s.materialMap, (std::map<std::string, std::string>{{"Brick wall", "brick"}, {"floor", "carpet_thick"}}));
  EXPECT_FALSE(s.listener.trajectory.isStatic());
  Pose l = s.listener.trajectory.at(2.0);
  EXPECT_NEAR(l.position.x, 2.0, 1e-12);
  EXPECT_NEAR(l.forward.x, std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(l.up.z, 1.0, 1e-12);
  ASSERT_EQ(s.sources.size(), 2u);
  EXPECT_EQ(s.sources[0].gainDb, -6.5);
  EXPECT_EQ(s.sources[0].directivity, SourceDirectivity::kCardioid);
  EXPECT_EQ(s.sources[0].startSeconds, 1.25);
  EXPECT_EQ(s.sources[0].trajectory.at(0).forward, Vec3d(0, 1, 0));
  EXPECT_EQ(s.sources[1].audioPath, (mDir.path / "sub" / "b.wav").string());
  EXPECT_EQ(s.sources[1].trajectory.keyframes()[0].t, 0.5);
  EXPECT_EQ(s.settings.sampleRateHz, 44100.0);
  EXPECT_EQ(s.settings.quality, "high");
  EXPECT_EQ(s.settings.rays, 1000u);
  EXPECT_EQ(s.settings.bounces, 0u);
  EXPECT_EQ(s.settings.hrtfPath, (mDir.path / "set.sofa").string());
  EXPECT_EQ(s.settings.seed, 18446744073709551615u);
  EXPECT_EQ(s.settings.updateRateHz, 12.5);
  EXPECT_EQ(s.settings.durationSeconds, 9.5);
  EXPECT_EQ(s.settings.air.temperatureC, -20.0);
  EXPECT_EQ(s.settings.air.humidityPercent, 100.0);
  EXPECT_EQ(s.settings.air.pressureKpa, 90.0);
  EXPECT_EQ(s.settings.trace, "per-source");
  EXPECT_EQ(s.settings.speedOfSound, 340.0);
  EXPECT_EQ(directivityGain(SourceDirectivity::kCardioid, -1.0), 0.0);
  EXPECT_EQ(directivityGain(SourceDirectivity::kCardioid, 0.0), 0.5);
  EXPECT_EQ(directivityGain(SourceDirectivity::kOmni, -1.0), 1.0);

  auto off = parse(scene("", R"("settings": {"air": "off"})"));
  ASSERT_TRUE(off.isOk()) << off.status().message();
  EXPECT_FALSE(off->settings.air.enabled);
}

TEST_F(SceneFileTest, MissingFieldsAreNamed) {
  EXPECT_HAS(error(R"({"sources": []})"), "scene.json: listener: missing");
  EXPECT_HAS(error(R"({"listener": {"position": [0, 0, 0]}})"), "scene.json: sources: missing");
  EXPECT_HAS(error(R"({"listener": {"position": [0, 0, 0]}, "sources": []})"),
             "scene.json: sources: expected at least one source");
  EXPECT_HAS(error(R"({"listener": {}, "sources": [{"name": "a", "audio": "dry.wav", "position": [0, 0, 0]}]})"),
             "scene.json: listener.position: missing");
  EXPECT_HAS(error(R"({"listener": {"position": [0, 0, 0]}, "sources": [{"name": "a", "position": [0, 0, 0]}]})"),
             "scene.json: sources[0].audio: missing (expected a path to the dry audio file)");
  EXPECT_HAS(error(R"({"listener": {"position": [0, 0, 0]},
                       "sources": [{"audio": "dry.wav", "position": [0, 0, 0]}]})"),
             "scene.json: sources[0].name: missing");
  EXPECT_HAS(error(R"({"listener": {"position": [0, 0, 0]}, "sources": [{"name": "a", "audio": "dry.wav"}]})"),
             "scene.json: sources[0].position: missing");
  EXPECT_HAS(error(R"({"listener": {"path": [{"position": [0, 0, 0]}]},
                       "sources": [{"name": "a", "audio": "dry.wav", "position": [0, 0, 0]}]})"),
             "scene.json: listener.path[0].t: missing");
}

TEST_F(SceneFileTest, WrongTypesSayWhatWasExpected) {
  EXPECT_HAS(error(scene("", R"("settings": {"sample_rate": "48k"})")),
             "scene.json: settings.sample_rate: expected a number, got string \"48k\"");
  EXPECT_HAS(error(R"({"listener": {"position": 3}, "sources": []})"),
             "scene.json: listener.position: expected [x, y, z] (3 numbers), got number 3");
  EXPECT_HAS(error(R"({"listener": {"position": [1, 2]}, "sources": []})"),
             "scene.json: listener.position: expected [x, y, z] (3 numbers), got an array of 2");
  EXPECT_HAS(error(R"({"listener": {"position": [1, true, 3]}, "sources": []})"),
             "scene.json: listener.position[1]: expected a number, got boolean true");
  EXPECT_HAS(error(scene(R"("gain_db": null)")), "scene.json: sources[0].gain_db: expected a number, got null");
  EXPECT_HAS(error(scene(R"("directivity": "shotgun")")),
             "scene.json: sources[0].directivity: expected omni, subcardioid, cardioid, supercardioid, "
             "hypercardioid, figure8 or a number in [0, 1], got \"shotgun\"");
  EXPECT_HAS(error(scene(R"("directivity": 1.5)")), "scene.json: sources[0].directivity:");
  EXPECT_HAS(error(scene(R"("distance_model": "cubic")")),
             "scene.json: sources[0].distance_model: expected physical, inverse, linear, exponential or table");
  EXPECT_HAS(error(scene(R"("occlusion": "maybe")")), "scene.json: sources[0].occlusion: expected ray, off or volumetric");
  EXPECT_HAS(error(scene(R"("transmission": 1)")), "scene.json: sources[0].transmission: expected true or false");
  EXPECT_HAS(error(scene(R"("priority": -1)")), "scene.json: sources[0].priority:");
  EXPECT_HAS(error(scene(R"("min_distance": 5, "max_distance": 2)")), "scene.json: sources[0].max_distance:");
  EXPECT_HAS(error(scene(R"("radius": 0)")), "scene.json: sources[0].radius:");
  EXPECT_HAS(error(scene("", R"("settings": [])")), "scene.json: settings: expected an object, got array");
  EXPECT_HAS(error(scene("", R"("settings": {"rays": 1.5})")),
             "scene.json: settings.rays: expected a whole number, got number 1.5");
  EXPECT_HAS(error(scene("", R"("settings": {"air": "on"})")),
             "scene.json: settings.air: expected \"off\" or an object {temperature_c, humidity_pct}, "
             "got string \"on\"");
  EXPECT_HAS(error(scene("", R"("material_map": 7)")), "scene.json: material_map: expected an object");
  EXPECT_HAS(error(scene("", R"("material_map": {"wall": 3})")),
             "scene.json: material_map.wall: expected an acoustic material name (string), got number 3");
  EXPECT_HAS(error("[1, 2]"), "scene.json: expected a JSON object at the top level, got array");
  EXPECT_HAS(error(R"({"listener": {"position": [0, 0, 0]}, "sources": {"name": "a"}})"),
             "scene.json: sources: expected an array of sources, got object");
}

TEST_F(SceneFileTest, UnknownKeysWarnByDefaultAndFailWhenStrict) {
  const std::string text = scene(R"("gian_db": 3)", R"("setings": {})");
  auto r = parse(text);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  ASSERT_EQ(mWarnings.size(), 2u);
  EXPECT_EQ(mWarnings[0], "scene.json: setings: unknown key (did you mean \"settings\"?)");
  EXPECT_EQ(mWarnings[1], "scene.json: sources[0].gian_db: unknown key (did you mean \"gain_db\"?)");
  EXPECT_HAS(error(text, /*strict=*/true), "scene.json: setings: unknown key");
  EXPECT_EQ(error(scene(R"("colour": "red")"), true), "scene.json: sources[0].colour: unknown key");
  EXPECT_HAS(error(scene("", R"("settings": {"air": {"temp_c": 3}})"), true),
             "scene.json: settings.air.temp_c: unknown key");
  EXPECT_HAS(error(R"({"listener": {"path": [{"t": 0, "position": [0, 0, 0], "roll": 1}]},
                       "sources": [{"name": "a", "audio": "dry.wav", "position": [0, 0, 0]}]})", true),
             "scene.json: listener.path[0].roll: unknown key");
}

TEST_F(SceneFileTest, UnknownMaterialsAreNamedWithTheirKey) {
  EXPECT_EQ(error(scene("", R"("material_map": {"Wall": "brik"})")),
            "scene.json: material_map.Wall: unknown acoustic material \"brik\" (not in the default materials; "
            "did you mean \"brick\"?)");
  EXPECT_HAS(error(scene("", R"("material_map": {"Back wall": "nothing_like_it"})")),
             "scene.json: material_map[\"Back wall\"]: unknown acoustic material \"nothing_like_it\"");
  std::ofstream(mDir / "map.json") << R"({"floor": "wood_floor", "door": "dor_wood"})";
  const std::string m = error(scene("", R"("material_map": "map.json")"));
  EXPECT_HAS(m, "scene.json: material_map: " + (mDir.path / "map.json").string() +
                    ": door: unknown acoustic material \"dor_wood\"");
  // Names are checked against the scene's own materials file when it has one.
  std::ofstream(mDir / "mats.json") << R"({"bands_hz": [1000], "materials": {"felt": {"absorption": [0.5]}}})";
  EXPECT_TRUE(parse(scene("", R"("materials": "mats.json", "material_map": {"Wall": "felt"})")).isOk());
  EXPECT_HAS(error(scene("", R"("materials": "mats.json", "material_map": {"Wall": "brick"})")),
             "scene.json: material_map.Wall: unknown acoustic material \"brick\" (not in " +
                 (mDir.path / "mats.json").string() + ")");
  std::ofstream(mDir / "broken_map.json") << "{\"a\": ";
  EXPECT_HAS(error(scene("", R"("material_map": "broken_map.json")")), "scene.json: material_map: ");
}

TEST_F(SceneFileTest, MissingFilesAreNamed) {
  auto r = parse(scene().replace(scene().find("dry.wav"), 7, "nope.wav"));
  ASSERT_FALSE(r.isOk());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(r.status().message(), "scene.json: sources[0].audio: the dry audio file \"" +
                                      (mDir.path / "nope.wav").string() + "\" not found");
  EXPECT_HAS(error(scene("", R"("geometry": "room.glb")")), "scene.json: geometry: the glTF geometry file \"");
  EXPECT_HAS(error(scene("", R"("materials": "m.json")")), "scene.json: materials: the materials file \"");
  EXPECT_HAS(error(scene("", R"("material_map": "none.json")")), "scene.json: material_map: the material map file");
  EXPECT_HAS(error(scene("", R"("settings": {"hrtf": "x.sofa"})")), "scene.json: settings.hrtf: the HRTF (SOFA) file");
  EXPECT_HAS(error(scene("", R"("geometry": ".")")), "scene.json: geometry: \"" + mDir.path.string());

  // Without file checks nothing is opened: paths are only resolved.
  SceneParseOptions o;
  o.checkFiles = false;
  auto unchecked = parseSceneText(scene("", R"("geometry": "g.glb", "material_map": "m.json")")
                                      .replace(scene().find("dry.wav"), 7, "nope.wav"),
                                  "/nowhere", "scene.json", o);
  ASSERT_TRUE(unchecked.isOk()) << unchecked.status().message();
  EXPECT_EQ(unchecked->sources[0].audioPath, "/nowhere/nope.wav");
  EXPECT_EQ(unchecked->geometryPath, "/nowhere/g.glb");
  EXPECT_EQ(unchecked->materialMapPath, "/nowhere/m.json");

  auto file = loadSceneFile(mDir / "absent.json");
  ASSERT_FALSE(file.isOk());
  EXPECT_EQ(file.status().code(), StatusCode::kNotFound);
  EXPECT_HAS(file.status().message(), mDir / "absent.json");
}

TEST_F(SceneFileTest, NegativeAndDisorderedTimesAreRejected) {
  EXPECT_EQ(error(scene(R"("start": -1)")),
            "scene.json: sources[0].start: -1 s is negative (times are seconds from the start of the scene, >= 0)");
  EXPECT_HAS(error(scene("", R"("settings": {"duration": -2})")), "scene.json: settings.duration: -2 s is negative");
  EXPECT_HAS(error(scene("", R"("settings": {"duration": 0})")),
             "scene.json: settings.duration: 0 s is outside (0, 86400] s");
  const std::string path = R"({"listener": {"path": [{"t": %1, "position": [0, 0, 0]},
                                                     {"t": %2, "position": [1, 0, 0]}]},
                               "sources": [{"name": "a", "audio": "dry.wav", "position": [0, 0, 0]}]})";
  auto keyed = [&](const std::string& t1, const std::string& t2) {
    return std::regex_replace(std::regex_replace(path, std::regex("%1"), t1), std::regex("%2"), t2);
  };
  EXPECT_HAS(error(keyed("-0.5", "1")), "scene.json: listener.path[0].t: -0.5 is negative");
  EXPECT_HAS(error(keyed("2", "1")),
             "scene.json: listener.path[1].t: 1 is not after listener.path[0].t = 2 (keyframe times must increase "
             "strictly)");
  EXPECT_HAS(error(keyed("1", "1")), "scene.json: listener.path[1].t: 1 is not after");
  // Keyframes closer than 1 us are refused (a jump within 9e-315 s had an
  // infinite velocity); 1 us apart is a jump.
  EXPECT_HAS(error(keyed("0", "1e-9")), "scene.json: listener.path[1].t: 1e-09 is less than 1 us after");
  EXPECT_TRUE(parse(keyed("0", "1e-6")).isOk());
}

TEST_F(SceneFileTest, HugeAndOverflowingNumbersAreRejected) {
  // 1e999 overflows a double: JSON has no infinity, but the parser would make one.
  const std::string text = "{\n  \"listener\": {\"position\": [0, 0, 0]},\n  \"settings\": {\"duration\": 1e999}\n}";
  const std::string m = error(text);
  EXPECT_HAS(m, "scene.json:3:28: settings.duration: the number 1e999 is too large");
  EXPECT_HAS(error(R"({"listener": {"position": [-1e999, 0, 0]}})"), "listener.position[0]: the number -1e999");
  EXPECT_HAS(error(R"({"listener": {"position": [1e300, 0, 0]}, "sources": []})"),
             "scene.json: listener.position[0]: 1e+300 is outside [-1000000, 1000000]");
  EXPECT_HAS(error(scene(R"("gain_db": 1e308)")), "scene.json: sources[0].gain_db: 1e+308 dB is outside [-120, 60] dB");
  EXPECT_HAS(error(scene("", R"("settings": {"rays": 1e20})")),
             "scene.json: settings.rays: 1e+20 is outside [1, 100000000]");
  EXPECT_HAS(error(scene("", R"("settings": {"seed": -1})")), "scene.json: settings.seed: -1 is outside [0, ");
  EXPECT_HAS(error(scene("", R"("settings": {"sample_rate": 4000})")),
             "scene.json: settings.sample_rate: 4000 Hz is outside [8000, 192000] Hz");
  EXPECT_HAS(error(scene("", R"("settings": {"sample_rate": 48000.5})")),
             "scene.json: settings.sample_rate: 48000.5 Hz is not a whole number of Hz");
  EXPECT_HAS(error(scene("", R"("settings": {"update_rate_hz": 0})")),
             "scene.json: settings.update_rate_hz: 0 Hz is outside [0.01, 1000] Hz");
  EXPECT_HAS(error(scene("", R"("settings": {"air": {"humidity_pct": 101}})")),
             "scene.json: settings.air.humidity_pct: 101 % is outside [0, 100] %");
  EXPECT_HAS(error(scene(R"("start": 1e6)")), "scene.json: sources[0].start: 1000000 s is outside [0, 86400] s");
  // Issue 15's keys.
  EXPECT_HAS(error(scene("", R"("settings": {"ambisonic_order": 4})")),
             "scene.json: settings.ambisonic_order: 4 is outside [0, 3]");
  EXPECT_HAS(error(scene("", R"("settings": {"ambisonic_order": 1.5})")), "settings.ambisonic_order");
  EXPECT_HAS(error(scene("", R"("settings": {"output": "surround"})")),
             "scene.json: settings.output: \"surround\" is not \"binaural\" or \"ambisonic\"");
  EXPECT_HAS(error(scene("", R"("settings": {"output": "ambisonic", "ambisonic_order": 0})")),
             "settings.output: ambisonic output needs settings.ambisonic_order 1-3");
  // Issue 16's.
  EXPECT_HAS(error(scene("", R"("settings": {"trace": "listener"})")),
             "scene.json: settings.trace: \"listener\" is not \"auto\", \"shared\" or \"per-source\"");
  EXPECT_HAS(error(scene("", R"("settings": {"trace": 2})")), "settings.trace");
}

TEST_F(SceneFileTest, BadOrientationsAreRejected) {
  EXPECT_HAS(error(R"({"listener": {"position": [0, 0, 0], "forward": [0, 0, 0]}, "sources": []})"),
             "scene.json: listener.forward: zero length");
  EXPECT_HAS(error(R"({"listener": {"position": [0, 0, 0], "up": [0, 0, 0]}, "sources": []})"),
             "scene.json: listener.up: zero length");
  EXPECT_HAS(error(R"({"listener": {"position": [0, 0, 0], "forward": [0, 0, 1], "up": [0, 0, -3]}, "sources": []})"),
             "scene.json: listener.up: [0, 0, -3] is parallel to forward [0, 0, 1]");
  // A z-up scene that gives up but keeps the default forward (-z): parallel.
  EXPECT_HAS(error(scene(R"("up": [0, 0, 1])")),
             "scene.json: sources[0].up: [0, 0, 1] is parallel to forward [0, 0, -1]");
  EXPECT_HAS(error(R"({"listener": {"up": [0, 0, 1], "path": [{"t": 0, "position": [0, 0, 0], "forward": [1, 0, 0]},
                                                                {"t": 1, "position": [0, 0, 0], "forward": [0, 0, 2]}]},
                       "sources": []})"),
             "scene.json: listener.path[1].up: [0, 0, 1] is parallel to forward [0, 0, 2]");
}

TEST_F(SceneFileTest, OtherStructuralErrors) {
  EXPECT_HAS(error(R"({"listener": {"position": [0, 0, 0], "path": [{"t": 0, "position": [0, 0, 0]}]}})"),
             "scene.json: listener: give either \"position\" (static) or \"path\" (keyframes), not both");
  EXPECT_HAS(error(R"({"listener": {"path": []}})"), "scene.json: listener.path: expected at least one keyframe");
  EXPECT_HAS(error(scene("", R"("settings": {"quality": "ultra"})")),
             "scene.json: settings.quality: unknown quality \"ultra\" (expected draft, balanced, high or reference)");
  const std::string two = R"({"listener": {"position": [0, 0, 0]}, "sources": [
      {"name": "a", "audio": "dry.wav", "position": [0, 0, 0]},
      {"name": "a", "audio": "dry.wav", "position": [1, 0, 0]}]})";
  EXPECT_EQ(error(two), "scene.json: sources[1].name: \"a\" is already the name of sources[0] (names must be unique)");
  EXPECT_HAS(error(scene(R"("gain_db": 1, "gain_db": 2)")), "scene.json: sources[0].gain_db: duplicate key");
}

TEST_F(SceneFileTest, MalformedJsonGivesLineAndColumn) {
  const std::string m = error("{\n  \"listener\": {\"position\": [0, 0, 0]},\n  \"sources\" []\n}");
  EXPECT_HAS(m, "scene.json:3:13: malformed JSON: ");
  EXPECT_HAS(m, "expected ':'");
  EXPECT_HAS(error(""), "scene.json:1:1: malformed JSON: ");
  EXPECT_HAS(error("{\"a\": [1, 2}"), "malformed JSON");
  EXPECT_HAS(error(std::string(100, '[') + std::string(100, ']')), "nested deeper than 64 levels");
  EXPECT_HAS(error("{\"description\": \"\xff\"}"), "malformed JSON");
}

// The engine's own lists: the parser must accept exactly these.
TEST_F(SceneFileTest, QualityNamesAndAirRangesAreTheEngines) {
  std::vector<std::string> presets;
  for (const QualityPreset& p : qualityPresets()) presets.push_back(p.name);
  EXPECT_EQ(sceneQualityNames(), presets);
  for (const std::string& q : presets) EXPECT_TRUE(parse(scene("", R"("settings": {"quality": ")" + q + "\"}")).isOk());
  struct Case {
    const char* key;
    double value;
  };
  for (Case c : {Case{"temperature_c", -20}, Case{"temperature_c", 50}, Case{"temperature_c", -20.5},
                 Case{"temperature_c", 50.5}, Case{"humidity_pct", 0}, Case{"humidity_pct", 100},
                 Case{"humidity_pct", -0.5}, Case{"humidity_pct", 100.5}, Case{"pressure_kpa", 50},
                 Case{"pressure_kpa", 120}, Case{"pressure_kpa", 49.5}, Case{"pressure_kpa", 120.5}}) {
    auto r =
        parse(scene("", std::string(R"("settings": {"air": {")") + c.key + "\": " + std::to_string(c.value) + "}}"));
    AirConditions air;
    if (std::string(c.key) == "temperature_c") air.temperatureC = c.value;
    if (std::string(c.key) == "humidity_pct") air.humidityPercent = c.value;
    if (std::string(c.key) == "pressure_kpa") air.pressureKpa = c.value;
    EXPECT_EQ(r.isOk(), validate(air).isOk()) << c.key << " = " << c.value;
  }
}

// ------------------------------------------------------------ samples

std::vector<fs::path> sampleScenes() {
  std::vector<fs::path> out;
  for (const auto& e : fs::recursive_directory_iterator(kSource / "samples")) {
    const fs::path& p = e.path();
    if (p.extension() != ".json" || p.filename() == "materials_map.json" || p.filename() == "scene.schema.json")
      continue;
    out.push_back(p);
  }
  std::sort(out.begin(), out.end());
  return out;
}

TEST(SampleScenes, EverySampleSceneLoadsStrictlyWithoutWarnings) {
  auto scenes = sampleScenes();
  ASSERT_GE(scenes.size(), 4u);
  for (const fs::path& p : scenes) {
    SceneParseOptions o;
    o.strict = true;
    std::vector<std::string> warnings;
    auto r = loadSceneFile(p.string(), o, &warnings);
    ASSERT_TRUE(r.isOk()) << r.status().message();
    EXPECT_TRUE(warnings.empty()) << p << ": " << warnings.front();
    EXPECT_FALSE(r->geometryPath.empty()) << p;
    EXPECT_FALSE(r->materialMap.empty()) << p;
    ASSERT_TRUE(r->settings.durationSeconds.has_value()) << p;
    EXPECT_GE(*r->settings.durationSeconds, 8.0) << p;
    EXPECT_LE(*r->settings.durationSeconds, 12.0) << p;
    for (const SceneSource& s : r->sources) EXPECT_LE(fs::file_size(s.audioPath), 1000000u) << s.audioPath;
  }
}

SceneDescription loadSample(const std::string& rel) {
  auto r = loadSceneFile((kSource / "samples" / rel).string());
  EXPECT_TRUE(r.isOk()) << r.status().message();
  return r.isOk() ? *r : SceneDescription{};
}

TEST(SampleScenes, EachSampleDoesWhatItsReadmeSays) {
  // Two rooms: the source starts in A (x < 6), crosses the doorway (y in [2, 3])
  // well inside it (y in [2.2, 2.8]) at the partition (x 6..6.2), ends in B
  // (x > 6.2); the listener stays in A. (TwoRoomsTalkerWalksThroughTheOpenDoor
  // checks the walk against the geometry.)
  SceneDescription door = loadSample("two_rooms/walk_through_door.json");
  ASSERT_EQ(door.sources.size(), 1u);
  EXPECT_EQ(fs::path(door.geometryPath).filename(), "two_rooms_door_open.gltf");
  const Trajectory& walk = door.sources[0].trajectory;
  EXPECT_LT(walk.at(0).position.x, 6.0);
  EXPECT_GT(walk.at(walk.endSeconds()).position.x, 6.2);
  for (double t = 0; t <= walk.endSeconds(); t += 0.01) {
    Vec3d p = walk.at(t).position;
    if (p.x >= 5.9 && p.x <= 6.3) {
      EXPECT_GT(p.y, 2.2) << t;
      EXPECT_LT(p.y, 2.8) << t;
      EXPECT_LT(p.z, 2.0) << t;
    }
  }
  EXPECT_LT(door.listener.trajectory.at(0).position.x, 6.0);
  EXPECT_TRUE(door.listener.trajectory.isStatic());

  // Hall: the source stays 2.5 m (the chord of a 15-degree step) from the listener, circling twice.
  SceneDescription hall = loadSample("hall/circling.json");
  const Vec3d centre = hall.listener.trajectory.at(0).position;
  double turned = 0, last = 0;
  for (int i = 0; i <= 240; ++i) {
    const double t = i * 0.05;
    Vec3d d = hall.sources[0].trajectory.at(t).position - centre;
    double r = std::hypot(d.x, d.y);
    EXPECT_GE(r, 2.5 * std::cos(kPi / 24) - 1e-3) << t;
    EXPECT_LE(r, 2.5 + 1e-3) << t;
    double a = std::atan2(d.y, d.x);
    if (i > 0) turned += std::remainder(a - last, 2 * kPi);
    last = a;
  }
  EXPECT_NEAR(std::abs(turned), 4 * kPi, 0.05);

  // Outdoor: behind the wall (y > 5.15, |x| < 5) for part of the walk, in front at the start.
  SceneDescription wall = loadSample("outdoor/wall.json");
  const Trajectory& w = wall.sources[0].trajectory;
  EXPECT_LT(w.at(0).position.y, 4.85);
  bool behind = false;
  for (double t = 0; t <= w.endSeconds(); t += 0.1) {
    Vec3d p = w.at(t).position;
    behind |= p.y > 5.15 && std::abs(p.x) < 5.0;
  }
  EXPECT_TRUE(behind);
  EXPECT_LT(wall.listener.trajectory.at(0).position.y, 4.85);

  // Shoebox: the positions of the reference data, static.
  SceneDescription box = loadSample("shoebox/static.json");
  EXPECT_TRUE(box.listener.trajectory.isStatic());
  EXPECT_TRUE(box.sources[0].trajectory.isStatic());
  EXPECT_EQ(box.sources[0].trajectory.at(0).position, Vec3d(2, 3.5, 1.5));
  EXPECT_EQ(box.listener.trajectory.at(0).position, Vec3d(7, 3.5, 1.5));
}

// The walk's positions every 10 ms, and whether the straight step between two
// of them crosses a surface of `tracer`.
std::vector<double> stepsThroughSurfaces(const Trajectory& walk, const RayTracer& tracer) {
  std::vector<double> crossed;
  for (double t = 0; t + 0.01 <= walk.endSeconds(); t += 0.01) {
    const Vec3d a = walk.at(t).position, b = walk.at(t + 0.01).position;
    const double len = length(b - a);
    if (len <= 0) continue;
    Ray ray;
    ray.origin = a;
    ray.direction = Vec3f((b - a) / len);
    ray.tFar = float(len);
    if (tracer.occluded(ray)) crossed.push_back(t);
  }
  return crossed;
}

std::unique_ptr<RayTracer> loadTwoRooms(const SceneDescription& scene, const std::string& file,
                                        std::vector<GltfNodeTriangles>* nodes) {
  auto g = loadGltf((fs::path(scene.geometryPath).parent_path() / file).string(), defaultMaterials(),
                    scene.materialMap);
  EXPECT_TRUE(g.isOk()) << g.status().message();
  if (!g.isOk()) return nullptr;
  EXPECT_TRUE(g->warnings.empty()) << g->warnings.front();
  *nodes = g->nodes;
  auto tracer = RayTracer::create(g->mesh);
  EXPECT_TRUE(tracer.isOk()) << tracer.status().message();
  return tracer.isOk() ? std::move(tracer).value() : nullptr;
}

TEST(SampleScenes, TwoRoomsTalkerWalksThroughTheOpenDoor) {
  SceneDescription scene = loadSample("two_rooms/walk_through_door.json");
  ASSERT_EQ(scene.sources.size(), 1u);
  const Trajectory& walk = scene.sources[0].trajectory;
  std::vector<GltfNodeTriangles> openNodes, closedNodes;
  auto open = loadTwoRooms(scene, "two_rooms_door_open.gltf", &openNodes);
  auto closed = loadTwoRooms(scene, "two_rooms.gltf", &closedNodes);
  ASSERT_TRUE(open && closed);

  // The same triangles but the door's: the two files differ only in the door node's transform.
  ASSERT_EQ(open->mesh().triangleCount(), closed->mesh().triangleCount());
  ASSERT_EQ(openNodes.size(), 2u);
  ASSERT_EQ(openNodes[1].name, "door");
  const GltfNodeTriangles& doorNode = openNodes[1];
  const TriangleMesh& om = open->mesh();
  const TriangleMesh& cm = closed->mesh();
  Vec3f lo{1e9f, 1e9f, 1e9f}, hi{-1e9f, -1e9f, -1e9f};
  for (uint32_t t = 0; t < om.triangleCount(); ++t) {
    const bool isDoor = t >= doorNode.firstTriangle && t < doorNode.firstTriangle + doorNode.triangleCount;
    for (int k = 0; k < 3; ++k) {
      const Vec3f p = om.positions[om.triangles[t][k]];
      if (!isDoor) {
        EXPECT_EQ(p, cm.positions[cm.triangles[t][k]]) << t;
        continue;
      }
      lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
      hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
    }
  }
  // README: the open door stands in room B at x in [6.105, 7.095], y in [2.005, 2.045]:
  // clear of the partition's solid part (y < 2 or y > 3 for x in [6, 6.2]) and of the doorway's head (z 2.1).
  EXPECT_NEAR(lo.x, 6.105f, 1e-4f);
  EXPECT_NEAR(hi.x, 7.095f, 1e-4f);
  EXPECT_NEAR(lo.y, 2.005f, 1e-4f);
  EXPECT_NEAR(hi.y, 2.045f, 1e-4f);
  EXPECT_GT(lo.z, 0.0f);
  EXPECT_LT(hi.z, 2.1f);

  // The talker walks through no surface of the open-door geometry, but through
  // the closed door (the only thing between the two) in the other file.
  EXPECT_EQ(stepsThroughSurfaces(walk, *open), std::vector<double>{});
  const std::vector<double> throughClosed = stepsThroughSurfaces(walk, *closed);
  ASSERT_FALSE(throughClosed.empty());
  for (double t : throughClosed) EXPECT_NEAR(walk.at(t).position.x, 6.1, 0.05) << t;  // the door's two faces

  // Direct sound: the listener sees the talker in the doorway (t ~ 3.5 s) and
  // loses them behind the partition later in room B (t ~ 5 s).
  const Vec3d ear = scene.listener.trajectory.at(0).position;
  auto visible = [&](double t) {
    const Vec3d d = walk.at(t).position - ear;
    Ray ray;
    ray.origin = ear;
    ray.direction = Vec3f(d / length(d));
    ray.tFar = float(length(d));
    return !open->occluded(ray);
  };
  double doorway = -1, hidden = -1;
  for (double t = 0; t <= walk.endSeconds(); t += 0.01) {
    if (doorway < 0 && walk.at(t).position.x >= 6.1) doorway = t;
    if (doorway >= 0 && hidden < 0 && !visible(t)) hidden = t;
  }
  EXPECT_NEAR(doorway, 3.5, 0.1);
  EXPECT_TRUE(visible(doorway));
  EXPECT_NEAR(hidden, 5.0, 0.3);
}

TEST(SampleScenes, SampleAudioLoadsAtTheSceneRate) {
  std::set<std::string> audio;
  for (const fs::path& p : sampleScenes()) {
    auto r = loadSceneFile(p.string());
    ASSERT_TRUE(r.isOk()) << r.status().message();
    for (const SceneSource& s : r->sources) audio.insert(s.audioPath);
  }
  bool resampled = false;
  for (const std::string& a : audio) {
    std::string log;
    auto d = loadDryAudio(a, 48000.0, &log);
    ASSERT_TRUE(d.isOk()) << d.status().message();
    EXPECT_EQ(d->fileChannels, 1u) << a;
    EXPECT_GE(d->samples.size(), size_t(8 * 48000)) << a;
    resampled |= d->fileRateHz != 48000.0;
  }
  EXPECT_TRUE(resampled) << "no sample exercises resampling";
}

// ------------------------------------------------------------ schema and docs

TEST(SceneSchema, IsValidJsonAndListsTheKeysTheParserAccepts) {
  const std::string text = readFile(kSource / "samples" / "scene.schema.json");
  json schema = json::parse(text, nullptr, false);
  ASSERT_FALSE(schema.is_discarded()) << "samples/scene.schema.json is not valid JSON";
  EXPECT_EQ(schema.value("$schema", ""), "https://json-schema.org/draft/2020-12/schema");
  auto keysOf = [](const json& props) {
    std::set<std::string> s;
    for (auto it = props.begin(); it != props.end(); ++it) s.insert(it.key());
    return s;
  };
  for (const SceneObjectKeys& o : sceneFileKeys()) {
    const json* obj = nullptr;
    if (o.object == "scene") {
      obj = &schema;
    } else if (o.object == "air") {
      obj = &schema["$defs"]["air"]["oneOf"][1];
    } else {
      ASSERT_TRUE(schema["$defs"].contains(o.object)) << o.object;
      obj = &schema["$defs"][o.object];
    }
    ASSERT_TRUE(obj->contains("properties")) << o.object;
    EXPECT_EQ(keysOf((*obj)["properties"]), std::set<std::string>(o.keys.begin(), o.keys.end())) << o.object;
    EXPECT_EQ(obj->value("additionalProperties", true), false) << o.object;
  }
  std::vector<std::string> qualities = schema["$defs"]["settings"]["properties"]["quality"]["enum"];
  EXPECT_EQ(qualities, sceneQualityNames());
}

TEST(SceneDocs, TheFormatDocNamesEveryKeyAndItsExampleParses) {
  const std::string doc = readFile(kSource / "docs" / "scene-format.md");
  ASSERT_FALSE(doc.empty());
  for (const SceneObjectKeys& o : sceneFileKeys())
    for (const std::string& k : o.keys) EXPECT_HAS(doc, "`" + k + "`");
  const size_t begin = doc.find("```json\n");
  ASSERT_NE(begin, std::string::npos);
  const size_t end = doc.find("```", begin + 8);
  // Its paths are written as seen from samples/furnished_room/: every file
  // exists. They reach the shared materials, HRTF and other scenes' audio
  // outside that folder, as the doc says, so only with allowOutsidePaths.
  SceneParseOptions o;
  o.strict = true;
  {
    auto refused = parseSceneText(doc.substr(begin + 8, end - begin - 8),
                                  (kSource / "samples" / "furnished_room").string(), "scene-format.md example", o);
    ASSERT_FALSE(refused.isOk());
    EXPECT_HAS(refused.status().message(), "allow-outside-paths");
  }
  o.allowOutsidePaths = true;
  std::vector<std::string> warnings;
  auto r = parseSceneText(doc.substr(begin + 8, end - begin - 8), (kSource / "samples" / "furnished_room").string(),
                          "scene-format.md example", o, &warnings);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_TRUE(warnings.empty());
  EXPECT_GE(r->sources.size(), 2u);
}

}  // namespace
}  // namespace earshot

namespace earshot {
namespace {

// The per-source controls of issue 19 are read with their values.
class SceneControlsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    AudioBuffer a(1, 480, 48000.0);
    ASSERT_TRUE(writeWavFloat(mDir / "dry.wav", a).isOk());
  }
  testing::TempDir mDir{"scene_controls"};
};

TEST_F(SceneControlsTest, EveryControlIsRead) {
  const std::string text = R"({"listener": {"position": [0, 0, 0]}, "sources": [{"name": "a", "audio": "dry.wav",
      "position": [0, 0, -2], "directivity": "hypercardioid", "directivity_sharpness": 2, "direct_gain_db": -3,
      "reflections_gain_db": -6, "distance_model": "inverse", "min_distance": 2, "max_distance": 50, "rolloff": 1.5,
      "occlusion": "volumetric", "radius": 0.75, "transmission": false, "priority": 7},
      {"name": "b", "audio": "dry.wav", "position": [1, 0, -2], "directivity": 0.3}]})";
  SceneParseOptions o;
  o.strict = true;
  auto r = parseSceneText(text, mDir.path.string(), "scene.json", o);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const SceneSource& a = r->sources[0];
  EXPECT_EQ(a.directivityAlpha, 0.75);
  EXPECT_EQ(a.directivitySharpness, 2.0);
  EXPECT_EQ(a.directGainDb, -3.0);
  EXPECT_EQ(a.reflectionsGainDb, -6.0);
  EXPECT_EQ(a.distanceModel, "inverse");
  EXPECT_EQ(a.minDistance, 2.0);
  EXPECT_EQ(a.maxDistance, 50.0);
  EXPECT_EQ(a.rolloff, 1.5);
  EXPECT_EQ(a.occlusion, "volumetric");
  EXPECT_EQ(a.radius, 0.75);
  EXPECT_FALSE(a.transmission);
  EXPECT_EQ(a.priority, 7);
  EXPECT_EQ(r->sources[1].directivityAlpha, 0.3);
  auto bands = parseSceneText(R"({"listener": {"position": [0, 0, 0]}, "sources": [{"name": "a", "audio": "dry.wav",
      "position": [0, 0, -2], "directivity_bands": [0, 0, 0.1, 0.3, 0.5, 0.6, 0.7]}]})",
                              mDir.path.string(), "scene.json", o);
  ASSERT_TRUE(bands.isOk()) << bands.status().message();
  EXPECT_EQ(bands->sources[0].directivityBands, (std::vector<double>{0, 0, 0.1, 0.3, 0.5, 0.6, 0.7}));
  auto sixBands = parseSceneText(R"({"listener": {"position": [0, 0, 0]}, "sources": [{"name": "a", "audio": "dry.wav",
      "position": [0, 0, -2], "directivity_bands": [0, 0, 0.1, 0.3, 0.5, 0.6]}]})",
                                 mDir.path.string(), "scene.json", o);
  EXPECT_FALSE(sixBands.isOk());
  auto t = parseSceneText(R"({"listener": {"position": [0, 0, 0]}, "sources": [{"name": "a", "audio": "dry.wav",
      "position": [0, 0, -2], "distance_model": "table", "distance_table": [[1, 1], [5, 0.2]]}]})",
                          mDir.path.string(), "scene.json", o);
  ASSERT_TRUE(t.isOk()) << t.status().message();
  ASSERT_EQ(t->sources[0].distanceTable.size(), 2u);
  EXPECT_EQ(t->sources[0].distanceTable[1], std::make_pair(5.0, 0.2));
  auto noTable = parseSceneText(R"({"listener": {"position": [0, 0, 0]}, "sources": [{"name": "a", "audio": "dry.wav",
      "position": [0, 0, -2], "distance_model": "table"}]})",
                                mDir.path.string(), "scene.json", o);
  ASSERT_FALSE(noTable.isOk());
  EXPECT_NE(noTable.status().message().find("distance_table"), std::string::npos);
  EXPECT_EQ(r->sources[1].distanceModel, "physical");
  EXPECT_TRUE(r->sources[1].transmission);
}

}  // namespace
}  // namespace earshot
