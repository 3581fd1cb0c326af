// `earshot render` run as a user would (issue 7): exactness of a static scene
// against `earshot ir`, Doppler, no clicks, bad scene files, no partial output.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "../cli/cli_test_util.h"
#include "../support/sine_frequency.h"
#include "earshot/core/math.h"
#include "earshot/core/random.h"
#include "earshot/io/wav.h"

namespace earshot {
namespace {

using testing::readFile;
using testing::runEarshot;
using testing::TempDir;

const std::string kSamples = std::string(EARSHOT_SOURCE_DIR) + "/samples/";
constexpr double kFs = 48000.0;

void writeMono(const std::string& path, const std::vector<float>& x) {
  AudioBuffer b(1, x.size(), kFs);
  b.channels[0] = x;
  ASSERT_TRUE(writeWavFloat(path, b).isOk());
}

AudioBuffer read(const std::string& path) {
  auto r = readAudioFile(path);
  EXPECT_TRUE(r.isOk()) << path << ": " << r.status().message();
  return r.isOk() ? std::move(r.value()) : AudioBuffer();
}

std::vector<float> sine(double hz, double seconds) {
  std::vector<float> x(size_t(seconds * kFs));
  for (size_t i = 0; i < x.size(); ++i) x[i] = float(0.5 * std::sin(2 * kPi * hz * double(i) / kFs));
  return x;
}

double frequency(const std::vector<float>& x, size_t from, size_t n) { return test::sineFrequency(x, from, n, kFs); }

// Largest sample-to-sample step relative to the local amplitude (the largest
// |x| within one period either side). A steady sine of frequency f gives at
// most 2 sin(pi f / fs); a click gives far more whatever the level.
double maxRelativeStep(const std::vector<float>& x, size_t from, size_t to, size_t period) {
  double m = 0;
  for (size_t i = std::max<size_t>(from, 1); i < to && i + period < x.size(); ++i) {
    double amplitude = 0;
    for (size_t k = i - std::min(i, period); k <= i + period; ++k) amplitude = std::max(amplitude, double(std::fabs(x[k])));
    if (amplitude > 0) m = std::max(m, double(std::fabs(x[i] - x[i - 1])) / amplitude);
  }
  return m;
}

// A source walking from (2, 2) to (4, 5) in the shoebox over `seconds`,
// playing sine.wav from the scene's folder, draft quality, 10 Hz updates.
void writeWalkInShoebox(const std::string& path, double seconds) {
  std::ofstream(path) << R"({"geometry": ")" << kSamples << R"(shoebox/shoebox.gltf",
    "material_map": ")" << kSamples << R"(shoebox/materials_map.json",
    "listener": {"position": [7, 3.5, 1.5], "forward": [-1, 0, 0], "up": [0, 0, 1]},
    "sources": [{"name": "s", "audio": "sine.wav", "path": [{"t": 0, "position": [2, 2, 1.5]}, {"t": )"
                      << seconds << R"(, "position": [4, 5, 1.5]}]}],
    "settings": {"quality": "draft", "duration": )" << seconds << R"(, "update_rate_hz": 10}})";
}

std::string vec(double x, double y, double z) {
  return "[" + std::to_string(x) + ", " + std::to_string(y) + ", " + std::to_string(z) + "]";
}

}  // namespace

// Issue 7: one static source and listener (binaural reflections,
// ambisonic_order 0: the exact per-arrival path) render to exactly the convolution
// of the dry signal with `earshot ir`'s IR for the same positions and seed
// (to 1e-5 of the peak), with each trace (issue 16): shared is `earshot ir
// --trace shared`'s, per-source `earshot ir`'s default, and the render's
// default (auto: the listener stays in place, so one source too is traced
// from it, its paths kept) is the shared one.
TEST(RenderCli, StaticSceneIsTheDrySignalConvolvedWithEarshotIrsIr) {
  TempDir dir("render_static");
  std::vector<float> dry(size_t(0.25 * kFs));
  Pcg32 rng(5, 6);
  for (float& v : dry) v = rng.uniform() - 0.5f;
  writeMono(dir / "dry.wav", dry);
  for (const std::string trace : {"", "per-source", "shared"}) {
    SCOPED_TRACE("trace " + (trace.empty() ? std::string("(default)") : trace));
    std::ofstream(dir / "scene.json") << R"({
      "geometry": ")" << kSamples << R"(shoebox/shoebox.gltf",
      "material_map": ")" << kSamples << R"(shoebox/materials_map.json",
      "listener": {"position": [7, 4, 1.6], "forward": [-1, 0.2, 0], "up": [0, 0, 1]},
      "sources": [{"name": "noise", "audio": "dry.wav", "position": [2.5, 3, 1.4]}],
      "settings": {"quality": "draft", "seed": 3, "duration": 1.6, "ambisonic_order": 0)"
                                      << (trace.empty() ? "" : R"(, "trace": ")" + trace + "\"") << R"(}
    })";
    auto ir = runEarshot("ir " + kSamples + "shoebox/shoebox.gltf --material-map " + kSamples +
                         "shoebox/materials_map.json --source 2.5,3,1.4 --listener 7,4,1.6 --forward -1,0.2,0 --up "
                         "0,0,1 --quality draft --seed 3 --trace " + (trace.empty() ? "shared" : trace) + " -o " +
                         dir / "ir.wav");
    ASSERT_EQ(ir.exitCode, 0) << ir.output;
    auto render = runEarshot("--allow-outside-paths render " + dir / "scene.json" + " -o " + dir / "out.wav");
    ASSERT_EQ(render.exitCode, 0) << render.output;
    if (trace.empty()) {
      EXPECT_NE(render.output.find("its paths kept (the listener stays in place)"), std::string::npos) << render.output;
    }
    const AudioBuffer h = read(dir / "ir.wav"), y = read(dir / "out.wav");
    ASSERT_EQ(h.channelCount(), 2u);
    ASSERT_EQ(y.channelCount(), 2u);
    ASSERT_EQ(y.frameCount(), size_t(1.6 * kFs));
    double peak = 0, worst = 0;
    for (int ear = 0; ear < 2; ++ear) {
      // Direct convolution in double, every 7th output sample (enough to catch any error).
      for (size_t t = 0; t < y.frameCount(); t += 7) {
        double acc = 0;
        const size_t k0 = t >= h.frameCount() ? t - h.frameCount() + 1 : 0;
        for (size_t k = k0; k <= t && k < dry.size(); ++k) acc += double(dry[k]) * h.channels[ear][t - k];
        peak = std::max(peak, std::fabs(acc));
        worst = std::max(worst, std::fabs(acc - y.channels[ear][t]));
      }
    }
    EXPECT_GT(peak, 1e-3);
    EXPECT_LE(worst, 1e-5 * peak) << "worst " << worst << " of peak " << peak;
  }
}

