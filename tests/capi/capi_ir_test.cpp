// IR access through the C API: a source's latest IR and IRs computed on
// demand equal `earshot ir`'s for the same inputs (issue 19), and the
// handles' errors.
#include <gtest/gtest.h>

#include <malloc.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "capi_fixture.h"
#include "earshot/earshot.h"
#include "earshot/earshot.hpp"
#include "earshot/io/wav.h"

namespace {

const std::string kShoebox = std::string(EARSHOT_SOURCE_DIR) + "/samples/shoebox/shoebox.gltf";
const std::string kShoeboxMap = std::string(EARSHOT_SOURCE_DIR) + "/samples/shoebox/materials_map.json";

/** `earshot ir` in the shoebox: source (2, 3.5, 1.5), listener (7, 3.5, 1.5)
 *  facing -x with +z up, balanced defaults, seed `seed`. */
earshot::AudioBuffer cliIr(const std::string& receiver, int seed, const std::string& extra = "") {
  const auto dir = std::filesystem::temp_directory_path() / ("earshot_capi_ir_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string out = (dir / (receiver + ".wav")).string();
  const std::string cmd = std::string(EARSHOT_CLI) + " ir " + kShoebox + " --material-map " + kShoeboxMap +
                          " --source 2,3.5,1.5 --listener 7,3.5,1.5 --forward -1,0,0 --up 0,0,1 --receiver " +
                          receiver + extra + " --seed " + std::to_string(seed) + " -o " + out + " 2>/dev/null";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  auto r = earshot::readAudioFile(out);
  EXPECT_TRUE(r.isOk()) << r.status().message();
  std::filesystem::remove_all(dir);
  return r.isOk() ? *r : earshot::AudioBuffer{};
}

struct Shoebox {
  earshot_context* context = nullptr;
  earshot_scene* scene = nullptr;

  explicit Shoebox(uint64_t seed = 1, uint32_t ambisonicOrder = 0, earshot_trace_mode trace = EARSHOT_TRACE_AUTO,
                   double maxIrSeconds = 3.0) {
    earshot_context_settings cs;
    earshot_context_settings_init(&cs);  // the balanced defaults, as `earshot ir`
    cs.max_sources = 2;
    cs.max_ir_seconds = maxIrSeconds;
    cs.seed = seed;
    cs.trace_mode = trace;
    cs.ambisonic_order = ambisonicOrder;  // 0: binaural source IRs, as `earshot ir --receiver binaural`
    EXPECT_EQ(earshot_context_create(&cs, &context), EARSHOT_OK) << earshot_last_error_message();
    EXPECT_EQ(earshot_scene_create(context, nullptr, &scene), EARSHOT_OK);
    earshot_gltf_settings gs;
    earshot_gltf_settings_init(&gs);
    gs.path = kShoebox.c_str();
    gs.material_map_path = kShoeboxMap.c_str();
    EXPECT_EQ(earshot_scene_load_gltf(scene, &gs), EARSHOT_OK) << earshot_last_error_message();
    EXPECT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
    EXPECT_EQ(earshot_context_set_scene(context, scene), EARSHOT_OK);
    EXPECT_EQ(earshot_context_set_listener(context, {7, 3.5f, 1.5f}, {-1, 0, 0}, {0, 0, 1}), EARSHOT_OK);
  }
  ~Shoebox() {
    earshot_scene_release(scene);
    earshot_context_release(context);
  }
};

earshot::AudioBuffer copyOut(earshot_ir* ir) {
  earshot_ir_info info;
  info.struct_size = sizeof(info);
  EXPECT_EQ(earshot_ir_get_info(ir, &info), EARSHOT_OK);
  earshot::AudioBuffer b(info.channels, size_t(info.frames), info.sample_rate_hz);
  for (uint32_t c = 0; c < info.channels; ++c)
    EXPECT_EQ(earshot_ir_copy_channel(ir, c, b.channels[c].data(), info.frames), EARSHOT_OK);
  return b;
}

void expectSame(const earshot::AudioBuffer& a, const earshot::AudioBuffer& b) {
  ASSERT_EQ(a.channelCount(), b.channelCount());
  ASSERT_EQ(a.frameCount(), b.frameCount());
  EXPECT_EQ(a.sampleRateHz, b.sampleRateHz);
  for (size_t c = 0; c < a.channelCount(); ++c) EXPECT_EQ(a.channels[c], b.channels[c]) << "channel " << c;
}

TEST(CapiIr, SourceIrIsEarshotIrsForAStaticSource) {
  Shoebox box;
  earshot_source_settings ss;
  earshot_source_settings_init(&ss);
  ss.direct = EARSHOT_DIRECT_IN_IMPULSE_RESPONSE;
  earshot_source* src = nullptr;
  ASSERT_EQ(earshot_source_create(box.context, &ss, &src), EARSHOT_OK);
  ASSERT_EQ(earshot_source_set_position(src, {2, 3.5f, 1.5f}), EARSHOT_OK);
  earshot_ir* ir = nullptr;
  EXPECT_EQ(earshot_source_get_ir(src, &ir), EARSHOT_ERROR_NOT_FOUND);  // not simulated yet
  EXPECT_EQ(ir, nullptr);
  ASSERT_EQ(earshot_simulate(box.context, 0), EARSHOT_OK);
  ASSERT_EQ(earshot_source_get_ir(src, &ir), EARSHOT_OK) << earshot_last_error_message();
  earshot_ir_info info;
  info.struct_size = sizeof(info);
  ASSERT_EQ(earshot_ir_get_info(ir, &info), EARSHOT_OK);
  EXPECT_EQ(info.channels, 2u);
  EXPECT_EQ(info.includes_direct, 1u);
  EXPECT_EQ(info.simulation, 1u);
  EXPECT_EQ(info.sample_rate_hz, 48000.0);
  // The context's default trace (auto) traces one source from itself.
  expectSame(copyOut(ir), cliIr("binaural", 1));

  // The handle keeps its IR: a later simulation and the source's release do
  // not change it.
  const earshot::AudioBuffer before = copyOut(ir);
  ASSERT_EQ(earshot_source_set_position(src, {3, 3.5f, 1.5f}), EARSHOT_OK);
  ASSERT_EQ(earshot_simulate(box.context, 0), EARSHOT_OK);
  earshot_ir* second = nullptr;
  ASSERT_EQ(earshot_source_get_ir(src, &second), EARSHOT_OK);
  ASSERT_EQ(earshot_ir_get_info(second, &info), EARSHOT_OK);
  EXPECT_EQ(info.simulation, 2u);
  EXPECT_NE(copyOut(second).channels[0], before.channels[0]);
  earshot_source_release(src);
  expectSame(copyOut(ir), before);
  earshot_ir_release(second);
  earshot_ir_release(ir);
}

// trace_mode selects the trace: the context's IR is `earshot ir --trace`'s
// of that mode; the info reports the mode; a value that is no
// earshot_trace_mode is refused.
TEST(CapiIr, TraceModeSelectsTheTrace) {
  for (auto [mode, flag] : {std::pair{EARSHOT_TRACE_SHARED, " --trace shared"},
                            std::pair{EARSHOT_TRACE_PER_SOURCE, " --trace per-source"}}) {
    Shoebox box(1, 0, mode);
    earshot_context_info ci;
    ci.struct_size = sizeof(ci);
    ASSERT_EQ(earshot_context_get_info(box.context, &ci), EARSHOT_OK);
    EXPECT_EQ(ci.trace_mode, mode);
    earshot_source_settings ss;
    earshot_source_settings_init(&ss);
    ss.direct = EARSHOT_DIRECT_IN_IMPULSE_RESPONSE;
    earshot_source* src = nullptr;
    ASSERT_EQ(earshot_source_create(box.context, &ss, &src), EARSHOT_OK);
    ASSERT_EQ(earshot_source_set_position(src, {2, 3.5f, 1.5f}), EARSHOT_OK);
    ASSERT_EQ(earshot_simulate(box.context, 0), EARSHOT_OK);
    earshot_ir* ir = nullptr;
    ASSERT_EQ(earshot_source_get_ir(src, &ir), EARSHOT_OK) << earshot_last_error_message();
    expectSame(copyOut(ir), cliIr("binaural", 1, flag));
    earshot_ir_release(ir);
    earshot_source_release(src);
  }
  earshot_context_settings cs = earshot::capi::test::fastSettings();
  EXPECT_EQ(cs.trace_mode, EARSHOT_TRACE_AUTO);
  earshot_context* c = nullptr;
  earshot::capi::test::storeRaw(cs.trace_mode, 5);
  EXPECT_EQ(earshot_context_create(&cs, &c), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(c, nullptr);
  EXPECT_NE(std::string(earshot_last_error_message()).find("trace_mode"), std::string::npos);
}

// The complete IR, not cut where the context cuts its sources' IRs
// (max_ir_seconds 0.3 s here: the shoebox's IR is longer).
TEST(CapiIr, ComputedIrIsEarshotIrsOmniAndBinaural) {
  Shoebox box(7, 0, EARSHOT_TRACE_AUTO, 0.3);
  earshot_ir_request req;
  ASSERT_EQ(earshot_ir_request_init(&req), EARSHOT_OK);
  req.source = {2, 3.5f, 1.5f};
  req.listener = {7, 3.5f, 1.5f};
  req.forward = {-1, 0, 0};
  req.up = {0, 0, 1};
  for (auto [receiver, name] : {std::pair{EARSHOT_RECEIVER_OMNI, "omni"}, {EARSHOT_RECEIVER_BINAURAL, "binaural"}}) {
    req.receiver = receiver;
    earshot_ir* ir = nullptr;
    ASSERT_EQ(earshot_context_compute_ir(box.context, &req, &ir), EARSHOT_OK) << earshot_last_error_message();
    expectSame(copyOut(ir), cliIr(name, 7));  // the context's seed
    earshot_ir_release(ir);
  }
  // A request's own seed.
  req.receiver = EARSHOT_RECEIVER_OMNI;
  req.seed = 3;
  earshot_ir* ir = nullptr;
  ASSERT_EQ(earshot_context_compute_ir(box.context, &req, &ir), EARSHOT_OK);
  expectSame(copyOut(ir), cliIr("omni", 3));
  earshot_ir_release(ir);
}

// Issue 15: an ambisonic request is `earshot ir --receiver ambisonic`'s IR;
// an ambisonic context's source IR is the world-frame AmbiX IR of its order
// (the listener's orientation plays no part: the same IR whichever way the
// listener faces).
TEST(CapiIr, AmbisonicIrsAreEarshotIrsAndWorldFrameForSources) {
  Shoebox box(7, 2);
  earshot_ir_request req;
  ASSERT_EQ(earshot_ir_request_init(&req), EARSHOT_OK);
  EXPECT_EQ(req.ambisonic_order, 1u);
  req.source = {2, 3.5f, 1.5f};
  req.listener = {7, 3.5f, 1.5f};
  req.forward = {-1, 0, 0};
  req.up = {0, 0, 1};
  req.receiver = EARSHOT_RECEIVER_AMBISONIC;
  req.ambisonic_order = 3;
  earshot_ir* ir = nullptr;
  ASSERT_EQ(earshot_context_compute_ir(box.context, &req, &ir), EARSHOT_OK) << earshot_last_error_message();
  expectSame(copyOut(ir), cliIr("ambisonic", 7, " --order 3"));
  earshot_ir_release(ir);
  req.ambisonic_order = 4;
  EXPECT_EQ(earshot_context_compute_ir(box.context, &req, &ir), EARSHOT_ERROR_INVALID_ARGUMENT);

  earshot_source_settings ss;
  earshot_source_settings_init(&ss);
  earshot_source* src = nullptr;
  ASSERT_EQ(earshot_source_create(box.context, &ss, &src), EARSHOT_OK);
  ASSERT_EQ(earshot_source_set_position(src, {2, 3.5f, 1.5f}), EARSHOT_OK);
  ASSERT_EQ(earshot_simulate(box.context, 0), EARSHOT_OK);
  ASSERT_EQ(earshot_source_get_ir(src, &ir), EARSHOT_OK);
  const earshot::AudioBuffer first = copyOut(ir);
  earshot_ir_release(ir);
  EXPECT_EQ(first.channelCount(), 9u);
  ASSERT_EQ(earshot_context_set_listener(box.context, {7, 3.5f, 1.5f}, {0, 1, 0}, {0, 0, 1}), EARSHOT_OK);
  ASSERT_EQ(earshot_simulate(box.context, 0), EARSHOT_OK);
  ASSERT_EQ(earshot_source_get_ir(src, &ir), EARSHOT_OK);
  expectSame(copyOut(ir), first);
  earshot_ir_release(ir);
  earshot_source_release(src);
}

TEST(CapiIr, FreeFieldWithoutAScene) {
  earshot_context_settings cs;
  earshot_context_settings_init(&cs);
  cs.max_sources = 1;
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&cs, &c), EARSHOT_OK);
  earshot_ir_request req;
  earshot_ir_request_init(&req);
  req.source = {0, 0, -3.4375f};  // exact in float, as the CLI's double
  req.receiver = EARSHOT_RECEIVER_OMNI;
  earshot_ir* ir = nullptr;
  ASSERT_EQ(earshot_context_compute_ir(c, &req, &ir), EARSHOT_OK) << earshot_last_error_message();
  earshot_ir_info info;
  info.struct_size = sizeof(info);
  ASSERT_EQ(earshot_ir_get_info(ir, &info), EARSHOT_OK);
  EXPECT_EQ(info.age_seconds, 0.0) << "a computed IR has no age";
  const earshot::AudioBuffer b = copyOut(ir);
  ASSERT_EQ(b.channelCount(), 1u);
  // The direct sound arrives at r/c (481.05 frames), and the whole IR is the CLI's.
  size_t peak = 0;
  for (size_t i = 0; i < b.frameCount(); ++i)
    if (std::fabs(b.channels[0][i]) > std::fabs(b.channels[0][peak])) peak = i;
  EXPECT_EQ(peak, 481u);
  const auto dir = std::filesystem::temp_directory_path() / ("earshot_capi_ff_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string out = (dir / "ff.wav").string();
  const std::string cmd = std::string(EARSHOT_CLI) + " ir --source 0,0,-3.4375 --listener 0,0,0 --receiver omni -o " +
                          out + " 2>/dev/null";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  auto cli = earshot::readAudioFile(out);
  std::filesystem::remove_all(dir);
  ASSERT_TRUE(cli.isOk());
  expectSame(b, *cli);
  earshot_ir_release(ir);
  earshot_context_release(c);
}

TEST(CapiIr, ErrorsAreStatusesNeverCrashes) {
  earshot_context_settings cs = earshot::capi::test::fastSettings();
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&cs, &c), EARSHOT_OK);
  earshot_ir_request req;
  earshot_ir_request_init(&req);
  earshot_ir* ir = nullptr;
  EXPECT_EQ(earshot_context_compute_ir(nullptr, &req, &ir), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_context_compute_ir(c, nullptr, &ir), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_context_compute_ir(c, &req, nullptr), EARSHOT_ERROR_INVALID_ARGUMENT);
  earshot_ir_request bad = req;
  bad.struct_size = 3;
  EXPECT_EQ(earshot_context_compute_ir(c, &bad, &ir), EARSHOT_ERROR_INVALID_ARGUMENT);
  bad = req;
  bad.source.x = NAN;
  EXPECT_EQ(earshot_context_compute_ir(c, &bad, &ir), EARSHOT_ERROR_INVALID_ARGUMENT);
  bad = req;
  bad.up = bad.forward;
  EXPECT_EQ(earshot_context_compute_ir(c, &bad, &ir), EARSHOT_ERROR_INVALID_ARGUMENT);
  bad = req;
  std::memset(&bad.receiver, 0x7f, sizeof(bad.receiver));
  EXPECT_EQ(earshot_context_compute_ir(c, &bad, &ir), EARSHOT_ERROR_INVALID_ARGUMENT);
  bad = req;
  bad.source = {3e6f, 0, 0};
  EXPECT_EQ(earshot_context_compute_ir(c, &bad, &ir), EARSHOT_ERROR_OUT_OF_RANGE);
  EXPECT_EQ(ir, nullptr);

