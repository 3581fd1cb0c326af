// Per-source controls through the C API (issue 19): distance curves match
// their formulas, gains scale what they name, occlusion modes differ as
// documented, priority orders simulation; bad values are refused.
#include <gtest/gtest.h>
#include <chrono>
#include <thread>

#include <cmath>
#include <cstring>
#include <vector>

#include "capi_fixture.h"
#include "earshot/earshot.h"
#include "earshot/earshot.hpp"

namespace {

using earshot::capi::test::BoxData;
using earshot::capi::test::fastSettings;

struct World {
  earshot_context* c = nullptr;
  earshot_scene* scene = nullptr;
  earshot_source* src = nullptr;

  /** Free field, or (wall) a 4 m x 4 m curtain in the plane z = -1 centred on
   *  the axis, between the listener at the origin and sources along -z. */
  explicit World(bool wall, const earshot_source_settings* ss = nullptr) {
    earshot_context_settings cs = fastSettings();
    cs.max_sources = 2;
    EXPECT_EQ(earshot_context_create(&cs, &c), EARSHOT_OK);
    if (wall) {
      EXPECT_EQ(earshot_scene_create(c, nullptr, &scene), EARSHOT_OK);
      BoxData quad;
      quad.vertices = {-2, -2, -1, 2, -2, -1, 2, 2, -1, -2, 2, -1};
      quad.indices = {0, 1, 2, 0, 2, 3};
      earshot_mesh* m = earshot::capi::test::makeMesh(c, quad, "curtain_light", EARSHOT_MESH_STATIC, "wall");
      EXPECT_EQ(earshot_scene_add_mesh(scene, m), EARSHOT_OK);
      earshot_mesh_release(m);
      EXPECT_EQ(earshot_scene_commit(scene), EARSHOT_OK);
      EXPECT_EQ(earshot_context_set_scene(c, scene), EARSHOT_OK);
    }
    EXPECT_EQ(earshot_source_create(c, ss, &src), EARSHOT_OK) << earshot_last_error_message();
  }
  ~World() {
    earshot_source_release(src);
    if (scene) earshot_scene_release(scene);
    earshot_context_release(c);
  }
  void set(const earshot_source_settings& s) {
    ASSERT_EQ(earshot_source_set_settings(src, &s), EARSHOT_OK) << earshot_last_error_message();
  }
  earshot_source_settings get() {
    earshot_source_settings s;
    s.struct_size = sizeof(s);
    EXPECT_EQ(earshot_source_get_settings(src, &s), EARSHOT_OK);
    return s;
  }
  /** Energy (both ears) of the response to one impulse, after a second of
   *  silence (gains settle; the previous response dies away). */
  double impulseEnergy() {
    std::vector<float> dry(256, 0.0f), l(256), r(256);
    const float* in[2] = {dry.data(), nullptr};
    for (int b = 0; b < 188; ++b) EXPECT_EQ(earshot_process(c, in, 2, l.data(), r.data(), 256), EARSHOT_OK);
    double e = 0;
    for (int b = 0; b < 94; ++b) {  // 0.5 s
      dry[0] = b == 0 ? 1.0f : 0.0f;
      EXPECT_EQ(earshot_process(c, in, 2, l.data(), r.data(), 256), EARSHOT_OK);
      for (int i = 0; i < 256; ++i) e += double(l[i]) * l[i] + double(r[i]) * r[i];
    }
    return e;
  }
};

earshot_source_settings defaults() {
  earshot_source_settings s;
  earshot_source_settings_init(&s);
  return s;
}

double curve(earshot_distance_model m, double d, double mn, double mx, double rolloff) {
  const double D = std::min(std::max(d, mn), mx);
  switch (m) {
    case EARSHOT_DISTANCE_INVERSE: return mn / (mn + rolloff * (D - mn));
    case EARSHOT_DISTANCE_LINEAR: return std::max(0.0, 1.0 - rolloff * (D - mn) / (mx - mn));
    case EARSHOT_DISTANCE_EXPONENTIAL: return std::pow(D / mn, -rolloff);
    default: return 1.0 / std::max(d, 0.1);
  }
}

TEST(CapiControls, DistanceCurvesMatchTheirFormulas) {
  World w(false);
  for (double d : {0.5, 4.0, 15.0}) {
    ASSERT_EQ(earshot_source_set_position(w.src, {0, 0, float(-d)}), EARSHOT_OK);
    w.set(defaults());
    const double physical = w.impulseEnergy();
    ASSERT_GT(physical, 0.0);
    struct Case {
      earshot_distance_model model;
      float mn, mx, rolloff;
    };
    for (Case k : {Case{EARSHOT_DISTANCE_INVERSE, 1, 100, 2}, Case{EARSHOT_DISTANCE_LINEAR, 1, 11, 1},
                   Case{EARSHOT_DISTANCE_EXPONENTIAL, 2, 10, 1.5f}}) {
      earshot_source_settings s = defaults();
      s.distance_model = k.model;
      s.min_distance = k.mn;
      s.max_distance = k.mx;
      s.rolloff = k.rolloff;
      w.set(s);
      // Energy relative to the physical 1/r at the same place: (g(d) d)^2.
      const double expected = std::pow(curve(k.model, d, k.mn, k.mx, k.rolloff) * std::max(d, 0.1), 2.0);
      EXPECT_NEAR(w.impulseEnergy() / physical, expected, 1e-3 * std::max(expected, 1e-3))
          << "model " << k.model << " at " << d << " m";
    }
  }
}

TEST(CapiControls, DistanceTableIsInterpolatedLinearly) {
  World w(false);
  // Points (1 m, 1), (3 m, 0.5), (10 m, 0.1): at 2 m 0.75, at 20 m 0.1 (flat beyond).
  earshot_source_settings s = defaults();
  s.distance_model = EARSHOT_DISTANCE_TABLE;
  s.distance_table_count = 3;
  const float d[3] = {1, 3, 10}, g[3] = {1, 0.5f, 0.1f};
  for (int i = 0; i < 3; ++i) {
    s.distance_table_distance[i] = d[i];
    s.distance_table_gain[i] = g[i];
  }
  for (auto [dist, gain] : {std::pair{2.0, 0.75}, std::pair{20.0, 0.1}, std::pair{0.5, 1.0}}) {
    ASSERT_EQ(earshot_source_set_position(w.src, {0, 0, float(-dist)}), EARSHOT_OK);
    w.set(defaults());
    const double physical = w.impulseEnergy();
    w.set(s);
    const double expected = std::pow(gain * std::max(dist, 0.1), 2.0);
    EXPECT_NEAR(w.impulseEnergy() / physical, expected, 1e-3 * expected) << dist << " m";
  }
  const earshot_source_settings back = w.get();
  EXPECT_EQ(back.distance_model, EARSHOT_DISTANCE_TABLE);
  EXPECT_EQ(back.distance_table_count, 3u);
  EXPECT_FLOAT_EQ(back.distance_table_gain[1], 0.5f);
  // Not ascending, too many or no points, a gain past 10: refused.
  earshot_source_settings bad = s;
  bad.distance_table_distance[2] = 2;
  EXPECT_EQ(earshot_source_set_settings(w.src, &bad), EARSHOT_ERROR_INVALID_ARGUMENT);
  bad = s;
  bad.distance_table_count = 17;
  EXPECT_EQ(earshot_source_set_settings(w.src, &bad), EARSHOT_ERROR_INVALID_ARGUMENT);
  bad.distance_table_count = 0;
  EXPECT_EQ(earshot_source_set_settings(w.src, &bad), EARSHOT_ERROR_INVALID_ARGUMENT);
  bad = s;
  bad.distance_table_gain[0] = 11;
  EXPECT_EQ(earshot_source_set_settings(w.src, &bad), EARSHOT_ERROR_INVALID_ARGUMENT);
}

TEST(CapiControls, GainsScaleWhatTheyName) {
  // Direct gain, free field (no reflections).
  World w(false);
  ASSERT_EQ(earshot_source_set_position(w.src, {0, 0, -3}), EARSHOT_OK);
  const double open = w.impulseEnergy();
  earshot_source_settings s = defaults();
  s.direct_gain_db = -6.0f;
  w.set(s);
  EXPECT_NEAR(w.impulseEnergy() / open, std::pow(10.0, -0.6), 1e-4);
  EXPECT_FLOAT_EQ(w.get().direct_gain_db, -6.0f);

  // Reflections gain, with the curtain: the direct sound silenced, the
  // curtain's reflection at -10 dB, then 0 dB.
  World r(true);
  ASSERT_EQ(earshot_source_set_position(r.src, {0, 0.5f, -0.5f}), EARSHOT_OK);  // in front of the curtain
  ASSERT_EQ(earshot_simulate(r.c, 0), EARSHOT_OK);
  s = defaults();
  s.direct_gain_db = -120.0f;
  r.set(s);
  const double full = r.impulseEnergy();
  ASSERT_GT(full, 0.0);
  s.reflections_gain_db = -10.0f;
  r.set(s);
  const double quiet = r.impulseEnergy();
  // The direct sound's -120 dB leaves ~1e-12 of the open level: negligible.
  EXPECT_NEAR(quiet / full, 0.1, 0.002);
}

// What earshot_source_get_settings returns is what was set, to the bit
// (fuzz_capi found -0 and 1e-30 dB coming back as +0: the engine gave the
// gains back from their linear values). earshot_source_set_gain_db too.
TEST(CapiControls, GainsReadBackAsSet) {
  World w(false);
  for (float db : {-0.0f, 1e-30f, -1e-20f, 4e-4f, -7.25f, -39.9f, 40.0f}) {  // -db within [-120, 40] too
    earshot_source_settings s = defaults();
    s.gain_db = db;
    s.direct_gain_db = -db;
    s.reflections_gain_db = db / 2;
    w.set(s);
    const earshot_source_settings back = w.get();
    EXPECT_EQ(std::memcmp(&back.gain_db, &s.gain_db, sizeof(float)), 0) << db << " came back as " << back.gain_db;
    EXPECT_EQ(std::memcmp(&back.direct_gain_db, &s.direct_gain_db, sizeof(float)), 0) << -db;
    EXPECT_EQ(std::memcmp(&back.reflections_gain_db, &s.reflections_gain_db, sizeof(float)), 0) << db / 2;
    ASSERT_EQ(earshot_source_set_gain_db(w.src, -db), EARSHOT_OK);
    const float expected = -db, got = w.get().gain_db;
    EXPECT_EQ(std::memcmp(&got, &expected, sizeof(float)), 0) << -db << " came back as " << got;
  }
}

TEST(CapiControls, OcclusionModesDifferAsDocumented) {
  World w(true);
  ASSERT_EQ(earshot_source_set_position(w.src, {0, 0, -3}), EARSHOT_OK);  // behind the curtain, on axis
  earshot_source_settings s = defaults();
  s.reflections_gain_db = -120.0f;  // the direct sound alone
  auto energyWith = [&](earshot_occlusion_mode mode, int transmission, float radius) {
    s.occlusion = mode;
    s.transmission = transmission;
    s.radius = radius;
    w.set(s);
    EXPECT_EQ(earshot_simulate(w.c, 0), EARSHOT_OK);
    return w.impulseEnergy();
  };
  const double off = energyWith(EARSHOT_OCCLUSION_OFF, 1, 0.5f);
  const double ray = energyWith(EARSHOT_OCCLUSION_RAY, 1, 0.5f);
  const double blocked = energyWith(EARSHOT_OCCLUSION_RAY, 0, 0.5f);
  EXPECT_GT(off, 0.0);
  EXPECT_LT(ray, 0.9 * off);         // through the curtain: filtered by its transmission
  EXPECT_GT(ray, 0.01 * off);        // (light curtain: 3-37 % of the energy per band)
  EXPECT_LT(blocked, 1e-9 * off);    // no transmission: silent
  // Volumetric: a sphere of 1 m around a source whose ray to the listener
  // crosses the curtain's plane (z = -1) at x = 1.9, just inside its edge
  // (x = 2): the sphere's rays cross at x = 1.57 .. 2.23, some through the
  // curtain, some past it.
  ASSERT_EQ(earshot_source_set_position(w.src, {5.7f, 0, -3}), EARSHOT_OK);
  const double edgeRay = energyWith(EARSHOT_OCCLUSION_RAY, 0, 1.0f);
  const double edgeVolume = energyWith(EARSHOT_OCCLUSION_VOLUMETRIC, 0, 1.0f);
  const double edgeOpen = energyWith(EARSHOT_OCCLUSION_OFF, 0, 1.0f);
  EXPECT_LT(edgeRay, 1e-9 * edgeOpen);
  EXPECT_GT(edgeVolume, 0.05 * edgeOpen);
  EXPECT_LT(edgeVolume, 0.95 * edgeOpen);
}

// earshot_source_get_occlusion reports the direct path the last simulation
// found: the light curtain's transmission per band (pressure: the square
// root of its energy fraction, air excluded), nothing without
// transmission, all clear on the open side, and "not simulated" (clear)
// before the first simulation. EARSHOT_OCCLUSION_OFF reports what a ray
// finds though the sound is not filtered. Bad arguments are refused.
TEST(CapiControls, OcclusionReportsTheLastSimulation) {
  World w(true);
  ASSERT_EQ(earshot_source_set_position(w.src, {0, 0, -3}), EARSHOT_OK);  // behind the curtain, on axis
  auto occlusion = [&] {
    earshot_source_occlusion o;
    std::memset(&o, 0xff, sizeof(o));
    o.struct_size = sizeof(o);
    EXPECT_EQ(earshot_source_get_occlusion(w.src, &o), EARSHOT_OK) << earshot_last_error_message();
    return o;
  };
  earshot_source_occlusion o = occlusion();
  EXPECT_EQ(o.simulated, 0u);
  EXPECT_EQ(o.audible, 1u);
  for (float t : o.transmission) EXPECT_EQ(t, 1.0f);

  earshot_source_settings s = defaults();
  s.transmission = 1;
  w.set(s);
  ASSERT_EQ(earshot_simulate(w.c, 0), EARSHOT_OK);
  o = occlusion();
  EXPECT_EQ(o.simulated, 1u);
  EXPECT_EQ(o.audible, 1u);
  // The light curtain of materials/default.json.
  const float curtain[EARSHOT_BAND_COUNT] = {0.025f, 0.03f, 0.195f, 0.315f, 0.35f, 0.365f, 0.365f};
  for (int b = 0; b < EARSHOT_BAND_COUNT; ++b)
    EXPECT_NEAR(o.transmission[b], std::sqrt(curtain[b]), 1e-6) << "band " << b;
  const earshot_source_occlusion through = o;

  s.occlusion = EARSHOT_OCCLUSION_OFF;
  w.set(s);
  ASSERT_EQ(earshot_simulate(w.c, 0), EARSHOT_OK);
  o = occlusion();
  EXPECT_EQ(std::memcmp(o.transmission, through.transmission, sizeof(o.transmission)), 0);

  s.occlusion = EARSHOT_OCCLUSION_RAY;
  s.transmission = 0;
  w.set(s);
  ASSERT_EQ(earshot_simulate(w.c, 0), EARSHOT_OK);
  o = occlusion();
  EXPECT_EQ(o.simulated, 1u);
  EXPECT_EQ(o.audible, 0u);
  for (float t : o.transmission) EXPECT_EQ(t, 0.0f);

  ASSERT_EQ(earshot_source_set_position(w.src, {0, 0, 3}), EARSHOT_OK);  // behind the listener: clear
  ASSERT_EQ(earshot_simulate(w.c, 0), EARSHOT_OK);
  o = occlusion();
  EXPECT_EQ(o.audible, 1u);
  for (float t : o.transmission) EXPECT_EQ(t, 1.0f);

  EXPECT_EQ(earshot_source_get_occlusion(w.src, nullptr), EARSHOT_ERROR_INVALID_ARGUMENT);
  earshot_source_occlusion bad;
  bad.struct_size = sizeof(bad) - 4;
  EXPECT_EQ(earshot_source_get_occlusion(w.src, &bad), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(earshot_last_error_message()).find("struct_size"), std::string::npos);
  EXPECT_EQ(earshot_source_get_occlusion(nullptr, &o), EARSHOT_ERROR_INVALID_ARGUMENT);
}

TEST(CapiControls, PriorityOrdersSimulation) {
  earshot_context_settings cs = fastSettings();
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&cs, &c), EARSHOT_OK);
  earshot_source* a = nullptr;
  earshot_source* b = nullptr;
  ASSERT_EQ(earshot_source_create(c, nullptr, &a), EARSHOT_OK);
  earshot_source_settings s = defaults();
  s.priority = 5;
  ASSERT_EQ(earshot_source_create(c, &s, &b), EARSHOT_OK);
  // One source per step: the high-priority one first, each time.
  for (int step = 0; step < 3; ++step) ASSERT_EQ(earshot_simulate(c, 1), EARSHOT_OK);
  earshot_ir* ir = nullptr;
  EXPECT_EQ(earshot_source_get_ir(a, &ir), EARSHOT_ERROR_NOT_FOUND);
  ASSERT_EQ(earshot_source_get_ir(b, &ir), EARSHOT_OK);
  earshot_ir_info info;
  info.struct_size = sizeof(info);
  ASSERT_EQ(earshot_ir_get_info(ir, &info), EARSHOT_OK);
  EXPECT_EQ(info.simulation, 3u);
  // Its age: from the poses of its simulation to now, growing (issue 16).
  EXPECT_GE(info.age_seconds, 0.0);
  EXPECT_LT(info.age_seconds, 60.0);
  const double first = info.age_seconds;
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_EQ(earshot_ir_get_info(ir, &info), EARSHOT_OK);
  EXPECT_GE(info.age_seconds, first + 0.015);
  earshot_ir_release(ir);
  // Equal priorities: round robin.
  s.priority = 0;
  ASSERT_EQ(earshot_source_set_settings(b, &s), EARSHOT_OK);
  ASSERT_EQ(earshot_simulate(c, 1), EARSHOT_OK);
  ASSERT_EQ(earshot_simulate(c, 1), EARSHOT_OK);
  ASSERT_EQ(earshot_source_get_ir(a, &ir), EARSHOT_OK);
  earshot_ir_release(ir);
  earshot_source_release(a);
  earshot_source_release(b);
  earshot_context_release(c);
}