// Issue 7: a source moving at constant speed past the listener shows the
// Doppler shift expected from its speed: f c / (c - v) approaching and
// f c / (c + v) receding (measured on the rendered sine, within 1 %).
TEST(RenderCli, PassingSourceHasTheDopplerShiftOfItsSpeed) {
  TempDir dir("render_doppler");
  const double f0 = 400.0, v = 25.0, c = 343.0;
  writeMono(dir / "sine.wav", sine(f0, 8.0));
  std::ofstream(dir / "scene.json") << R"({
    "listener": {"position": [0, 0, 0]},
    "sources": [{"name": "car", "audio": "sine.wav",
                 "path": [{"t": 0, "position": )" << vec(-100, 0, -3) << R"(},
                          {"t": 8, "position": )" << vec(-100 + 8 * v, 0, -3) << R"(}]}],
    "settings": {"quality": "draft", "duration": 8, "air": "off"}
  })";
  auto render = runEarshot("--allow-outside-paths render " + dir / "scene.json" + " -o " + dir / "out.wav --quiet");
  ASSERT_EQ(render.exitCode, 0) << render.output;
  const AudioBuffer y = read(dir / "out.wav");
  ASSERT_EQ(y.channelCount(), 2u);
  const double approach = frequency(y.channels[0], size_t(1.0 * kFs), size_t(0.5 * kFs));
  const double recede = frequency(y.channels[0], size_t(7.0 * kFs), size_t(0.5 * kFs));
  // At 1.0-1.5 s the source is 60-75 m before the listener, 3 m aside (cos > 0.998).
  EXPECT_NEAR(approach / (f0 * c / (c - v)), 1.0, 0.01) << approach << " Hz";
  EXPECT_NEAR(recede / (f0 * c / (c + v)), 1.0, 0.01) << recede << " Hz";
}