  req.receiver = EARSHOT_RECEIVER_OMNI;
  ASSERT_EQ(earshot_context_compute_ir(c, &req, &ir), EARSHOT_OK);
  earshot_ir_info info;
  info.struct_size = sizeof(info);
  ASSERT_EQ(earshot_ir_get_info(ir, &info), EARSHOT_OK);
  std::vector<float> buffer(size_t(info.frames));
  EXPECT_EQ(earshot_ir_copy_channel(ir, 1, buffer.data(), info.frames), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_ir_copy_channel(ir, 0, nullptr, info.frames), EARSHOT_ERROR_INVALID_ARGUMENT);
  buffer.assign(buffer.size(), 42.0f);
  EXPECT_EQ(earshot_ir_copy_channel(ir, 0, buffer.data(), info.frames - 1), EARSHOT_ERROR_OUT_OF_RANGE);
  EXPECT_EQ(buffer[0], 42.0f);  // nothing copied
  info.struct_size = 1;
  EXPECT_EQ(earshot_ir_get_info(ir, &info), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_ir_get_info(nullptr, &info), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_ir_retain(ir), EARSHOT_OK);
  EXPECT_EQ(earshot_ir_release(ir), EARSHOT_OK);
  EXPECT_EQ(earshot_ir_release(ir), EARSHOT_OK);
  EXPECT_EQ(earshot_ir_release(reinterpret_cast<earshot_ir*>(c)), EARSHOT_ERROR_INVALID_ARGUMENT);  // wrong type
  earshot_source* src = nullptr;
  ASSERT_EQ(earshot_source_create(c, nullptr, &src), EARSHOT_OK);
  EXPECT_EQ(earshot_source_get_ir(src, nullptr), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_source_get_ir(nullptr, &ir), EARSHOT_ERROR_INVALID_ARGUMENT);
  earshot_source_release(src);
  earshot_context_release(c);
}

}  // namespace

