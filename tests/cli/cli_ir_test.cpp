#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli_test_util.h"
#include "earshot/core/bands.h"
#include "earshot/io/disk_cache.h"
#include "earshot/io/wav.h"
#include "earshot/propagation/reflection_tracer.h"

namespace earshot {
namespace {
using testing::readFile;
using testing::runEarshot;
using testing::TempDir;
namespace fs = std::filesystem;

const std::string kShoebox = std::string(EARSHOT_SOURCE_DIR) + "/samples/shoebox/shoebox.gltf";
const std::string kShoeboxMap = std::string(EARSHOT_SOURCE_DIR) + "/samples/shoebox/materials_map.json";

int countFiles(const fs::path& dir) {
  int n = 0;
  for (auto& e : fs::directory_iterator(dir)) n += e.is_regular_file();
  return n;
}
}  // namespace

TEST(CliIr, FreeFieldDirectSoundIsOneOverRAtRoverC) {
  TempDir dir("cli_free");
  auto r = runEarshot("ir --source 0,0,-3.43 --listener 0,0,0 --receiver omni --air off -o " + dir / "ir.wav");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  auto ir = readAudioFile(dir / "ir.wav");
  ASSERT_TRUE(ir.isOk()) << ir.status().message();
  ASSERT_EQ(ir->channelCount(), 1u);
  const auto& x = ir->channels[0];
  EXPECT_NEAR(x[480], 1.0 / 3.43, 1e-4);  // 3.43 m / 343 m/s * 48 kHz = 480 samples exactly
}

// A source on the listener is valid (the direct sound's 1/r is clamped at
// 0.1 m) but rarely meant: a warning says so, and the clamp holds.
TEST(CliIr, ASourceOnTheListenerIsWarnedAboutAndClamped) {
  TempDir dir("cli_coincident");
  auto r = runEarshot("ir --source 0,0,0.05 --listener 0,0,0 --receiver omni --air off -o " + dir / "ir.wav --json " +
                      dir / "s.json");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("warning: source and listener are 0.05 m apart"), std::string::npos) << r.output;
  const auto s = nlohmann::json::parse(readFile(dir / "s.json"));
  EXPECT_NE(s["warnings"].dump().find("clamped at 0.1 m"), std::string::npos) << s["warnings"].dump();
  auto ir = readAudioFile(dir / "ir.wav");
  ASSERT_TRUE(ir.isOk()) << ir.status().message();
  float peak = 0;
  for (float v : ir->channels[0]) peak = std::max(peak, std::abs(v));
  EXPECT_NEAR(peak, 10.0f, 0.05f);  // 1 / 0.1 m, not 1 / 0.05 m
  // 0.1 m apart: no warning.
  auto far = runEarshot("ir --source 0,0,0.1 --listener 0,0,0 --receiver omni -o " + dir / "far.wav");
  ASSERT_EQ(far.exitCode, 0) << far.output;
  EXPECT_EQ(far.output.find("apart"), std::string::npos) << far.output;
}

// A room that does not absorb rings past the automatic length's 30 s cap:
// the IR ends abruptly there, and a warning and --json say so.
TEST(CliIr, AnIrCutByTheAutomaticLengthsCapIsWarnedAbout) {
  TempDir dir("cli_capped");
  std::ofstream(dir / "m.json") << R"({"bands_hz": [125, 250, 500, 1000, 2000, 4000, 8000], "materials": )"
                                << R"({"default": {"absorption": [0, 0, 0, 0, 0, 0, 0], "scattering": 0.5}}})";
  const std::string common = "ir " + kShoebox + " --materials " + dir / "m.json" +
                             " --source 2,3.5,1.5 --listener 7,3.5,1.5 --receiver omni --quality draft --air off";
  auto r = runEarshot(common + " -o " + dir / "ir.wav --json " + dir / "s.json");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("warning: the reverberation had not decayed by 60 dB at 30 s"), std::string::npos)
      << r.output;
  const auto s = nlohmann::json::parse(readFile(dir / "s.json"));
  EXPECT_EQ(s["tail"]["length_capped_at_s"].get<double>(), 30.0);
  // At draft (8 bounces) too: kappa from the probes carries the tail on
  // past the trace's 4 s (it stopped there).
  EXPECT_NEAR(s["ir_seconds"].get<double>(), 30.0, 0.1);
  for (double kappa : s["tail"]["detections_per_energy_in_flight"]) EXPECT_GT(kappa, 0.0);
  // An explicit length is what was asked for: no warning.
  auto given = runEarshot(common + " --length 2 -o " + dir / "two.wav --json " + dir / "two.json");
  ASSERT_EQ(given.exitCode, 0) << given.output;
  EXPECT_EQ(given.output.find("had not decayed"), std::string::npos) << given.output;
  EXPECT_EQ(nlohmann::json::parse(readFile(dir / "two.json"))["tail"]["length_capped_at_s"].get<double>(), 0.0);
}