// Issue 7: no clicks. A steady 300 Hz sine from a source moving in steps
// (held for 0.4 s, then moved 0.5 m in 0.1 s, across reflection updates at
// 10 Hz) has no sample-to-sample jump larger than the static render has,
// relative to the local amplitude (in a room a steady sine's level depends on
// where the source stands, so absolute steps would compare positions, not
// clicks). A steady sine's relative step is 2 sin(pi f / fs) = 0.039; a click
// of even 1 % of full scale on a -30 dB tone would double it. Motion itself
// may raise it by the Doppler factor (1 + v / c, v = 5 m/s) times the slope
// change of crossfading two phases of the tone over the renderer's 2048-frame
// IR fade (1 + 1 / (2 pi f T)).
TEST(RenderCli, SourceMovingInStepsHasNoJumpsLargerThanTheStaticRender) {
  TempDir dir("render_steps");
  writeMono(dir / "sine.wav", sine(300.0, 4.0));
  std::string path = "[";
  for (int k = 0; k < 8; ++k) {
    const double x = 3.0 + 0.5 * k;
    path += (k ? "," : "") + std::string("{\"t\": ") + std::to_string(0.5 * k) + ", \"position\": " + vec(x, 3.5, 1.5) +
            "}, {\"t\": " + std::to_string(0.5 * k + 0.4) + ", \"position\": " + vec(x, 3.5, 1.5) + "}";
  }
  path += "]";
  auto scene = [&](const std::string& source) {
    return R"({"geometry": ")" + kSamples + R"(shoebox/shoebox.gltf", "material_map": ")" + kSamples +
           R"(shoebox/materials_map.json", "listener": {"position": [8, 3.5, 1.5], "forward": [-1, 0, 0], "up": [0, 0, 1]},
           "sources": [{"name": "tone", "audio": "sine.wav", )" + source + R"(}],
           "settings": {"quality": "draft", "duration": 4, "update_rate_hz": 10}})";
  };
  std::ofstream(dir / "moving.json") << scene("\"path\": " + path);
  std::ofstream(dir / "static.json") << scene("\"position\": " + vec(6.5, 3.5, 1.5));  // the nearest point
  auto a = runEarshot("--allow-outside-paths render " + dir / "moving.json" + " -o " + dir / "moving.wav --quiet");
  auto b = runEarshot("--allow-outside-paths render " + dir / "static.json" + " -o " + dir / "static.wav --quiet");
  ASSERT_EQ(a.exitCode, 0) << a.output;
  ASSERT_EQ(b.exitCode, 0) << b.output;
  const AudioBuffer moving = read(dir / "moving.wav"), still = read(dir / "static.wav");
  const size_t from = size_t(0.5 * kFs), to = size_t(3.9 * kFs);  // after the onset, before the tone ends
  const size_t period = size_t(kFs / 300.0) + 1;
  for (int ear = 0; ear < 2; ++ear) {
    const double m = maxRelativeStep(moving.channels[ear], from, to, period);
    const double s = maxRelativeStep(still.channels[ear], from, to, period);
    std::printf("ear %d: largest relative step moving %.4f, static %.4f (steady sine %.4f)\n", ear, m, s,
                2 * std::sin(kPi * 300.0 / kFs));
    EXPECT_GT(s, 0.0);
    const double motion = (1.0 + 5.0 / 343.0) * (1.0 + 1.0 / (2 * kPi * 300.0 * 2048.0 / kFs));
    EXPECT_LE(m, s * motion) << "ear " << ear;
  }
}