namespace {

TEST(CppIr, SourceAndComputedIrs) {
  earshot::ContextSettings cs;
  cs.max_sources = 1;
  cs.rays = 2000;
  earshot::Context context(cs);
  earshot::Source source(context);
  source.setPosition(earshot::vec3(0, 0, -2));
  EXPECT_THROW(source.ir(), earshot::Error);
  context.simulate();
  earshot::Ir reflections = source.ir();  // per-block direct: reflections only (free field: none)
  EXPECT_EQ(reflections.channels(), 4u);  // the default: world-frame AmbiX of order 1
  EXPECT_EQ(reflections.info().includes_direct, 0u);
  earshot::IrRequest req;
  req.source = earshot::vec3(0, 0, -2);
  earshot::Ir full = context.computeIr(req);
  EXPECT_EQ(full.info().includes_direct, 1u);
  double energy = 0;
  for (float v : full.channel(0)) energy += double(v) * v;
  EXPECT_GT(energy, 0.0);
  EXPECT_THROW(full.channel(2), earshot::Error);
}

}  // namespace

namespace {

// Any host block size from 1 to 8192 frames: the convolver's block is the
// next even 2^a 3^b 5^c size (issue 19).
TEST(CapiBlocks, AnyBlockSizeRenders) {
  for (uint32_t block : {1u, 7u, 254u, 441u, 8192u}) {
    earshot_context_settings cs = earshot::capi::test::fastSettings();
    cs.block_frames = block;
    cs.max_sources = 1;
    earshot_context* c = nullptr;
    ASSERT_EQ(earshot_context_create(&cs, &c), EARSHOT_OK) << block << ": " << earshot_last_error_message();
    earshot_context_info info;
    info.struct_size = sizeof(info);
    ASSERT_EQ(earshot_context_get_info(c, &info), EARSHOT_OK);
    EXPECT_EQ(info.block_frames, block);
    // The default ambisonic reflections add the decoder's block and its 2 ms.
    ASSERT_EQ(info.ambisonic_order, 1u);
    const uint32_t decoderDelay = 96;  // ceil(0.002 * 48000)
    ASSERT_GT(info.latency_frames, decoderDelay);
    ASSERT_EQ((info.latency_frames - decoderDelay) % 2, 0u);
    const uint32_t convolverBlock = (info.latency_frames - decoderDelay) / 2;
    EXPECT_GE(convolverBlock, std::max(block, 8u));
    EXPECT_EQ(convolverBlock % 2, 0u);
    uint32_t rest = convolverBlock;
    for (uint32_t f : {2u, 3u, 5u})
      while (rest % f == 0) rest /= f;
    EXPECT_EQ(rest, 1u) << convolverBlock;
    if (block == 254) {
      EXPECT_EQ(convolverBlock, 256u);
    }
    earshot_source* src = nullptr;
    ASSERT_EQ(earshot_source_create(c, nullptr, &src), EARSHOT_OK);
    ASSERT_EQ(earshot_source_set_position(src, {0, 0, -2}), EARSHOT_OK);
    ASSERT_EQ(earshot_simulate(c, 0), EARSHOT_OK);
    // Blocks of the requested size until the impulse is out.
    std::vector<float> dry(block, 0.0f), left(block), right(block);
    const float* inputs[1] = {dry.data()};
    double energy = 0;
    for (uint32_t done = 0; done < 4 * 8192u; done += block) {
      dry[0] = done == 0 ? 1.0f : 0.0f;
      ASSERT_EQ(earshot_process(c, inputs, 1, left.data(), right.data(), block), EARSHOT_OK);
      for (uint32_t i = 0; i < block; ++i) energy += double(left[i]) * left[i] + double(right[i]) * right[i];
    }
    EXPECT_GT(energy, 0.01) << block;  // 1/r^2 = 0.25 over two ears, less the HRTF's spectrum
    earshot_source_release(src);
    earshot_context_release(c);
  }
}

}  // namespace