// Third octaves end to end (issue 20): `ir --bands third-octave` in the
// sample room with a materials file in third octaves that absorbs at 315 Hz
// only; --json reports 21 bands' traced decays and the three passes; the
// same IR for 1 and 2 threads; `analyze --bands third-octave` reads 21 bands
// and broadband; `compare --third-octaves` of the IR with itself passes.
TEST(CliIr, ThirdOctaveIrAnalyseAndCompare) {
  TempDir dir("cli_thirds");
  std::string bands, absorption;
  for (size_t j = 0; j < kThirdOctaveNominalHz.size(); ++j) {
    bands += (j ? "," : "") + std::to_string(int(kThirdOctaveNominalHz[j]));
    absorption += std::string(j ? "," : "") + (kThirdOctaveNominalHz[j] == 315 ? "0.6" : "0.05");
  }
  std::string materials = "{\"bands_hz\": [" + bands + "], \"materials\": {";
  for (const char* name : {"acoustic_ceiling_tile", "plaster", "carpet_thick", "gypsum_board", "wood_panel", "brick"})
    materials += std::string(name == std::string("acoustic_ceiling_tile") ? "" : ",") + "\"" + name +
                 "\": {\"absorption\": [" + absorption + "], \"scattering\": 0.3}";
  std::ofstream(dir / "m.json") << materials << "}}";
  const std::string common = "ir " + kShoebox + " --material-map " + kShoeboxMap + " --materials " + dir / "m.json" +
                             " --source 2,3.1,1.3 --listener 6.7,4.2,1.7 --receiver omni --rays 2000 --bands third-octave";
  auto a = runEarshot(common + " --threads 1 -o " + dir / "a.wav --json " + dir / "a.json");
  auto b = runEarshot(common + " --threads 2 -o " + dir / "b.wav");
  ASSERT_EQ(a.exitCode, 0) << a.output;
  ASSERT_EQ(b.exitCode, 0) << b.output;
  EXPECT_TRUE(readFile(dir / "a.wav") == readFile(dir / "b.wav")) << "WAVs differ between 1 and 2 threads";
  const auto stats = nlohmann::json::parse(readFile(dir / "a.json"));
  EXPECT_EQ(stats["bands"], "third-octave");
  const auto& t = stats["third_octave"];
  ASSERT_EQ(t["bands_hz"].size(), 21u);
  ASSERT_EQ(t["passes"].size(), 3u);
  EXPECT_EQ(t["passes"][0]["shift_octaves"].get<double>(), -1.0 / 3.0);
  auto wav = readAudioFile(dir / "a.wav");
  ASSERT_TRUE(wav.isOk());
  EXPECT_EQ(stats["ir_samples"].get<size_t>(), wav->frameCount());
  double traceMs = 0;
  for (const auto& p : t["passes"]) traceMs += p["time_ms"]["trace"].get<double>();
  EXPECT_DOUBLE_EQ(stats["time_ms"]["trace"].get<double>(), traceMs);
  EXPECT_TRUE(stats["time_ms"].contains("combine"));
  const auto& t20 = t["decay"]["t20_s"];
  ASSERT_EQ(t20.size(), 21u);
  // 315 Hz (index 5) decays several times faster than its neighbours.
  EXPECT_LT(3.0 * t20[5].get<double>(), t20[4].get<double>());
  EXPECT_LT(3.0 * t20[5].get<double>(), t20[6].get<double>());

  auto an = runEarshot("analyze --json --bands third-octave " + dir / "a.wav");
  ASSERT_EQ(an.exitCode, 0) << an.output;
  const auto j = nlohmann::json::parse(an.output);
  const auto& band = j["channels"][0]["bands"];
  ASSERT_EQ(band.size(), 22u);
  EXPECT_EQ(band[5]["band"], "315 Hz");
  EXPECT_EQ(band[21]["band"], "broadband");
  // (Not the absorbing band's decay: through third-octave filters it reads its
  // neighbours' slower energy, which the synthesis's crossovers put within
  // its -3 dB edges; ThirdOctave.OneAbsorbingThirdOctaveKeepsItsOwnDecay
  // measures it where it is alone.)
  for (size_t k = 0; k < 21; ++k) EXPECT_GT(band[k]["T20"].get<double>(), 0.0) << band[k]["band"];

  auto cmp = runEarshot("compare --third-octaves --bands 315,broadband " + dir / "a.wav " + dir / "b.wav");
  EXPECT_EQ(cmp.exitCode, 0) << cmp.output;
  EXPECT_NE(cmp.output.find("315 Hz"), std::string::npos) << cmp.output;
  auto bad = runEarshot("compare --third-octaves --bands 300 " + dir / "a.wav " + dir / "b.wav");
  EXPECT_NE(bad.exitCode, 0);
  EXPECT_NE(bad.output.find("third-octave band"), std::string::npos) << bad.output;
}