// Issue 15: no click from a fast head turn. A steady 300 Hz sine from a
// still source in the shoebox while the listener turns 360 degrees in 0.5 s
// (ambisonic reflections rotated every block, the direct sound's HRTF every
// block): no sample-to-sample step larger, relative to the local amplitude,
// than the still head's render has, beyond what the turn itself does to a
// steady tone (the ears' path lengths change by at most the head's radius
// times the turn rate: (1 + 0.09 m x 4 pi / s / c) on the slope, and the
// level at each ear changes with the HRTF: we allow 10 % in all).
TEST(RenderCli, FastHeadTurnHasNoJumpsLargerThanAStillHead) {
  TempDir dir("render_turn");
  writeMono(dir / "sine.wav", sine(300.0, 3.0));
  std::string keys = "[";
  for (int k = 0; k <= 16; ++k) {
    const double t = 1.0 + 0.5 * k / 16.0, a = 2 * kPi * k / 16.0;
    keys += (k ? "," : "") + std::string("{\"t\": ") + std::to_string(t) + ", \"position\": [7, 3.5, 1.5], \"forward\": " +
            vec(std::cos(a), std::sin(a), 0) + ", \"up\": [0, 0, 1]}";
  }
  keys += "]";
  auto scene = [&](const std::string& listener) {
    return R"({"geometry": ")" + kSamples + R"(shoebox/shoebox.gltf", "material_map": ")" + kSamples +
           R"(shoebox/materials_map.json", "listener": )" + listener + R"(,
           "sources": [{"name": "tone", "audio": "sine.wav", "position": [3, 2, 1.5]}],
           "settings": {"quality": "draft", "duration": 3, "ambisonic_order": 1}})";
  };
  std::ofstream(dir / "turn.json") << scene("{\"path\": " + keys + "}");
  std::ofstream(dir / "still.json") << scene(R"({"position": [7, 3.5, 1.5], "forward": [1, 0, 0], "up": [0, 0, 1]})");
  auto a = runEarshot("--allow-outside-paths render " + dir / "turn.json" + " -o " + dir / "turn.wav --quiet");
  auto b = runEarshot("--allow-outside-paths render " + dir / "still.json" + " -o " + dir / "still.wav --quiet");
  ASSERT_EQ(a.exitCode, 0) << a.output;
  ASSERT_EQ(b.exitCode, 0) << b.output;
  const AudioBuffer turn = read(dir / "turn.wav"), still = read(dir / "still.wav");
  const size_t from = size_t(0.9 * kFs), to = size_t(1.6 * kFs);  // the turn and 0.1 s either side
  const size_t period = size_t(kFs / 300.0) + 1;
  for (int ear = 0; ear < 2; ++ear) {
    const double m = maxRelativeStep(turn.channels[ear], from, to, period);
    const double s = maxRelativeStep(still.channels[ear], from, to, period);
    std::printf("ear %d: largest relative step turning %.4f, still %.4f (steady sine %.4f)\n", ear, m, s,
                2 * std::sin(kPi * 300.0 / kFs));
    EXPECT_GT(s, 0.0);
    EXPECT_LE(m, s * 1.1) << "ear " << ear;
  }
}

// Issue 15: "output": "ambisonic" writes the AmbiX channels of the order in
// the listener's frame: a source on the listener's left (free field) is all
// in W and Y (Y = W), nothing in X or Z; ambisonic output without an
// ambisonic order is one clear error.
TEST(RenderCli, AmbisonicOutputIsAmbiXInTheListenersFrame) {
  TempDir dir("render_ambix");
  writeMono(dir / "sine.wav", sine(500.0, 1.0));
  auto scene = [&](const std::string& settings) {
    return R"({"listener": {"position": [0, 0, 0], "forward": [1, 0, 0], "up": [0, 0, 1]},
           "sources": [{"name": "tone", "audio": "sine.wav", "position": [0, 5, 0]}],
           "settings": {"duration": 1, )" + settings + "}}";
  };
  std::ofstream(dir / "ambix.json") << scene(R"("ambisonic_order": 2, "output": "ambisonic")");
  auto a = runEarshot("render " + dir / "ambix.json" + " -o " + dir / "ambix.wav --quiet");
  ASSERT_EQ(a.exitCode, 0) << a.output;
  const AudioBuffer out = read(dir / "ambix.wav");
  ASSERT_EQ(out.channelCount(), 9u);
  auto energy = [&](size_t c) {
    double e = 0;
    for (size_t i = size_t(0.2 * kFs); i < size_t(0.8 * kFs); ++i) e += double(out.channels[c][i]) * out.channels[c][i];
    return e;
  };
  const double w = energy(0);
  EXPECT_GT(w, 0.0);
  EXPECT_NEAR(energy(1) / w, 1.0, 0.01);  // Y
  EXPECT_LT(energy(2) / w, 1e-4);         // Z
  EXPECT_LT(energy(3) / w, 1e-4);         // X
  EXPECT_NEAR(energy(8) / w, 0.75, 0.01); // U = sqrt(3)/2 (x^2 - y^2): 3/4 of W's energy
  std::ofstream(dir / "bad.json") << scene(R"("ambisonic_order": 0, "output": "ambisonic")");
  auto b = runEarshot("render " + dir / "bad.json" + " -o " + dir / "bad.wav --quiet");
  EXPECT_EQ(b.exitCode, 2);
  EXPECT_NE(b.output.find("ambisonic_order"), std::string::npos) << b.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.wav"));
  auto c = runEarshot("render " + dir / "ambix.json" + " -o " + dir / "bin.wav --quiet --output-format binaural");
  ASSERT_EQ(c.exitCode, 0) << c.output;
  EXPECT_EQ(read(dir / "bin.wav").channelCount(), 2u);
}