namespace {

double renderEnergy(earshot_context* c, uint32_t frames) {
  std::vector<float> dry(256), left(256), right(256);
  const float* inputs[2] = {dry.data(), dry.data()};
  double e = 0;
  uint32_t seed = 7;
  for (uint32_t done = 0; done < frames; done += 256) {
    for (float& v : dry) {
      seed = seed * 1664525u + 1013904223u;
      v = float(int32_t(seed)) / 2147483648.0f * 0.1f;  // noise: every block carries sound
    }
    EXPECT_EQ(earshot_process(c, inputs, 2, left.data(), right.data(), 256), EARSHOT_OK);
    for (size_t i = 0; i < 256; ++i) e += double(left[i]) * left[i] + double(right[i]) * right[i];
  }
  return e;
}

// A new source's direct sound plays from its first block; its reflections
// join when its first simulation lands; a source whose IR holds the direct
// sound waits for it (issue 19).
TEST(CapiImmediate, DirectSoundFromTheFirstBlockReflectionsOnceSimulated) {
  Shoebox box;
  earshot_source* moving = nullptr;
  ASSERT_EQ(earshot_source_create(box.context, nullptr, &moving), EARSHOT_OK);
  ASSERT_EQ(earshot_source_set_position(moving, {5, 3.5f, 1.5f}), EARSHOT_OK);
  // The first 1024 frames: the direct sound's 2 m take 280 frames, the
  // convolver's latency 256.
  const double first = renderEnergy(box.context, 1024);
  EXPECT_GT(first, 0.0);
  const double before = renderEnergy(box.context, 48000);
  ASSERT_EQ(earshot_simulate(box.context, 0), EARSHOT_OK);
  renderEnergy(box.context, 4800);  // the IR lands and its reverberation builds up
  const double after = renderEnergy(box.context, 48000);
  // In a reverberant room the reflections carry more than the direct sound
  // at 2 m: energy rises once they join.
  EXPECT_GT(after, 1.5 * before) << before << " -> " << after;

  earshot_source_settings ss;
  earshot_source_settings_init(&ss);
  ss.direct = EARSHOT_DIRECT_IN_IMPULSE_RESPONSE;
  earshot_source* fixed = nullptr;
  ASSERT_EQ(earshot_source_create(box.context, &ss, &fixed), EARSHOT_OK);
  ASSERT_EQ(earshot_source_set_position(fixed, {3, 3.5f, 1.5f}), EARSHOT_OK);
  earshot_source_release(moving);
  renderEnergy(box.context, 48000 * 3);  // the released source's reverberation dies away
  EXPECT_EQ(renderEnergy(box.context, 2048), 0.0);  // the IR-mode source waits for its IR
  ASSERT_EQ(earshot_simulate(box.context, 0), EARSHOT_OK);
  EXPECT_GT(renderEnergy(box.context, 4096), 0.0);
  earshot_source_release(fixed);
}

}  // namespace