TEST(CliIr, SampleRoomGivesByteIdenticalIrsForOneAndTwoThreads) {
  TempDir dir("cli_threads");
  const std::string common = "ir " + kShoebox + " --material-map " + kShoeboxMap +
                             " --source 2,3.5,1.5 --listener 7,3.5,1.5 --receiver omni --rays 4000 --seed 5";
  auto a = runEarshot(common + " --threads 1 -o " + dir / "a.wav --json " + dir / "a.json");
  auto b = runEarshot(common + " --threads 2 -o " + dir / "b.wav");
  ASSERT_EQ(a.exitCode, 0) << a.output;
  ASSERT_EQ(b.exitCode, 0) << b.output;
  const std::string wa = readFile(dir / "a.wav"), wb = readFile(dir / "b.wav");
  EXPECT_GT(wa.size(), 10000u);
  EXPECT_TRUE(wa == wb) << "WAVs differ between 1 and 2 threads";
  const auto stats = nlohmann::json::parse(readFile(dir / "a.json"));
  EXPECT_EQ(stats["rays_traced"], 4000);
  EXPECT_EQ(stats["early_reflections"]["paths"], 62);  // a shoebox: order <= 3
  // The sample's gypsum and wood walls transmit a little: some rays leave,
  // and the escaped energy is reported per band.
  EXPECT_TRUE(stats["rays_escaped"].is_number());
  EXPECT_EQ(stats["energy_escaped_fraction"].size(), 7u);
  for (const char* stage : {"direct", "early_reflections", "trace", "tail", "synthesis"})
    EXPECT_GE(stats["time_ms"][stage].get<double>(), 0.0) << stage;
}

