// Hostile sizes and non-finite values in the files earshot reads: a header or
// accessor that claims far more data than the file holds must be refused with
// an error naming the field, before anything of the claimed size is allocated.
//
// Memory is checked through getrusage()'s peak RSS (ru_maxrss, a high-water
// mark): each case allows kRssBudget of growth. The claimed sizes need >= 8 GB
// (1e12 vertices x 12 bytes, 2^40 frames x 4 bytes), the honest inputs need
// under 20 MB, so a 256 MB budget separates "refused" from "allocated" by a
// factor of 30 either way while staying independent of allocator slack.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "earshot/io/wav.h"
#include "earshot/materials/material.h"
#include "earshot/scene/gltf_loader.h"

namespace earshot {
namespace {

namespace fs = std::filesystem;

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define EARSHOT_EXTREMES_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define EARSHOT_EXTREMES_SANITIZED 1
#endif
#endif
#ifdef EARSHOT_EXTREMES_SANITIZED
// Sanitizers keep freed blocks in a quarantine (ASan: 256 MB by default) and
// pad every allocation, so honest parses of the ~8 MB texts below peak near
// 300 MB; 1 GiB is still 8x under the smallest claimed size.
constexpr long long kRssBudgetBytes = 1024ll << 20;
#else
constexpr long long kRssBudgetBytes = 256ll << 20;
#endif

long long peakRssBytes() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<long long>(u.ru_maxrss) * 1024;  // Linux: kilobytes
}

/** Peak-RSS growth across a scope. */
class RssWatch {
 public:
  RssWatch() : mStart(peakRssBytes()) {}
  long long growth() const { return peakRssBytes() - mStart; }

 private:
  long long mStart;
};

class HostileFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    mDir = fs::temp_directory_path() / ("earshot_extremes_" + std::to_string(getpid()));
    fs::create_directories(mDir);
  }
  void TearDown() override { fs::remove_all(mDir); }

  std::string write(const std::string& name, const std::string& bytes) {
    const std::string path = (mDir / name).string();
    std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path;
  }

  fs::path mDir;
};

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

/** Shows what the loader said, so the test log documents each refusal. */
template <class T>
void show(const Result<T>& r) {
  std::printf("    -> %s\n", r.isOk() ? "accepted" : r.status().message().c_str());
}

// ---------------------------------------------------------------- glTF

// Three float32 vertices (0,0,0) (1,0,0) (0,1,0) = 36 bytes, base64.
const char* kTriangleBase64 = "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA";

/** A one-triangle glTF with the given POSITION accessor fields, buffer-view
 *  length and buffer byteLength (all as JSON text). */
std::string gltfWith(const std::string& accessor, const std::string& viewLength = "36",
                     const std::string& bufferLength = "36", const std::string& node = R"({"mesh":0})") {
  return std::string(R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":)") + bufferLength +
         R"(,"uri":"data:application/octet-stream;base64,)" + kTriangleBase64 +
         R"("}],"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":)" + viewLength +
         R"(}],"accessors":[)" + accessor +
         R"(],"meshes":[{"name":"m","primitives":[{"attributes":{"POSITION":0}}]}],"nodes":[)" + node +
         R"(],"scenes":[{"nodes":[0]}],"scene":0})";
}

TEST_F(HostileFiles, GltfTriangleControlLoads) {
  // The template itself is valid, so the failures below are due to the one
  // hostile field each changes.
  const std::string path =
      write("ok.gltf", gltfWith(R"({"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"})"));
  auto r = loadGltf(path, defaultMaterials());
  show(r);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(r.value().mesh.triangleCount(), 1u);
}

TEST_F(HostileFiles, GltfAccessorClaiming1e12VerticesIsAnErrorNotAnAllocation) {
  const std::string path = write(
      "huge.gltf", gltfWith(R"({"bufferView":0,"componentType":5126,"count":1000000000000,"type":"VEC3"})"));
  RssWatch rss;
  auto r = loadGltf(path, defaultMaterials());
  show(r);
  ASSERT_FALSE(r.isOk());
  EXPECT_TRUE(contains(r.status().message(), path)) << r.status().message();
  EXPECT_TRUE(contains(r.status().message(), "accessor")) << r.status().message();
  EXPECT_LT(rss.growth(), kRssBudgetBytes);
}

