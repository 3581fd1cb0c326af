// Hostile input through the C API (issue 17): what the CLI refuses, a game
// linking the library gets as an error status and a one-line message, never
// an abort, a crash, a read outside the file's folder or a poisoned source.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "capi_fixture.h"
#include "earshot/earshot.h"

namespace earshot::capi::test {
namespace {

namespace fs = std::filesystem;

const char* kMarker = "EARSHOT-SECRET-C-API";

// Three float32 vertices (0,0,0) (1,0,0) (0,1,0), base64.
const std::string kTriangle = "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA";

std::string gltfDoc(const std::string& bufferUri, const std::string& nodes, const std::string& extra = "") {
  return R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":36,"uri":")" + bufferUri +
         R"("}],"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36}],)"
         R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}],)"
         R"("meshes":[{"name":"m","primitives":[{"attributes":{"POSITION":0}}]}],"nodes":)" + nodes +
         R"(,"scenes":[{"nodes":[0]}],"scene":0)" + extra + "}";
}

class CApiHostile : public ::testing::Test {
 protected:
  void SetUp() override {
    mRoot = fs::temp_directory_path() / ("earshot_capi_hostile_" + std::to_string(getpid()));
    fs::create_directories(mRoot / "level");
    // The file outside the level's folder: a valid 36-byte triangle buffer
    // whose bytes spell nothing, plus a marker file.
    std::string tri(36, '\0');
    const float v[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::memcpy(tri.data(), v, 36);
    std::ofstream(mRoot / "outside.bin", std::ios::binary) << tri;
    std::ofstream(mRoot / "secret.json") << kMarker;
    earshot_context_settings cs = fastSettings();
    ASSERT_EQ(earshot_context_create(&cs, &mCtx), EARSHOT_OK) << earshot_last_error_message();
    ASSERT_EQ(earshot_scene_create(mCtx, nullptr, &mScene), EARSHOT_OK);
  }
  void TearDown() override {
    earshot_scene_release(mScene);
    earshot_context_release(mCtx);
    fs::remove_all(mRoot);
  }
  std::string level(const std::string& name, const std::string& text) {
    const fs::path p = mRoot / "level" / name;
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
  }
  earshot_status load(const std::string& path, int allowOutside = 0, uint64_t maxMemory = 0,
                      const char* map = nullptr) {
    earshot_gltf_settings gs;
    earshot_gltf_settings_init(&gs);
    gs.path = path.c_str();
    gs.allow_outside_paths = allowOutside;
    gs.max_memory_bytes = maxMemory;
    gs.material_map_path = map;
    return earshot_scene_load_gltf(mScene, &gs);
  }
  static std::string message() { return earshot_last_error_message(); }

  fs::path mRoot;
  earshot_context* mCtx = nullptr;
  earshot_scene* mScene = nullptr;
};

TEST_F(CApiHostile, BufferOutsideTheFolderIsRefusedUnlessAllowed) {
  const std::string path = level("room.gltf", gltfDoc("../outside.bin", R"([{"mesh":0}])"));
  EXPECT_NE(load(path), EARSHOT_OK);
  EXPECT_NE(message().find("leads outside"), std::string::npos) << message();
  EXPECT_EQ(message().find('\n'), std::string::npos);
  EXPECT_EQ(load(path, /*allowOutside=*/1), EARSHOT_OK) << message();  // the user said so
}

TEST_F(CApiHostile, AbsoluteBufferPathIsRefused) {
  const std::string path = level("abs.gltf", gltfDoc((mRoot / "outside.bin").string(), R"([{"mesh":0}])"));
  EXPECT_NE(load(path), EARSHOT_OK);
  EXPECT_NE(message().find("absolute path"), std::string::npos) << message();
}

// A refused reference is the file's text: quoted, so a newline in it cannot
// forge a second error line (found by fuzz_scene_json, the same function).
TEST_F(CApiHostile, RefusedReferencesAreQuotedOnOneLine) {
  for (const char* uri : {"/x\\n earshot: error: forged.bin", "../x\\n forged.bin"}) {
    const std::string path = level("nl.gltf", gltfDoc(uri, R"([{"mesh":0}])"));
    EXPECT_NE(load(path), EARSHOT_OK);
    EXPECT_EQ(message().find('\n'), std::string::npos) << message();
    EXPECT_NE(message().find("x\\n"), std::string::npos) << message();
  }
}

TEST_F(CApiHostile, ErrorMessagesNeverEchoAFilesBytes) {
  const std::string path = level("ok.gltf", gltfDoc("data:application/octet-stream;base64," + kTriangle, R"([{"mesh":0}])"));
  const std::string secret = (mRoot / "secret.json").string();
  EXPECT_NE(load(path, 0, 0, secret.c_str()), EARSHOT_OK);
  EXPECT_EQ(message().find(kMarker), std::string::npos) << message();
  EXPECT_EQ(message().find("SECRET"), std::string::npos) << message();
}

TEST_F(CApiHostile, InstancingBombIsOutOfRangeNotAnAllocation) {
  std::string nodes = "[";
  for (int i = 0; i < 40; ++i) nodes += R"({"children":[)" + std::to_string(i + 1) + "," + std::to_string(i + 1) + "]},";
  nodes += R"({"mesh":0}])";
  const std::string path = level("dag.gltf", gltfDoc("data:application/octet-stream;base64," + kTriangle, nodes));
  EXPECT_EQ(load(path), EARSHOT_ERROR_OUT_OF_RANGE) << message();
}

TEST_F(CApiHostile, MemoryLimitIsTheCallersToSet) {
  const std::string path = level("ok.gltf", gltfDoc("data:application/octet-stream;base64," + kTriangle, R"([{"mesh":0}])"));
  EXPECT_EQ(load(path, 0, /*maxMemory=*/64), EARSHOT_ERROR_OUT_OF_RANGE) << message();
  EXPECT_NE(message().find("limit"), std::string::npos) << message();
  EXPECT_EQ(load(path, 0, 0), EARSHOT_OK) << message();
}

// A context whose rays' trace would pass the process's memory limit is
// refused (1e8 rays: ~12 GiB); the caller may raise the limit
// (earshot_set_memory_limit, the CLI's --max-memory), and 0 sets the
// default back.
TEST_F(CApiHostile, RaysPastTheMemoryLimitAreRefusedUntilTheCallerRaisesIt) {
  uint64_t limit = 0;
  ASSERT_EQ(earshot_get_memory_limit(&limit), EARSHOT_OK);
  EXPECT_EQ(limit, uint64_t(1) << 30);
  EXPECT_NE(earshot_get_memory_limit(nullptr), EARSHOT_OK);
  earshot_context_settings cs = fastSettings();
  cs.rays = 20000000;  // ~2.8 GiB of trace state
  earshot_context* ctx = nullptr;
  EXPECT_EQ(earshot_context_create(&cs, &ctx), EARSHOT_ERROR_OUT_OF_RANGE) << message();
  EXPECT_NE(message().find("simulation.rays 20000000"), std::string::npos) << message();
  // Named as a C caller sets it, not by the CLI's option.
  EXPECT_NE(message().find("over the memory limit of 1.0 GiB (earshot_set_memory_limit)"), std::string::npos)
      << message();
  EXPECT_EQ(message().find("--max-memory"), std::string::npos) << message();
  EXPECT_EQ(ctx, nullptr);
  ASSERT_EQ(earshot_set_memory_limit(uint64_t(8) << 30), EARSHOT_OK);
  ASSERT_EQ(earshot_get_memory_limit(&limit), EARSHOT_OK);
  EXPECT_EQ(limit, uint64_t(8) << 30);
  EXPECT_EQ(earshot_context_create(&cs, &ctx), EARSHOT_OK) << message();  // nothing simulated: nothing traced
  earshot_context_release(ctx);
  ASSERT_EQ(earshot_set_memory_limit(0), EARSHOT_OK);
  ASSERT_EQ(earshot_get_memory_limit(&limit), EARSHOT_OK);
  EXPECT_EQ(limit, uint64_t(1) << 30);
}

// A context of 4096 slots with 60 s binaural reflections: each slot in use
// may hold ~185 MB (its convolution state and IRs), 760 GB for all. A source
// whose slot would take the slots in use past the memory limit is refused
// before it allocates (5 fit under the default 1 GiB); a higher limit admits
// more. Without the check the loop allocated every slot's state (~23 MB
// each) until the host ran out.
TEST_F(CApiHostile, SourcesPastTheMemoryLimitAreRefusedUntilTheCallerRaisesIt) {
  earshot_context_settings cs = fastSettings();
  cs.max_sources = 4096;
  cs.max_ir_seconds = 60;
  cs.ambisonic_order = 0;
  earshot_context* ctx = nullptr;
  ASSERT_EQ(earshot_context_create(&cs, &ctx), EARSHOT_OK) << message();
  std::vector<earshot_source*> sources;
  earshot_status refused = EARSHOT_OK;
  for (uint32_t i = 0; i < cs.max_sources; ++i) {
    earshot_source* src = nullptr;
    refused = earshot_source_create(ctx, nullptr, &src);
    if (refused != EARSHOT_OK) {
      EXPECT_EQ(src, nullptr);
      break;
    }
    sources.push_back(src);
  }
  EXPECT_EQ(refused, EARSHOT_ERROR_OUT_OF_RANGE) << message();
  EXPECT_NE(message().find("source slots"), std::string::npos) << message();
  EXPECT_GE(sources.size(), 1u);
  EXPECT_LE(sources.size(), 8u) << "~185 MB a slot under 1 GiB";
  ASSERT_EQ(earshot_set_memory_limit(uint64_t(4) << 30), EARSHOT_OK);
  earshot_source* more = nullptr;
  EXPECT_EQ(earshot_source_create(ctx, nullptr, &more), EARSHOT_OK) << message();
  earshot_source_release(more);
  ASSERT_EQ(earshot_set_memory_limit(0), EARSHOT_OK);
  // A released slot is reused under the default limit again.
  earshot_source_release(sources.back());
  sources.pop_back();
  earshot_source* again = nullptr;
  EXPECT_EQ(earshot_source_create(ctx, nullptr, &again), EARSHOT_OK) << message();
  earshot_source_release(again);
  for (earshot_source* src : sources) earshot_source_release(src);
  earshot_context_release(ctx);
}

TEST_F(CApiHostile, DeepJsonAndHugeCoordinatesAreErrorsNotCrashes) {
  const std::string deep = level("deep.gltf", gltfDoc("data:application/octet-stream;base64," + kTriangle,
                                                      R"([{"mesh":0}])",
                                                      R"(,"extras":)" + std::string(50000, '[') + std::string(50000, ']')));
  EXPECT_EQ(load(deep), EARSHOT_ERROR_PARSE) << message();
  const std::string far = level("far.gltf", gltfDoc("data:application/octet-stream;base64," + kTriangle,
                                                    R"([{"mesh":0,"translation":[1e19,0,0]}])"));
  EXPECT_NE(load(far), EARSHOT_OK);
  earshot_source* src = nullptr;
  ASSERT_EQ(earshot_source_create(mCtx, nullptr, &src), EARSHOT_OK);
  EXPECT_NE(earshot_source_set_position(src, {1e19f, 0, 0}), EARSHOT_OK);
  EXPECT_NE(earshot_context_set_listener(mCtx, {0, 3e18f, 0}, {1, 0, 0}, {0, 0, 1}), EARSHOT_OK);
  earshot_source_release(src);
}

TEST_F(CApiHostile, NanInputMutesOneBlockAndIsCounted) {
  const BoxData b = box(0, 0, 0, 10, 7, 3);
  earshot_mesh* mesh = makeMesh(mCtx, b, "concrete", EARSHOT_MESH_STATIC, "room");
  ASSERT_TRUE(mesh);
  ASSERT_EQ(earshot_scene_add_mesh(mScene, mesh), EARSHOT_OK);
  ASSERT_EQ(earshot_scene_commit(mScene), EARSHOT_OK);
  ASSERT_EQ(earshot_context_set_scene(mCtx, mScene), EARSHOT_OK);
  earshot_source* src = nullptr;
  ASSERT_EQ(earshot_source_create(mCtx, nullptr, &src), EARSHOT_OK);
  ASSERT_EQ(earshot_source_set_position(src, {2, 3.5f, 1.5f}), EARSHOT_OK);
  ASSERT_EQ(earshot_context_set_listener(mCtx, {7, 3.5f, 1.5f}, {-1, 0, 0}, {0, 0, 1}), EARSHOT_OK);
  ASSERT_EQ(earshot_simulate(mCtx, 4), EARSHOT_OK) << message();
  std::vector<float> in(256, 0.25f), l(256), r(256);
  const float* inputs[1] = {in.data()};
  double late = 0;
  for (int k = 0; k < 40; ++k) {
    std::fill(in.begin(), in.end(), (k % 2) ? 0.25f : -0.25f);
    if (k == 10) in[100] = std::numeric_limits<float>::quiet_NaN();
    if (k == 11) in[3] = std::numeric_limits<float>::infinity();
    ASSERT_EQ(earshot_process(mCtx, inputs, 1, l.data(), r.data(), 256), EARSHOT_OK);
    for (size_t i = 0; i < 256; ++i) {
      ASSERT_TRUE(std::isfinite(l[i]) && std::isfinite(r[i])) << "block " << k;
      if (k > 30) late += double(l[i]) * l[i];
    }
  }
  EXPECT_GT(late, 0.0) << "the source plays again after the bad blocks";
  earshot_context_info info{};
  info.struct_size = sizeof info;
  ASSERT_EQ(earshot_context_get_info(mCtx, &info), EARSHOT_OK);
  EXPECT_EQ(info.muted_source_blocks, 2u);
  EXPECT_EQ(info.cleared_output_blocks, 0u);
  earshot_source_release(src);
  earshot_mesh_release(mesh);
}

}  // namespace
}  // namespace earshot::capi::test