// The options that model only what the scene needs, end to end: in the
// convex sample room no occlusion test is made (and --json says so), and a
// loose convergence target stops the trace early and says how early.
TEST(CliIr, JsonSaysWhatWasSkippedAndWhy) {
  TempDir dir("cli_skipped");
  auto r = runEarshot("ir " + kShoebox + " --material-map " + kShoeboxMap +
                      " --source 2,3.5,1.5 --listener 7,3.5,1.5 --receiver omni --rays 32768 --converge 3 --tail-probes 256"
                      " -o " + dir / "ir.wav --json " + dir / "s.json");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const auto s = nlohmann::json::parse(readFile(dir / "s.json"));
  EXPECT_EQ(s["shadow_rays"], 0);
  EXPECT_GT(s["shadow_rays_skipped"].get<int64_t>(), 0);
  EXPECT_EQ(s["direct"]["occlusion_tested"], false);
  EXPECT_EQ(s["rays_requested"], 32768);
  EXPECT_LT(s["rays_traced"].get<int64_t>(), 32768);
  EXPECT_LE(s["estimated_error_db"].get<double>(), 3.0);
  EXPECT_EQ(s["settings"]["tail_probes"], 256);
  EXPECT_GT(s["tail_probe_segments"].get<int64_t>(), 0);
  std::string skipped;
  for (const auto& line : s["skipped"]) skipped += line.get<std::string>() + "\n";
  EXPECT_NE(skipped.find("convex around the listener"), std::string::npos) << skipped;
  EXPECT_NE(skipped.find("not traced, the histogram had converged"), std::string::npos) << skipped;
  EXPECT_EQ(s["flutter_cone_rays"], 0);  // rounds must each cover the sphere alike
}

// --trace shared (issue 16): rays from the listener, the source detecting;
// --json names the trace and what it skipped around the source; with
// --converge (a per-source option) it is a clear error and writes nothing.
TEST(CliIr, SharedTraceIsReportedAndRefusesConvergence) {
  TempDir dir("cli_shared_trace");
  auto r = runEarshot("ir " + kShoebox + " --material-map " + kShoeboxMap +
                      " --source 2,3.5,1.5 --listener 7,3.5,1.5 --receiver omni --rays 4096 --trace shared -o " +
                      dir / "ir.wav --json " + dir / "s.json");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const auto s = nlohmann::json::parse(readFile(dir / "s.json"));
  EXPECT_EQ(s["trace"], "shared");
  std::string skipped;
  for (const auto& line : s["skipped"]) skipped += line.get<std::string>() + "\n";
  EXPECT_NE(skipped.find("convex around the source"), std::string::npos) << skipped;
  auto bad = runEarshot("ir " + kShoebox + " --material-map " + kShoeboxMap +
                        " --source 2,3.5,1.5 --listener 7,3.5,1.5 --trace shared --converge 1 -o " + dir / "bad.wav");
  EXPECT_EQ(bad.exitCode, 2);
  EXPECT_NE(bad.output.find("--converge works with --trace per-source only"), std::string::npos) << bad.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.wav"));
  // The shared trace's shadow-ray roulette: reported, not played where no
  // shadow ray is needed (the shoebox is convex), and refused per source.
  EXPECT_EQ(s["settings"]["shared_shadow_roulette"], ReflectionSettings{}.sharedShadowRoulette);
  EXPECT_GT(s["shadow_rays_skipped"].get<uint64_t>(), 0u);
  EXPECT_EQ(s["shadow_rays_rouletted"], 0);
  auto perSource = runEarshot("ir " + kShoebox + " --material-map " + kShoeboxMap +
                              " --source 2,3.5,1.5 --listener 7,3.5,1.5 --shadow-roulette 1 -o " + dir / "bad.wav");
  EXPECT_EQ(perSource.exitCode, 2);
  EXPECT_NE(perSource.output.find("--shadow-roulette applies to --trace shared only"), std::string::npos)
      << perSource.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.wav"));
}