TEST_F(HostileFiles, GltfBufferlessAccessorClaiming1e12VerticesIsAnError) {
  // No bufferView: glTF says the accessor is all zeros, so nothing in the
  // file bounds the count; the loader must cap it itself.
  const std::string path =
      write("bufferless.gltf", gltfWith(R"({"componentType":5126,"count":1000000000000,"type":"VEC3"})"));
  RssWatch rss;
  auto r = loadGltf(path, defaultMaterials());
  show(r);
  ASSERT_FALSE(r.isOk());
  EXPECT_TRUE(contains(r.status().message(), path)) << r.status().message();
  EXPECT_LT(rss.growth(), kRssBudgetBytes);
}

TEST_F(HostileFiles, GltfSparseAccessorClaiming1e12VerticesIsAnError) {
  // No bufferView but one sparse value: the count is bounded by nothing in
  // the file, so only the loader's own cap can refuse it.
  const std::string path = write(
      "sparse.gltf",
      gltfWith(R"({"componentType":5126,"count":1000000000000,"type":"VEC3","sparse":{"count":1,)"
               R"("indices":{"bufferView":0,"componentType":5125},"values":{"bufferView":0,"byteOffset":12}}})"));
  RssWatch rss;
  auto r = loadGltf(path, defaultMaterials());
  show(r);
  ASSERT_FALSE(r.isOk());
  EXPECT_TRUE(contains(r.status().message(), path)) << r.status().message();
  EXPECT_TRUE(contains(r.status().message(), "1000000000000")) << r.status().message();
  EXPECT_LT(rss.growth(), kRssBudgetBytes);
}

TEST_F(HostileFiles, GltfBufferClaiming1e12BytesIsAnError) {
  const std::string path = write("bigbuffer.gltf", gltfWith(R"({"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"})",
                                                            "1000000000000", "1000000000000"));
  RssWatch rss;
  auto r = loadGltf(path, defaultMaterials());
  show(r);
  ASSERT_FALSE(r.isOk());
  EXPECT_TRUE(contains(r.status().message(), path)) << r.status().message();
  EXPECT_LT(rss.growth(), kRssBudgetBytes);
}

TEST_F(HostileFiles, GltfOverflowingNumberIsAParseError) {
  // 1e999 is not a double: JSON parsers must refuse it, not turn it into inf.
  const std::string path = write("inf.gltf", gltfWith(R"({"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"})",
                                                      "36", "36", R"({"mesh":0,"translation":[1e999,0,0]})"));
  auto r = loadGltf(path, defaultMaterials());
  show(r);
  ASSERT_FALSE(r.isOk());
  EXPECT_TRUE(contains(r.status().message(), path)) << r.status().message();
}

// Found by fuzzing (tests/fuzz/found/README.md,
// gltf-float-overflow-after-transform.glb): the double-precision point was
// finite, Vec3f(w) +inf, and it was accepted.
TEST_F(HostileFiles, GltfFiniteTransformThatOverflowsToInfinityIsAnError) {
  // Each number is a finite double, but 1e300 * 1e300 overflows: the vertices
  // come out infinite and must be refused, naming the mesh.
  const std::string path =
      write("overflow.gltf", gltfWith(R"({"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"})", "36",
                                      "36", R"({"mesh":0,"scale":[1e300,1e300,1e300],"translation":[1e300,0,0]})"));
  auto r = loadGltf(path, defaultMaterials());
  show(r);
  ASSERT_FALSE(r.isOk());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument) << r.status().message();
  EXPECT_TRUE(contains(r.status().message(), "\"m\"") || contains(r.status().message(), "mesh"))
      << r.status().message();
}

// ---------------------------------------------------------------- WAV

std::string le16(uint16_t v) { return {char(v & 0xff), char(v >> 8)}; }
std::string le32(uint32_t v) { return le16(uint16_t(v & 0xffff)) + le16(uint16_t(v >> 16)); }
std::string le64(uint64_t v) { return le32(uint32_t(v & 0xffffffffu)) + le32(uint32_t(v >> 32)); }

/** 16-bit mono PCM fmt chunk body at 8 kHz. */
std::string fmtPcm16Mono() { return le16(1) + le16(1) + le32(8000) + le32(16000) + le16(2) + le16(16); }

/** An RF64 file whose ds64 chunk claims `frames` 16-bit mono frames while
 *  the data chunk holds only 16 real samples. */
std::string rf64Claiming(uint64_t frames) {
  const std::string samples(32, '\x01');
  const std::string ds64 = le64(0xffffffffull) + le64(frames * 2) + le64(frames) + le32(0);
  const std::string body = "WAVE" + std::string("ds64") + le32(uint32_t(ds64.size())) + ds64 + "fmt " + le32(16) +
                           fmtPcm16Mono() + "data" + le32(0xffffffffu) + samples;
  return "RF64" + le32(0xffffffffu) + body;
}