TEST(CapiControls, BadValuesAreRefused) {
  World w(false);
  const earshot_source_settings good = defaults();
  auto refused = [&](earshot_source_settings s) { return earshot_source_set_settings(w.src, &s); };
  earshot_source_settings s = good;
  s.direct_gain_db = NAN;
  EXPECT_EQ(refused(s), EARSHOT_ERROR_INVALID_ARGUMENT);
  s = good;
  s.reflections_gain_db = 41;
  EXPECT_EQ(refused(s), EARSHOT_ERROR_INVALID_ARGUMENT);
  s = good;
  earshot::capi::test::storeRaw(s.distance_model, 9);
  EXPECT_EQ(refused(s), EARSHOT_ERROR_INVALID_ARGUMENT);
  s = good;
  s.min_distance = 0;
  EXPECT_EQ(refused(s), EARSHOT_ERROR_INVALID_ARGUMENT);
  s = good;
  s.max_distance = 0.5f;  // below min
  EXPECT_EQ(refused(s), EARSHOT_ERROR_INVALID_ARGUMENT);
  s = good;
  s.rolloff = -1;
  EXPECT_EQ(refused(s), EARSHOT_ERROR_INVALID_ARGUMENT);
  s = good;
  earshot::capi::test::storeRaw(s.occlusion, -3);
  EXPECT_EQ(refused(s), EARSHOT_ERROR_INVALID_ARGUMENT);
  s = good;
  s.radius = INFINITY;
  EXPECT_EQ(refused(s), EARSHOT_ERROR_INVALID_ARGUMENT);
  s = good;
  s.transmission = 2;
  EXPECT_EQ(refused(s), EARSHOT_ERROR_INVALID_ARGUMENT);
  s = good;
  s.direct = EARSHOT_DIRECT_IN_IMPULSE_RESPONSE;  // fixed at creation
  EXPECT_EQ(refused(s), EARSHOT_ERROR_INVALID_ARGUMENT);
  s = good;
  s.struct_size = 8;
  EXPECT_EQ(refused(s), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_source_set_settings(nullptr, &good), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_source_set_settings(w.src, nullptr), EARSHOT_ERROR_INVALID_ARGUMENT);
  // Nothing changed.
  const earshot_source_settings now = w.get();
  EXPECT_EQ(now.distance_model, EARSHOT_DISTANCE_PHYSICAL);
  EXPECT_EQ(now.transmission, 1);
  // C++: the same through Source.
  earshot::ContextSettings cs;
  cs.max_sources = 1;
  earshot::Context context(cs);
  earshot::Source source(context);
  earshot::SourceSettings ss = source.settings();
  ss.priority = 3;
  ss.occlusion = EARSHOT_OCCLUSION_VOLUMETRIC;
  ss.directivity_per_band = 1;
  for (int b = 0; b < EARSHOT_BAND_COUNT; ++b) ss.directivity_band_alpha[b] = 0.1f * float(b);
  source.setSettings(ss);
  EXPECT_EQ(source.settings().priority, 3);
  EXPECT_EQ(source.settings().directivity_per_band, 1);
  EXPECT_FLOAT_EQ(source.settings().directivity_band_alpha[6], 0.6f);
  ss.directivity_band_alpha[2] = 2.0f;
  EXPECT_THROW(source.setSettings(ss), earshot::Error);
  ss.directivity_band_alpha[2] = 0.2f;
  ss.rolloff = -2;
  EXPECT_THROW(source.setSettings(ss), earshot::Error);
}