// The sample shoebox's walls reflect enough for a flutter along its 10 m
// axis: 1/8 of the rays sample it, unless told not to.
// The cache folder (earshot/io/disk_cache.h): a one-shot `earshot ir`
// keeps the HRTF set and late noises it prepared there, and the next one
// reads them: bit for bit the same IR. Damaged entries are made again;
// "off" writes nothing; one process adds at most 8 noises; `earshot cache`
// lists and clears earshot's files only.
TEST(CliIr, CacheFolderGivesTheSameIrsAndSurvivesDamage) {
  namespace fs = std::filesystem;
  TempDir dir("cli_cache");
  const std::string cache = dir / "cache";
  const char* previous = std::getenv("EARSHOT_CACHE_DIR");
  const std::string saved = previous ? previous : "";
  setenv("EARSHOT_CACHE_DIR", cache.c_str(), 1);
  auto entries = [&](const std::string& prefix) {
    std::vector<fs::path> out;
    std::error_code ec;
    for (fs::directory_iterator it(cache, ec), end; !ec && it != end; it.increment(ec))
      if (it->path().filename().string().rfind(prefix, 0) == 0) out.push_back(it->path());
    return out;
  };
  // A user's HRTF file (the shipped set's bytes at another path): the
  // shipped file itself comes prepared with earshot and writes no entry
  // (HrtfCache.TheShippedSetIsReadPreparedOnAFirstRun).
  const std::string userHrtf = dir / "user.sofa";
  fs::copy_file(std::string(EARSHOT_SOURCE_DIR) + "/hrtf/FHK_HRIR_L2354.sofa", userHrtf);
  const std::string binaural = "--receiver binaural --hrtf " + userHrtf;
  const std::string common = "ir " + kShoebox + " --material-map " + kShoeboxMap +
                             " --source 2,3.5,1.5 --listener 7,3.5,1.5 --quality draft --seed 41 ";
  auto run = [&](const std::string& extra, const std::string& out) {
    auto r = runEarshot(common + extra + " -o " + dir / out);
    EXPECT_EQ(r.exitCode, 0) << r.output;
    return readFile(dir / out);
  };
  const std::string fresh = run(binaural, "a.wav");
  ASSERT_FALSE(fresh.empty());
  EXPECT_EQ(entries("hrtf-").size(), 1u);
  const auto noises = entries("noise-");
  EXPECT_GE(noises.size(), 1u);
  EXPECT_EQ(run(binaural, "b.wav"), fresh);
  // Damage every noise entry (one byte in the samples): made again, the
  // same IR, the entries rewritten whole.
  std::vector<std::string> original;
  for (const auto& e : noises) {
    original.push_back(readFile(e));
    std::fstream f(e, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(std::streamoff(original.back().size() / 2));
    f.write("\x7f\x7f", 2);
    f.close();
    EXPECT_NE(readFile(e), original.back());
  }
  EXPECT_EQ(run(binaural, "c.wav"), fresh);
  for (size_t i = 0; i < noises.size(); ++i) EXPECT_TRUE(readFile(noises[i]) == original[i]) << noises[i];
  EXPECT_EQ(run(binaural, "d.wav"), fresh);
  // A short order-3 ambisonic IR reads 16 noises (one per channel): at
  // most 8 are written. A long one reads one, W's, for every channel.
  const size_t before = entries("noise-").size();
  const std::string amb = run("--receiver ambisonic --order 3 --length 0.3", "e.wav");
  EXPECT_EQ(entries("noise-").size(), before + 8);
  EXPECT_EQ(run("--receiver ambisonic --order 3 --length 0.3", "f.wav"), amb);
  // (The folder keeps the newest 16 noises: count the new names.)
  const auto beforeLong = entries("noise-");
  const std::string ambLong = run("--receiver ambisonic --order 3 --length 1.5", "g.wav");
  size_t added = 0;
  for (const auto& e : entries("noise-"))
    added += std::find(beforeLong.begin(), beforeLong.end(), e) == beforeLong.end() ? 1 : 0;
  EXPECT_EQ(added, 1u);
  EXPECT_EQ(run("--receiver ambisonic --order 3 --length 1.5", "h.wav"), ambLong);
  // `earshot cache` says what is there; --clear removes earshot's files
  // (entries, an interrupted write's leftover) and nothing else.
  std::ofstream(cache + "/notes.txt") << "mine";
  const std::string partial = noises.front().string() + ".tmp-1-2";
  std::ofstream(partial) << "half";
  auto listing = runEarshot("cache");
  EXPECT_EQ(listing.exitCode, 0) << listing.output;
  // entries("noise-") counts the leftover too (it is named after its entry).
  EXPECT_NE(listing.output.find(cache + ": " + std::to_string(entries("noise-").size() + 1) + " files"),
            std::string::npos) << listing.output;
  EXPECT_NE(listing.output.find("hrtf     1,"), std::string::npos) << listing.output;
  EXPECT_NE(listing.output.find("partial  1,"), std::string::npos) << listing.output;
  auto cleared = runEarshot("cache --clear");
  EXPECT_EQ(cleared.exitCode, 0) << cleared.output;
  EXPECT_TRUE(entries("noise-").empty());
  EXPECT_TRUE(entries("hrtf-").empty());
  EXPECT_FALSE(fs::exists(partial));
  EXPECT_TRUE(fs::exists(cache + "/notes.txt"));
  // No cache: nothing written, the same IR.
  fs::remove_all(cache);
  setenv("EARSHOT_CACHE_DIR", "off", 1);
  EXPECT_EQ(run("--receiver binaural", "g.wav"), fresh);
  EXPECT_FALSE(fs::exists(cache));
  EXPECT_NE(runEarshot("cache").output.find("no cache folder"), std::string::npos);
  if (previous) setenv("EARSHOT_CACHE_DIR", saved.c_str(), 1);
  else unsetenv("EARSHOT_CACHE_DIR");
}

// A cache folder that cannot be one (a file, a device, a folder under a
// file) keeps nothing, and every run quietly prepares afresh: `earshot
// cache` says so instead of listing "0 files". (A folder not writable is
// said so too; as root, which the tests may run as, every folder is.)
TEST(CliCache, AFolderThatCannotHoldTheCacheIsWarnedAbout) {
  TempDir dir("cli_cache_unusable");
  const std::string file = dir / "a_file";
  std::ofstream(file) << "x";
  const char* previous = std::getenv("EARSHOT_CACHE_DIR");
  const std::string saved = previous ? previous : "";
  struct Case {
    std::string folder, why;
  };
  for (const Case& c : {Case{file, "it is not a folder"}, Case{"/dev/null", "it is not a folder"},
                        Case{file + "/sub/cache", "it cannot be made: " + file + " is not a folder"}}) {
    setenv("EARSHOT_CACHE_DIR", c.folder.c_str(), 1);
    auto r = runEarshot("cache");
    EXPECT_EQ(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find("warning: " + c.folder + ": " + c.why + ", so nothing new is kept there"), std::string::npos)
        << c.folder << ": " << r.output;
  }
  // A folder that can be made, or is there: no warning.
  for (const std::string& fine : {dir / "new/cache", dir.path.string()}) {
    setenv("EARSHOT_CACHE_DIR", fine.c_str(), 1);
    auto r = runEarshot("cache");
    EXPECT_EQ(r.exitCode, 0) << r.output;
    EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;
  }
  if (previous) setenv("EARSHOT_CACHE_DIR", saved.c_str(), 1);
  else unsetenv("EARSHOT_CACHE_DIR");
}

// A late-noise entry is checked beyond its checksum (anyone can compute
// one): a band louder than the noise-making could make it is a miss, made
// again and rewritten; a plausible one is read as it is.
TEST(CliIr, ACraftedNoiseEntryWithAValidChecksumIsMadeAgain) {
  namespace fs = std::filesystem;
  TempDir dir("cli_noise_craft");
  const std::string cache = dir / "cache";
  const char* previous = std::getenv("EARSHOT_CACHE_DIR");
  const std::string saved = previous ? previous : "";
  setenv("EARSHOT_CACHE_DIR", cache.c_str(), 1);
  const std::string cmd = "ir " + kShoebox + " --material-map " + kShoeboxMap +
                          " --source 2,3.5,1.5 --listener 7,3.5,1.5 --receiver omni --quality draft --seed 5 -o ";
  auto run = [&](const std::string& out) {
    auto r = runEarshot(cmd + dir / out);
    EXPECT_EQ(r.exitCode, 0) << r.output;
    return readFile(dir / out);
  };
  const std::string fresh = run("a.wav");
  std::vector<fs::path> noises;
  for (const auto& e : fs::directory_iterator(cache))
    if (e.path().filename().string().rfind("noise-", 0) == 0) noises.push_back(e.path());
  ASSERT_FALSE(noises.empty());
  std::vector<std::string> original, payload;
  for (const auto& e : noises) {
    original.push_back(readFile(e));
    const auto p = earshot::readCacheEntry(e.string(), original.back().size());
    ASSERT_TRUE(p) << e;
    payload.push_back(*p);
  }
  // Every sample times `gain` (the key is 72 bytes, the bands' floats
  // follow), written back with a valid checksum.
  auto craft = [&](float gain) {
    for (size_t i = 0; i < noises.size(); ++i) {
      std::string bytes = payload[i];
      for (size_t at = 72; at + 4 <= bytes.size(); at += 4) {
        float v;
        std::memcpy(&v, &bytes[at], 4);
        v *= gain;
        std::memcpy(&bytes[at], &v, 4);
      }
      ASSERT_TRUE(earshot::writeCacheEntry(cache, noises[i].filename().string(), bytes, "noise-", 1000));
    }
  };
  craft(1.01f);  // plausible: read, so the IR differs (the crafting works)
  EXPECT_FALSE(run("b.wav") == fresh) << "a plausible crafted entry was not read";
  craft(100.0f);  // 40 dB louder than the noise made, far past the bound: made again
  EXPECT_TRUE(run("c.wav") == fresh) << "the IR is not the one from the noise made";
  for (size_t i = 0; i < noises.size(); ++i) EXPECT_TRUE(readFile(noises[i]) == original[i]) << noises[i];
  if (previous) setenv("EARSHOT_CACHE_DIR", saved.c_str(), 1);
  else unsetenv("EARSHOT_CACHE_DIR");
}

TEST(CliIr, FlutterConesAreReportedAndCanBeTurnedOff) {
  TempDir dir("cli_flutter");
  for (const std::string flag : {"", " --no-flutter-cones"}) {
    auto r = runEarshot("ir " + kShoebox + " --material-map " + kShoeboxMap +
                        " --source 2,3.5,1.5 --listener 7,3.5,1.5 --receiver omni --rays 4096 --bounces 4" + flag +
                        " -o " + dir / "ir.wav --json " + dir / "s.json");
    ASSERT_EQ(r.exitCode, 0) << r.output;
    const auto s = nlohmann::json::parse(readFile(dir / "s.json"));
    EXPECT_EQ(s["settings"]["flutter_cones"], flag.empty());
    EXPECT_EQ(s["flutter_axes"], flag.empty() ? 1 : 0);
    EXPECT_EQ(s["flutter_cone_rays"], flag.empty() ? 512 : 0);
  }
}

struct BadInput {
  std::string name, args, expectInMessage;
  std::string fileName = {}, fileContent = {};  // an input file the case writes first
};

class CliIrBadInput : public ::testing::TestWithParam<BadInput> {};

TEST_P(CliIrBadInput, OneLineErrorNonZeroExitNoOutputFile) {
  TempDir dir("cli_bad_" + GetParam().name);
  if (!GetParam().fileName.empty()) std::ofstream(dir / GetParam().fileName) << GetParam().fileContent;
  std::string args = GetParam().args;
  for (size_t p; (p = args.find("@DIR@")) != std::string::npos;) args.replace(p, 5, dir.path.string());
  auto r = runEarshot("ir " + args + " -o " + dir / "out.wav");
  EXPECT_NE(r.exitCode, 0) << r.output;
  EXPECT_NE(r.exitCode, -1) << "crashed: " << r.output;
  EXPECT_NE(r.output.find(GetParam().expectInMessage), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("error"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "out.wav"));
  // Nothing but the inputs the test wrote.
  int inputs = 0;
  for (auto& e : fs::directory_iterator(dir.path)) inputs += e.path().filename() != "out.wav";
  EXPECT_EQ(countFiles(dir.path), inputs);
}

INSTANTIATE_TEST_SUITE_P(
    Errors, CliIrBadInput,
    ::testing::Values(
        BadInput{"nan", "--source nan,0,0 --listener 0,0,0", "not a finite number"},
        BadInput{"inf", "--source 1,0,0 --listener 0,inf,0", "not a finite number"},
        BadInput{"count", "--source 1,0 --listener 0,0,0", "expected X,Y,Z"},
        BadInput{"missing", "/nonexistent/room.gltf --source 1,0,0 --listener 0,0,0", "/nonexistent/room.gltf"},
        BadInput{"malformed", "@DIR@/bad.gltf --source 1,0,0 --listener 0,0,0", "bad.gltf", "bad.gltf",
                 "{ \"asset\": { \"version\": \"2.0\" }, \"meshes\": [ {"},
        BadInput{"materials", "--materials @DIR@/m.json --source 1,0,0 --listener 0,0,0",
                 "absorption[0] = 1.5 is outside [0, 1]", "m.json",
                 R"({"bands_hz": [125, 250, 500, 1000, 2000, 4000, 8000], "materials": {"x": )"
                 R"({"absorption": [1.5, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1], "scattering": 0.1}}})"},
        BadInput{"rays", "--rays 0 --source 1,0,0 --listener 0,0,0", "--rays"},
        BadInput{"converge", "--converge 25 --source 1,0,0 --listener 0,0,0", "--converge"},
        BadInput{"probes", "--tail-probes -1 --source 1,0,0 --listener 0,0,0", "--tail-probes"},
        BadInput{"thirds_shared", "--bands third-octave --receiver omni --trace shared --source 1,0,0 --listener 0,0,0",
                 "per-source"},
        BadInput{"bands", "--bands sixth --source 1,0,0 --listener 0,0,0", "--bands"}),
    [](const ::testing::TestParamInfo<BadInput>& i) { return i.param.name; });

}  // namespace earshot