/** A plain WAV whose data chunk claims `dataBytes` but holds 16 samples. */
std::string wavClaiming(uint32_t dataBytes) {
  const std::string samples(32, '\x01');
  const std::string body = "WAVE" + std::string("fmt ") + le32(16) + fmtPcm16Mono() + "data" + le32(dataBytes) + samples;
  return "RIFF" + le32(uint32_t(body.size())) + body;
}

TEST_F(HostileFiles, Rf64HeaderClaiming2To40FramesIsRefusedWithoutAllocating) {
  const std::string path = write("huge.rf64.wav", rf64Claiming(uint64_t(1) << 40));
  RssWatch rss;
  auto r = readAudioFile(path);  // default limit: defaultMaxReadSamples()
  show(r);
  // libsndfile (1.2, Debian 12) trims the ds64 claim to the bytes present:
  // exactly the 16 real frames come back, never 2^40 frames' worth of memory.
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(r.value().frameCount(), 16u);
  EXPECT_LT(rss.growth(), kRssBudgetBytes);
}

TEST_F(HostileFiles, WavDataChunkClaiming4GBHoldsOnlyWhatIsThere) {
  // 0xFFFFFFF0 bytes = 2^31 - 8 frames: only the file's real length (or the
  // default sample limit) can stop an 8 GB float allocation.
  const std::string path = write("liar.wav", wavClaiming(0xfffffff0u));
  RssWatch rss;
  auto r = readAudioFile(path);
  show(r);
  // Trimmed to the file's length by libsndfile, as for RF64 above.
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(r.value().frameCount(), 16u);
  EXPECT_LT(rss.growth(), kRssBudgetBytes);
}

/** A header-only FLAC stream (STREAMINFO, no audio frames) claiming
 *  `totalFrames` mono 16-bit frames at 44.1 kHz: 42 bytes. */
std::string flacClaiming(uint64_t totalFrames) {
  const uint64_t packed = (uint64_t(44100) << 44) | (uint64_t(0) << 41) | (uint64_t(15) << 36) | totalFrames;
  std::string info = std::string("\x10\x00\x10\x00", 4) + std::string(6, '\0');  // block sizes, frame sizes
  for (int b = 7; b >= 0; --b) info += char((packed >> (8 * b)) & 0xff);
  info += std::string(16, '\0');  // MD5
  return "fLaC" + std::string("\x80\x00\x00\x22", 4) + info;
}

TEST_F(HostileFiles, FlacHeaderClaiming2To36FramesIsRefusedByName) {
  // FLAC's STREAMINFO count is not trimmed by libsndfile: the limit must act.
  const std::string path = write("huge.flac", flacClaiming((uint64_t(1) << 36) - 1));
  RssWatch rss;
  auto r = readAudioFile(path);
  show(r);
  ASSERT_FALSE(r.isOk());
  EXPECT_EQ(r.status().code(), StatusCode::kOutOfRange);
  EXPECT_TRUE(contains(r.status().message(), "68719476735 frames")) << r.status().message();
  EXPECT_LT(rss.growth(), kRssBudgetBytes);
}

// Found by fuzzing: this used to allocate 8 GiB (42 bytes of file claiming
// 2^31 - 1 frames, just under the limit of the time); the reader now grows
// its buffer with what it actually reads. See tests/fuzz/found/README.md.
TEST_F(HostileFiles, FlacHeaderClaiming2To31FramesDoesNotAllocateThem) {
  const std::string path = write("liar.flac", flacClaiming((uint64_t(1) << 31) - 1));
  RssWatch rss;
  auto r = readAudioFile(path);
  show(r);
  if (r.isOk()) {
    EXPECT_EQ(r.value().frameCount(), 0u);  // no audio frames in the file
  }
  EXPECT_LT(rss.growth(), kRssBudgetBytes);
}

TEST_F(HostileFiles, WavOverTheCallersSampleLimitNamesTheLimit) {
  const std::string path = write("ok.wav", wavClaiming(32));
  auto r = readAudioFile(path, 8);  // 16 samples present, 8 allowed
  show(r);
  ASSERT_FALSE(r.isOk());
  EXPECT_EQ(r.status().code(), StatusCode::kOutOfRange);
  EXPECT_TRUE(contains(r.status().message(), "16 frames")) << r.status().message();
  EXPECT_TRUE(contains(r.status().message(), "limit of 8")) << r.status().message();
}

// ---------------------------------------------------------------- materials