namespace {

// Directivity (issue 19): a directional source's direct sound follows its
// pattern, its reverberation stays the omni source's (power-normalised), and
// reflections leave along their own directions. Through IR-mode sources in
// the shoebox (their IR holds the direct sound).
struct DirectionalIr {
  earshot::AudioBuffer ir;
  double direct = 0, late = 0;
};

DirectionalIr directionalIr(float alpha, earshot_vec3 forward) {
  Shoebox box;
  earshot_source_settings ss;
  earshot_source_settings_init(&ss);
  ss.direct = EARSHOT_DIRECT_IN_IMPULSE_RESPONSE;
  ss.directivity_alpha = alpha;
  earshot_source* src = nullptr;
  EXPECT_EQ(earshot_source_create(box.context, &ss, &src), EARSHOT_OK) << earshot_last_error_message();
  EXPECT_EQ(earshot_source_set_position(src, {2, 3.5f, 1.5f}), EARSHOT_OK);
  EXPECT_EQ(earshot_source_set_orientation(src, forward), EARSHOT_OK);
  EXPECT_EQ(earshot_simulate(box.context, 0), EARSHOT_OK);
  earshot_ir* ir = nullptr;
  EXPECT_EQ(earshot_source_get_ir(src, &ir), EARSHOT_OK);
  DirectionalIr out;
  out.ir = copyOut(ir);
  earshot_ir_release(ir);
  earshot_source_release(src);
  // Direct: 5 m at 343 m/s = 699.7 frames; the floor's reflection comes
  // 2.4 ms later. Window -1 .. +1.5 ms. Late: after 150 ms.
  const size_t d0 = 700 - 48, d1 = 700 + 72, late0 = size_t(0.15 * 48000);
  for (const auto& ch : out.ir.channels)
    for (size_t i = 0; i < ch.size(); ++i) {
      const double e = double(ch[i]) * ch[i];
      if (i >= d0 && i < d1) out.direct += e;
      if (i >= late0) out.late += e;
    }
  return out;
}

TEST(CapiDirectivity, DirectFollowsThePatternReverberationStaysTheOmnis) {
  const DirectionalIr omni = directionalIr(0.0f, {1, 0, 0});
  ASSERT_GT(omni.direct, 0.0);
  ASSERT_GT(omni.late, 0.0);
  // Subcardioid (alpha 0.25): g = 0.75 + 0.25 cos; <g^2> = 0.5625 + 0.0625/3.
  const double ms = 0.5625 + 0.0625 / 3.0;
  const DirectionalIr toward = directionalIr(0.25f, {1, 0, 0});   // facing the listener (+x)
  const DirectionalIr away = directionalIr(0.25f, {-1, 0, 0});
  EXPECT_NEAR(toward.direct / omni.direct, 1.0 / ms, 0.01 / ms);
  EXPECT_NEAR(away.direct / omni.direct, 0.25 / ms, 0.01 * 0.25 / ms);
  // Down by the pattern's value from front to back: (0.5 / 1)^2.
  EXPECT_NEAR(away.direct / toward.direct, 0.25, 0.0025);
  // A cardioid facing away: no direct sound, and the reverberation within
  // 1 dB of the omni source's (it was muted whole before).
  const DirectionalIr cardioidAway = directionalIr(0.5f, {-1, 0, 0});
  EXPECT_LT(cardioidAway.direct, 1e-6 * omni.direct + 1e-3 * omni.late);
  const double lateDb = 10.0 * std::log10(cardioidAway.late / omni.late);
  EXPECT_LT(std::fabs(lateDb), 1.0) << lateDb << " dB";
  // Facing down the room's long axis the late field keeps more of it: this
  // shoebox's walls scatter little, so the flutter between its end walls
  // remembers where the sound went (measured +1.1 dB); the same power, not
  // a diffuse field.
  const DirectionalIr cardioidToward = directionalIr(0.5f, {1, 0, 0});
  EXPECT_LT(std::fabs(10.0 * std::log10(cardioidToward.late / omni.late)), 1.5);
  // Omni with an orientation is omni: bit for bit.
  const DirectionalIr turned = directionalIr(0.0f, {0, 1, 0});
  expectSame(turned.ir, omni.ir);
}

TEST(CapiDirectivity, BadPatternsAndOrientationsAreRefused) {
  earshot_context_settings cs = earshot::capi::test::fastSettings();
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&cs, &c), EARSHOT_OK);
  earshot_source_settings ss;
  earshot_source_settings_init(&ss);
  earshot_source* src = nullptr;
  ss.directivity_alpha = 1.5f;
  EXPECT_EQ(earshot_source_create(c, &ss, &src), EARSHOT_ERROR_INVALID_ARGUMENT);
  ss.directivity_alpha = 0.5f;
  ss.directivity_sharpness = 0.5f;
  EXPECT_EQ(earshot_source_create(c, &ss, &src), EARSHOT_ERROR_INVALID_ARGUMENT);
  ss.directivity_sharpness = 2.0f;
  ASSERT_EQ(earshot_source_create(c, &ss, &src), EARSHOT_OK);
  EXPECT_EQ(earshot_source_set_orientation(src, {0, 0, 0}), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_source_set_orientation(src, {NAN, 0, 1}), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_source_set_orientation(nullptr, {0, 0, 1}), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_source_set_orientation(src, {0, 0, 1}), EARSHOT_OK);
  earshot_source_release(src);
  earshot_context_release(c);
}

}  // namespace