namespace earshot {

// -o writes the format its extension names, or refuses it (issue 19).
TEST(CliIr, OutputFormatFollowsTheExtension) {
  TempDir dir("cli_formats");
  const std::string common = "ir --source 0,0,-3.43 --listener 0,0,0 --receiver omni --air off --length 0.1 -o ";
  for (const char* name : {"ir.wav", "ir.flac", "ir.ogg", "IR.FLAC", "noextension"}) {
    auto r = runEarshot(common + dir / name);
    ASSERT_EQ(r.exitCode, 0) << name << ": " << r.output;
  }
  EXPECT_EQ(readFile(dir / "ir.wav").substr(0, 4), "RIFF");
  EXPECT_EQ(readFile(dir / "noextension"), readFile(dir / "ir.wav"));  // --help: WAV for a name without one
  EXPECT_EQ(readFile(dir / "ir.flac").substr(0, 4), "fLaC");
  EXPECT_EQ(readFile(dir / "IR.FLAC").substr(0, 4), "fLaC");
  EXPECT_EQ(readFile(dir / "ir.ogg").substr(0, 4), "OggS");
  auto wav = readAudioFile(dir / "ir.wav");
  auto flac = readAudioFile(dir / "ir.flac");
  ASSERT_TRUE(wav.isOk() && flac.isOk());
  ASSERT_EQ(wav->frameCount(), flac->frameCount());
  for (size_t i = 0; i < wav->frameCount(); ++i)
    ASSERT_NEAR(wav->channels[0][i], flac->channels[0][i], 1.0 / (1 << 23)) << i;  // 24-bit

  // Unknown extensions are refused before any work, naming what is written.
  auto bad = runEarshot(common + dir / "ir.mp3");
  EXPECT_EQ(bad.exitCode, 2);
  EXPECT_NE(bad.output.find(".flac"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(dir / "ir.mp3"));

  // A source closer than 1 m peaks above full scale: float keeps it, FLAC
  // clips it and says so.
  const std::string close = "ir --source 0,0,-0.25 --listener 0,0,0 --receiver omni --air off --length 0.1 -o ";
  auto w = runEarshot(close + dir / "close.wav");
  ASSERT_EQ(w.exitCode, 0) << w.output;
  EXPECT_EQ(w.output.find("clipped"), std::string::npos) << w.output;
  auto f = runEarshot(close + dir / "close.flac --json " + dir / "close.json");
  ASSERT_EQ(f.exitCode, 0) << f.output;
  EXPECT_NE(f.output.find("clipped"), std::string::npos) << f.output;
  const auto stats = nlohmann::json::parse(readFile(dir / "close.json"));
  EXPECT_NE(stats["warnings"].dump().find("clipped"), std::string::npos);
}

}  // namespace earshot