// Issue 7: bad scene files each give one clear error naming the file and the
// field, exit 2, and never leave a partial output; an existing output is
// left untouched.
TEST(RenderCli, BadScenesAreOneClearErrorAndLeaveTheOutputAlone) {
  TempDir dir("render_bad");
  writeMono(dir / "dry.wav", sine(200.0, 0.5));
  const std::string good = R"("listener": {"position": [0, 0, 0]}, "sources": [{"name": "a", "audio": "dry.wav", "position": [0, 0, -2]}])";
  struct Case {
    std::string name, json, mustMention;
  };
  const std::vector<Case> cases = {
      {"missing_listener", R"({"sources": [{"name": "a", "audio": "dry.wav", "position": [0, 0, -2]}]})", "listener"},
      {"wrong_type", "{" + good + R"(, "settings": {"sample_rate": "48k"}})", "settings.sample_rate"},
      {"unknown_material", "{" + good + R"(, "material_map": {"Wall": "no_such_material"}})", "no_such_material"},
      {"missing_audio", R"({"listener": {"position": [0, 0, 0]}, "sources": [{"name": "a", "audio": "nope.wav", "position": [0, 0, -2]}]})", "nope.wav"},
      {"negative_time", R"({"listener": {"position": [0, 0, 0]}, "sources": [{"name": "a", "audio": "dry.wav", "position": [0, 0, -2], "start": -1}]})", "start"},
      {"keyframes_backwards", R"({"listener": {"path": [{"t": 1, "position": [0, 0, 0]}, {"t": 0.5, "position": [1, 0, 0]}]}, "sources": [{"name": "a", "audio": "dry.wav", "position": [0, 0, -2]}]})", "path[1].t"},
      {"huge_number", "{" + good + R"(, "settings": {"duration": 1e999}})", "settings.duration"},
      {"malformed", "{" + good + ", }", "malformed JSON"},
  };
  for (const Case& c : cases) {
    const std::string scene = dir / (c.name + ".json"), out = dir / (c.name + ".wav");
    std::ofstream(scene) << c.json;
    std::ofstream(out) << "precious";
    auto r = runEarshot("--allow-outside-paths render " + scene + " -o " + out + " --quiet");
    EXPECT_EQ(r.exitCode, 2) << c.name << ": " << r.output;
    EXPECT_NE(r.output.find(c.mustMention), std::string::npos) << c.name << ": " << r.output;
    EXPECT_NE(r.output.find(c.name + ".json"), std::string::npos) << c.name << " names the file: " << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << c.name << ": one line: " << r.output;
    EXPECT_EQ(readFile(out), "precious") << c.name << ": output replaced on failure";
  }
  // No output at all when the render fails: nothing is created.
  std::ofstream(dir / "bad.json") << "{" + good + R"(, "settings": {"quality": "ultra"}})";
  auto r = runEarshot("--allow-outside-paths render " + dir / "bad.json" + " -o " + dir / "none.wav --quiet");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "none.wav"));
  // -o naming an input is refused.
  std::ofstream(dir / "ok.json") << "{" + good + R"(, "settings": {"duration": 0.5, "quality": "draft"}})";
  const std::string before = readFile(dir / "dry.wav");
  r = runEarshot("--allow-outside-paths render " + dir / "ok.json" + " -o " + dir / "dry.wav --quiet");
  EXPECT_EQ(r.exitCode, 2) << r.output;
  EXPECT_NE(r.output.find("input"), std::string::npos) << r.output;
  EXPECT_EQ(readFile(dir / "dry.wav"), before);
}