// earshot_source_create_at: a source created where it is plays from there
// from its first block (the same output as one created and placed before
// the audio thread ran); a bad pose creates nothing.
TEST(CapiControls, ASourceCreatedWhereItIsPlaysFromThereAndABadPoseCreatesNothing) {
  const earshot_vec3 at{3, 0, -2}, facing{0, 0, 1};  // a cardioid not facing the default way (0, 0, -1)
  earshot_source_settings ss = defaults();
  ss.directivity_alpha = 0.5f;
  // 0.2 s of the output from the source's first block, in which it starts
  // a 50 ms burst (free field: the direct sound alone).
  auto render = [&](bool createdAt) {
    earshot_context_settings cs = fastSettings();
    cs.max_sources = 1;
    earshot_context* c = nullptr;
    EXPECT_EQ(earshot_context_create(&cs, &c), EARSHOT_OK);
    EXPECT_EQ(earshot_context_set_listener(c, {1, 0, 0}, {0, 0, -1}, {0, 1, 0}), EARSHOT_OK);
    earshot_source* src = nullptr;
    if (createdAt) {
      EXPECT_EQ(earshot_source_create_at(c, &ss, at, facing, &src), EARSHOT_OK) << earshot_last_error_message();
    } else {
      EXPECT_EQ(earshot_source_create(c, &ss, &src), EARSHOT_OK);
      EXPECT_EQ(earshot_source_set_position(src, at), EARSHOT_OK);
      EXPECT_EQ(earshot_source_set_orientation(src, facing), EARSHOT_OK);
    }
    std::vector<float> dry(256), l(256), r(256), out;
    const float* in[1] = {dry.data()};
    uint32_t seed = 12345;
    for (int b = 0; b < 38; ++b) {
      for (float& x : dry) {
        seed = seed * 1664525u + 1013904223u;
        x = b < 9 ? float(seed >> 8) / float(1u << 24) - 0.5f : 0.0f;
      }
      EXPECT_EQ(earshot_process(c, in, 1, l.data(), r.data(), 256), EARSHOT_OK);
      out.insert(out.end(), l.begin(), l.end());
      out.insert(out.end(), r.begin(), r.end());
    }
    earshot_source_release(src);
    earshot_context_release(c);
    return out;
  };
  const std::vector<float> placed = render(false), createdAt = render(true);
  double e = 0;
  for (float x : placed) e += double(x) * x;
  EXPECT_GT(e, 0.0);
  EXPECT_EQ(createdAt, placed) << "the same samples";

  earshot_context_settings cs = fastSettings();
  earshot_context* c = nullptr;
  ASSERT_EQ(earshot_context_create(&cs, &c), EARSHOT_OK);
  auto created = [&](earshot_vec3 p, earshot_vec3 f, const earshot_source_settings* settings) {
    earshot_source* src = reinterpret_cast<earshot_source*>(&cs);  // not left as it was on failure
    const earshot_status st = earshot_source_create_at(c, settings, p, f, &src);
    EXPECT_EQ(src, nullptr) << "a refused source is not handed out";
    if (src) earshot_source_release(src);
    earshot_context_info info;
    info.struct_size = sizeof(info);
    EXPECT_EQ(earshot_context_get_info(c, &info), EARSHOT_OK);
    EXPECT_EQ(info.active_sources, 0u) << "and nothing was created";
    return st;
  };
  EXPECT_EQ(created({NAN, 0, 0}, facing, nullptr), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(created({0, INFINITY, 0}, facing, nullptr), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(created({0, 0, 2e6f}, facing, nullptr), EARSHOT_ERROR_OUT_OF_RANGE);
  EXPECT_EQ(created(at, {0, 0, 0}, nullptr), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(created(at, {0, NAN, 1}, nullptr), EARSHOT_ERROR_INVALID_ARGUMENT);
  earshot_source_settings bad = defaults();
  bad.rolloff = -1;
  EXPECT_EQ(created(at, facing, &bad), EARSHOT_ERROR_INVALID_ARGUMENT);
  bad = defaults();
  bad.struct_size = 8;
  EXPECT_EQ(created(at, facing, &bad), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(earshot_source_create_at(c, nullptr, at, facing, nullptr), EARSHOT_ERROR_INVALID_ARGUMENT);
  earshot_source* none = nullptr;
  EXPECT_EQ(earshot_source_create_at(nullptr, nullptr, at, facing, &none), EARSHOT_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(none, nullptr);
  earshot_context_release(c);

  // C++: the same through Source's constructor.
  earshot::ContextSettings cpp;
  cpp.max_sources = 1;
  earshot::Context context(cpp);
  EXPECT_THROW(earshot::Source(context, earshot_vec3{0, 0, 0}, earshot_vec3{0, 0, 0}), earshot::Error);
  earshot::Source source(context, at, facing);
  EXPECT_EQ(source.index(), 0u);
}

}  // namespace