TEST_F(HostileFiles, MillionElementBandArrayAgainstSevenBandsIsAnError) {
  std::string absorption = "[0.1";
  absorption.reserve(4 * 1000000);
  for (int i = 1; i < 1000000; ++i) absorption += ",0.1";
  absorption += "]";
  const std::string text = R"({"bands_hz":[125,250,500,1000,2000,4000,8000],"materials":{"big":{"absorption":)" +
                           absorption + "}}}";
  RssWatch rss;
  auto r = parseMaterials(text, "big.json");
  show(r);
  ASSERT_FALSE(r.isOk());
  EXPECT_TRUE(contains(r.status().message(), "big.json")) << r.status().message();
  EXPECT_TRUE(contains(r.status().message(), "1000000")) << r.status().message();
  EXPECT_LT(rss.growth(), kRssBudgetBytes);
}

TEST_F(HostileFiles, MillionBandsHzIsRefusedOrBounded) {
  // A million ascending centre frequencies with matching absorption: a
  // legal-looking but absurd file. It must not blow up memory or time beyond
  // proportion; if accepted, the engine's 7 bands stay in [0, 1].
  std::string hz = "[1", abs = "[0.1";
  for (int i = 2; i <= 1000000; ++i) {
    hz += "," + std::to_string(i);
    abs += ",0.1";
  }
  hz += "]";
  abs += "]";
  const std::string text = R"({"bands_hz":)" + hz + R"(,"materials":{"big":{"absorption":)" + abs + "}}}";
  RssWatch rss;
  auto r = parseMaterials(text, "bands.json");
  show(r);
  if (r.isOk()) {
    const auto id = r.value().find("big");
    ASSERT_TRUE(id.has_value());
    for (float a : r.value()[*id].absorption) EXPECT_NEAR(a, 0.1f, 1e-6f);  // flat input stays flat
  } else {
    EXPECT_TRUE(contains(r.status().message(), "bands.json")) << r.status().message();
  }
  EXPECT_LT(rss.growth(), kRssBudgetBytes);
}

TEST_F(HostileFiles, NaNAsStringAndOverflowAreErrorsNamingTheField) {
  const std::string bands = R"({"bands_hz":[125,250,500,1000,2000,4000,8000],"materials":{"w":{"absorption":)";
  {
    auto r = parseMaterials(bands + R"([0.1,0.1,"NaN",0.1,0.1,0.1,0.1]}}})", "nan.json");
    show(r);
    ASSERT_FALSE(r.isOk());
    EXPECT_TRUE(contains(r.status().message(), "nan.json")) << r.status().message();
    EXPECT_TRUE(contains(r.status().message(), "absorption[2]")) << r.status().message();
  }
  {
    auto r = parseMaterials(bands + R"([0.1,0.1,1e999,0.1,0.1,0.1,0.1]}}})", "inf.json");
    show(r);
    ASSERT_FALSE(r.isOk());
    EXPECT_TRUE(contains(r.status().message(), "inf.json")) << r.status().message();
  }
  {
    auto r = parseMaterials(bands + R"([0.1,0.1,NaN,0.1,0.1,0.1,0.1]}}})", "bare.json");
    show(r);
    ASSERT_FALSE(r.isOk());
    EXPECT_EQ(r.status().code(), StatusCode::kParseError);
    EXPECT_TRUE(contains(r.status().message(), "bare.json")) << r.status().message();
  }
  {
    auto r = parseMaterials(R"({"bands_hz":[125,"NaN"],"materials":{}})", "hz.json");
    show(r);
    ASSERT_FALSE(r.isOk());
    EXPECT_TRUE(contains(r.status().message(), "bands_hz[1]")) << r.status().message();
  }
}

TEST_F(HostileFiles, TenThousandMaterialsStayProportional) {
  // 1e7 materials would be a ~300 MB text (too slow for a unit test), and
  // MaterialTable::add looks names up linearly, so n materials cost n^2/2
  // name compares (see issue 8 report); 1e4 keeps this test fast and shows
  // memory stays linear in the input: ~0.3 MB text, well inside the budget.
  std::string text = R"({"bands_hz":[1000],"materials":{)";
  for (int i = 0; i < 10000; ++i) {
    if (i) text += ",";
    text += "\"m" + std::to_string(i) + R"(":{"absorption":[0.5]})";
  }
  text += "}}";
  RssWatch rss;
  auto r = parseMaterials(text, "many.json");
  show(r);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(r.value().size(), 10001u);  // + built-in default at id 0
  EXPECT_LT(rss.growth(), kRssBudgetBytes);
}

}  // namespace
}  // namespace earshot