// Same scene and seed, any thread count: bit-identical output.
TEST(RenderCli, ThreadCountDoesNotChangeTheOutput) {
  TempDir dir("render_threads");
  writeMono(dir / "sine.wav", sine(250.0, 1.0));
  writeWalkInShoebox(dir / "scene.json", 1.5);
  auto a = runEarshot("--allow-outside-paths render " + dir / "scene.json" + " -o " + dir / "a.wav --quiet --threads 1");
  auto b = runEarshot("--allow-outside-paths render " + dir / "scene.json" + " -o " + dir / "b.wav --quiet --threads 2");
  ASSERT_EQ(a.exitCode, 0) << a.output;
  ASSERT_EQ(b.exitCode, 0) << b.output;
  EXPECT_TRUE(readFile(dir / "a.wav") == readFile(dir / "b.wav"));
}

// Sources that play the same file share one load of it (read and resampled
// once, while the HRTF loads); the render is the one two copies of the file
// give, and the log says which source's audio a source plays.
TEST(RenderCli, SourcesPlayingOneFileLoadItOnce) {
  TempDir dir("render_shared_audio");
  std::vector<float> x = sine(250.0, 1.0);
  for (size_t i = 0; i < x.size(); i += 7) x[i] *= 0.5f;  // not a pure tone
  AudioBuffer b(1, x.size(), 44100.0);  // resampled to 48 kHz
  b.channels[0] = x;
  ASSERT_TRUE(writeWavFloat(dir / "a.wav", b).isOk());
  ASSERT_TRUE(writeWavFloat(dir / "b.wav", b).isOk());
  auto scene = [&](const std::string& second) {
    std::ofstream(dir / "scene.json") << R"({"geometry": ")" << kSamples << R"(shoebox/shoebox.gltf",
      "material_map": ")" << kSamples << R"(shoebox/materials_map.json",
      "listener": {"position": [7, 3.5, 1.5], "forward": [-1, 0, 0], "up": [0, 0, 1]},
      "sources": [{"name": "one", "audio": "a.wav", "position": [2, 2, 1.5]},
                  {"name": "two", "audio": ")" << second << R"(", "position": [3, 5, 1.2]}],
      "settings": {"quality": "draft", "duration": 1.2}})";
  };
  scene("a.wav");
  auto shared = runEarshot("--allow-outside-paths render " + dir / "scene.json" + " -o " + dir / "shared.wav");
  scene("b.wav");
  auto copies = runEarshot("--allow-outside-paths render " + dir / "scene.json" + " -o " + dir / "copies.wav");
  ASSERT_EQ(shared.exitCode, 0) << shared.output;
  ASSERT_EQ(copies.exitCode, 0) << copies.output;
  EXPECT_NE(shared.output.find("source \"two\": the audio of source \"one\""), std::string::npos) << shared.output;
  EXPECT_EQ(copies.output.find("the audio of source"), std::string::npos) << copies.output;
  EXPECT_TRUE(readFile(dir / "shared.wav") == readFile(dir / "copies.wav"));
}

// --from/--to: a window that starts within the 2 s pre-roll is exactly that
// part of the full render (the same blocks, updates and reverberation); a
// window ending before it starts is an error.
TEST(RenderCli, FromToWindowIsTheSamePartOfTheFullRender) {
  TempDir dir("render_window");
  writeMono(dir / "sine.wav", sine(330.0, 2.0));
  writeWalkInShoebox(dir / "scene.json", 2.5);
  auto full = runEarshot("--allow-outside-paths render " + dir / "scene.json" + " -o " + dir / "full.wav --quiet");
  auto part = runEarshot("--allow-outside-paths render " + dir / "scene.json" + " -o " + dir / "part.wav --quiet --from 1 --to 2");
  ASSERT_EQ(full.exitCode, 0) << full.output;
  ASSERT_EQ(part.exitCode, 0) << part.output;
  const AudioBuffer f = read(dir / "full.wav"), p = read(dir / "part.wav");
  ASSERT_EQ(p.frameCount(), size_t(kFs));
  for (int ear = 0; ear < 2; ++ear)
    for (size_t i = 0; i < p.frameCount(); ++i)
      ASSERT_EQ(p.channels[ear][i], f.channels[ear][size_t(kFs) + i]) << "ear " << ear << " frame " << i;
  auto bad = runEarshot("--allow-outside-paths render " + dir / "scene.json" + " -o " + dir / "bad.wav --quiet --from 2 --to 1");
  EXPECT_EQ(bad.exitCode, 2) << bad.output;
  EXPECT_NE(bad.output.find("--from"), std::string::npos) << bad.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.wav"));
}

}  // namespace earshot