namespace {

// Lazy context creation (issue 19): the slots of a context cost their state
// only once sources use them, and the HRTF loads in the background.

#if defined(__GLIBC__)
double heapBytes() { return double(mallinfo2().uordblks); }
#endif

TEST(CapiLazyContext, SlotsCostNothingUntilSourcesUseThem) {
#if !defined(__GLIBC__)
  GTEST_SKIP() << "heap measured with glibc's mallinfo2";
#else
  // With sanitizers, malloc is not glibc's and mallinfo2 sees nothing.
  const double start = heapBytes();
  earshot_context_settings cs;
  earshot_context_settings_init(&cs);
  cs.max_sources = 256;
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&cs, &c), EARSHOT_OK) << earshot_last_error_message();
  earshot_source* first = nullptr;
  ASSERT_EQ(earshot_source_create(c, nullptr, &first), EARSHOT_OK) << earshot_last_error_message();
  // One source in use: the HRTF (loaded by now) and one slot's state. Each
  // slot's state was ~1.5 MB with 3 s IRs per source (256 slots allocated up
  // front would be ~390 MB); with the shared tail ~0.4 MB.
  const double oneSource = heapBytes() - start;
  EXPECT_LT(oneSource, 50e6);
  earshot_source* more[8] = {};
  for (auto& s : more) ASSERT_EQ(earshot_source_create(c, nullptr, &s), EARSHOT_OK);
  const double nine = heapBytes() - start;
  // Each new slot allocates its state: the direct voice's delay line (343 m:
  // ~0.26 MB) and the convolution history of its own IR (with the shared
  // tail, 0.16 s: ~0.15 MB); 0.41 MB a slot measured.
  if (nine > 0) {
    EXPECT_GT(nine - oneSource, 8 * 0.3e6) << "each new slot allocates its state";
  }
  // A released slot's state is kept for its next source.
  for (auto& s : more) earshot_source_release(s);
  for (auto& s : more) ASSERT_EQ(earshot_source_create(c, nullptr, &s), EARSHOT_OK);
  EXPECT_LT(heapBytes() - start, nine + 1e6);
  for (auto& s : more) earshot_source_release(s);
  earshot_source_release(first);
  earshot_context_release(c);