namespace earshot {

// Issue 19: a scene's per-source controls reach the render. A moving source
// (direct sound per block) with its reflections at -120 dB is quieter than
// the same source with them, and silencing the direct sound instead leaves
// the reflections; a cardioid facing away keeps its reverberation.
TEST(RenderCli, SceneControlsReachTheRender) {
  TempDir dir("render_controls");
  // Noise: direct sound and reflections add in energy (a sine's would interfere).
  std::vector<float> noise(48000);
  Pcg32 rng(3, 0);
  for (float& v : noise) v = float(0.2 * (double(rng.next()) / 4294967296.0 - 0.5));
  writeMono(dir / "sine.wav", noise);
  auto energyOf = [&](const std::string& sourceExtra) {
    std::ofstream(dir / "scene.json") << R"({"geometry": ")" << kSamples << R"(shoebox/shoebox.gltf",
      "material_map": ")" << kSamples << R"(shoebox/materials_map.json",
      "listener": {"position": [7, 3.5, 1.5], "forward": [-1, 0, 0], "up": [0, 0, 1]},
      "sources": [{"name": "s", "audio": "sine.wav", "forward": [-1, 0, 0],
                   "path": [{"t": 0, "position": [2, 3, 1.5]}, {"t": 1, "position": [2.5, 3, 1.5]}])"
                                      << sourceExtra << R"(}],
      "settings": {"quality": "draft", "duration": 1.5, "update_rate_hz": 10}})";
    auto r = runEarshot("render " + dir / "scene.json" + " -o " + dir / "out.wav --quiet --allow-outside-paths");
    EXPECT_EQ(r.exitCode, 0) << r.output;
    const AudioBuffer b = read(dir / "out.wav");
    double e = 0;
    for (const auto& ch : b.channels)
      for (float v : ch) e += double(v) * v;
    return e;
  };
  const double both = energyOf("");
  const double direct = energyOf(R"(, "reflections_gain_db": -120)");
  const double reflections = energyOf(R"(, "direct_gain_db": -120)");
  ASSERT_GT(both, 0.0);
  EXPECT_LT(direct, 0.9 * both);
  EXPECT_LT(reflections, 0.9 * both);
  EXPECT_NEAR(direct + reflections, both, 0.05 * both);  // they add in energy
  // Facing away (forward -x, the listener at +x): the direct sound is gone,
  // the room still rings; within 1.5 dB of the omni source's reflections.
  const double cardioidReflections = energyOf(R"(, "direct_gain_db": 0, "directivity": "cardioid")") ;
  EXPECT_GT(cardioidReflections, 0.5 * reflections);
  EXPECT_LT(cardioidReflections, 1.5 * reflections);
}

}  // namespace earshot

namespace earshot {

// Issue 19: --normalize scales the whole render to a peak level, in any
// output format, and says so; nothing of the first pass is left behind.
TEST(RenderCli, NormalizeSetsThePeakAndReportsIt) {
  TempDir dir("render_normalize");
  for (auto [name, dbfs] : {std::pair{"out.wav", -6.0}, std::pair{"out.flac", -1.0}}) {
    auto r = runEarshot("render " + kSamples + "shoebox/static.json -o " + dir / name +
                        " --quality draft --to 1 --quiet --normalize " + std::to_string(dbfs));
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find("normalised"), std::string::npos) << r.output;
    const AudioBuffer b = read(dir / name);
    float peak = 0;
    for (const auto& ch : b.channels)
      for (float v : ch) peak = std::max(peak, std::fabs(v));
    EXPECT_NEAR(20.0 * std::log10(peak), dbfs, 0.01) << name;
  }
  int files = 0;
  for (auto& e : std::filesystem::directory_iterator(dir.path)) files += e.is_regular_file();
  EXPECT_EQ(files, 2);  // out.wav, out.flac: no first-pass file left
}

}  // namespace earshot