#endif
}

TEST(CapiLazyContext, ABrokenHrtfFailsItsFirstUseNotTheContext) {
  const auto dir = std::filesystem::temp_directory_path() / ("earshot_capi_lazy_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string sofa = (dir / "broken.sofa").string();
  {
    std::FILE* f = std::fopen(sofa.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    const char junk[] = "\x89HDF\r\n\x1a\nnot really a SOFA file, secret-bytes-here";
    std::fwrite(junk, 1, sizeof junk, f);
    std::fclose(f);
  }
  earshot_context_settings cs;
  earshot_context_settings_init(&cs);
  cs.max_sources = 4;
  // A folder or a missing file is refused at once.
  cs.hrtf_path = dir.c_str();
  earshot_context* c = nullptr;
  EXPECT_NE(earshot_context_create(&cs, &c), EARSHOT_OK);
  EXPECT_EQ(c, nullptr);
  // A file that is there but not a SOFA set: the context is made, and every
  // use of the HRTF reports the load's error (the path, never the bytes).
  cs.hrtf_path = sofa.c_str();
  ASSERT_EQ(earshot_context_create(&cs, &c), EARSHOT_OK) << earshot_last_error_message();
  earshot_source* s = nullptr;
  for (int attempt = 0; attempt < 2; ++attempt) {
    EXPECT_NE(earshot_source_create(c, nullptr, &s), EARSHOT_OK);
    EXPECT_EQ(s, nullptr);
    const std::string message = earshot_last_error_message();
    EXPECT_NE(message.find("broken.sofa"), std::string::npos) << message;
    EXPECT_EQ(message.find("secret-bytes"), std::string::npos) << message;
  }
  earshot_ir_request req;
  earshot_ir_request_init(&req);
  req.source = {0, 0, -2};
  req.receiver = EARSHOT_RECEIVER_BINAURAL;
  earshot_ir* ir = nullptr;
  EXPECT_NE(earshot_context_compute_ir(c, &req, &ir), EARSHOT_OK);
  EXPECT_EQ(ir, nullptr);
  // The omni receiver needs no HRTF; the audio path renders silence.
  req.receiver = EARSHOT_RECEIVER_OMNI;
  EXPECT_EQ(earshot_context_compute_ir(c, &req, &ir), EARSHOT_OK) << earshot_last_error_message();
  earshot_ir_release(ir);
  std::vector<float> left(256, 1.0f), right(256, 1.0f);
  std::vector<float> dry(256, 0.5f);
  const float* inputs[4] = {dry.data(), dry.data(), dry.data(), dry.data()};
  EXPECT_EQ(earshot_process(c, inputs, 4, left.data(), right.data(), 256), EARSHOT_OK) << earshot_last_error_message();
  for (float v : left) EXPECT_EQ(v, 0.0f);
  earshot_context_release(c);
  std::filesystem::remove_all(dir);
}

}  // namespace

namespace {

// Issue 15: the context's output format. An ambisonic context reports its
// channels, renders through earshot_process_channels only (earshot_process
// is INVALID_STATE) and refuses a wrong channel count; a source on the
// listener's left is all in W and Y. Settings out of range are refused.
TEST(CapiAmbisonic, OutputFormatSelectsTheChannels) {
  earshot_context_settings cs = earshot::capi::test::fastSettings();
  cs.ambisonic_order = 2;
  cs.output_format = EARSHOT_OUTPUT_AMBISONIC;
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&cs, &c), EARSHOT_OK) << earshot_last_error_message();
  earshot_context_info info;
  info.struct_size = sizeof(info);
  ASSERT_EQ(earshot_context_get_info(c, &info), EARSHOT_OK);
  EXPECT_EQ(info.output_channels, 9u);
  EXPECT_EQ(info.ambisonic_order, 2u);
  EXPECT_EQ(info.output_format, EARSHOT_OUTPUT_AMBISONIC);
  earshot_source_settings ss;
  earshot_source_settings_init(&ss);
  earshot_source* src = nullptr;
  ASSERT_EQ(earshot_source_create(c, &ss, &src), EARSHOT_OK) << earshot_last_error_message();
  ASSERT_EQ(earshot_context_set_listener(c, {0, 0, 0}, {1, 0, 0}, {0, 0, 1}), EARSHOT_OK);
  ASSERT_EQ(earshot_source_set_position(src, {0, 3, 0}), EARSHOT_OK);  // left
  ASSERT_EQ(earshot_simulate(c, 0), EARSHOT_OK);
  const size_t frames = 256;
  std::vector<float> in(frames), l(frames), r(frames);
  std::vector<std::vector<float>> out(9, std::vector<float>(frames));
  std::vector<float*> outs;
  for (auto& o : out) outs.push_back(o.data());
  const float* inputs[1] = {in.data()};
  EXPECT_EQ(earshot_process(c, inputs, 1, l.data(), r.data(), frames), EARSHOT_ERROR_INVALID_STATE);
  EXPECT_EQ(earshot_process_channels(c, inputs, 1, outs.data(), 2, frames), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_process_channels(c, inputs, 1, nullptr, 9, frames), EARSHOT_ERROR_INVALID_ARGUMENT);
  std::vector<float*> overlapping = outs;
  overlapping[4] = overlapping[3] + 1;
  EXPECT_EQ(earshot_process_channels(c, inputs, 1, overlapping.data(), 9, frames), EARSHOT_ERROR_INVALID_ARGUMENT);
  double w = 0, y = 0, x = 0;
  for (int b = 0; b < 40; ++b) {
    for (size_t i = 0; i < frames; ++i) in[i] = float(std::sin(0.07 * double(b * frames + i)));
    ASSERT_EQ(earshot_process_channels(c, inputs, 1, outs.data(), 9, frames), EARSHOT_OK);
    for (size_t i = 0; i < frames; ++i) {
      w += double(out[0][i]) * out[0][i];
      y += double(out[1][i]) * out[1][i];
      x += double(out[3][i]) * out[3][i];
    }
  }
  EXPECT_GT(w, 0.0);
  EXPECT_NEAR(y / w, 1.0, 0.01);
  EXPECT_LT(x / w, 1e-4);
  earshot_source_release(src);
  earshot_context_release(c);

  // A binaural context writes two channels either way.
  cs = earshot::capi::test::fastSettings();
  ASSERT_EQ(earshot_context_create(&cs, &c), EARSHOT_OK);
  ASSERT_EQ(earshot_context_get_info(c, &info), EARSHOT_OK);
  EXPECT_EQ(info.output_channels, 2u);
  EXPECT_EQ(info.ambisonic_order, 1u) << "the default: ambisonic reflections of order 1";
  float* two[2] = {l.data(), r.data()};
  EXPECT_EQ(earshot_process_channels(c, nullptr, 0, two, 2, frames), EARSHOT_OK);
  EXPECT_EQ(earshot_process(c, nullptr, 0, l.data(), r.data(), frames), EARSHOT_OK);
  earshot_context_release(c);

  // (7 is no earshot_output_format: written as raw bytes, as a C caller's
  // garbage would arrive, not through an invalid enum value in C++.)
  for (auto [order, format] : {std::pair{0u, int(EARSHOT_OUTPUT_AMBISONIC)}, {4u, int(EARSHOT_OUTPUT_BINAURAL)},
                               {1u, 7}}) {
    cs = earshot::capi::test::fastSettings();
    cs.ambisonic_order = order;
    static_assert(sizeof(cs.output_format) == sizeof(int));
    std::memcpy(&cs.output_format, &format, sizeof format);
    EXPECT_EQ(earshot_context_create(&cs, &c), EARSHOT_ERROR_INVALID_ARGUMENT) << order << " " << format;
    EXPECT_EQ(c, nullptr);
  }
}

}  // namespace
