// The C++ API (earshot.hpp): RAII handles over the C API, errors as
// exceptions, spans over the caller's arrays.
#include <gtest/gtest.h>

#include <algorithm>

#include <array>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "capi_fixture.h"
#include "earshot/earshot.hpp"

namespace earshot::capi::test {

TEST(CppApi, SmokeTestFromGeometryToBinauralAudio) {
  ContextSettings settings;
  const earshot_context_settings fast = fastSettings();
  static_cast<earshot_context_settings&>(settings) = fast;
  Context context(settings);
  ASSERT_TRUE(context);
  EXPECT_EQ(context.info().max_sources, 4u);

  Scene scene(context);
  const BoxData room = box(0, 0, 0, 8, 6, 3);
  Mesh walls(context, room.vertices, room.indices, {"brick"}, {}, EARSHOT_MESH_STATIC, "walls");
  const BoxData slab = box(0, 0, 0, 0.05f, 1, 2);
  const std::vector<uint32_t> perTriangle(slab.indices.size() / 3, 1);  // all "metal"
  Mesh door(context, slab.vertices, slab.indices, {"door_wood", "metal"}, perTriangle, EARSHOT_MESH_MOVABLE, "door");
  scene.add(walls);
  scene.add(door);
  // The door hangs 1 m above the listener (y is up here: x 4 - 4.05, y 4 -
  // 5); at y = 3 it put the listener on its edge and grazed the direct path
  // (the shared trace, whose rays leave the listener, then counted the
  // door's surface at the listener as a reflection as early as the direct).
  door.setTransform({1, 0, 0, 4, 0, 1, 0, 4, 0, 0, 1, 0});
  EXPECT_EQ(door.transform()[3], 4.0f);
  scene.commit();
  context.setScene(scene);
  EXPECT_EQ(scene.stats().mesh_count, 2u);
  Mesh found = scene.findMesh("door");
  EXPECT_EQ(found.get(), door.get());

  context.setListener(vec3(4, 3, 1.5f), vec3(0, 0, -1), vec3(0, 1, 0));
  Source source(context);
  source.setPosition(vec3(6, 3, 1.5f));  // to the listener's right (forward -z, up +y)
  source.setGainDb(-6.0f);
  context.simulate();
  // Nothing between it and the listener (the door hangs above): clear.
  const earshot_source_occlusion occlusion = source.occlusion();
  EXPECT_EQ(occlusion.simulated, 1u);
  EXPECT_EQ(occlusion.audible, 1u);
  for (float t : occlusion.transmission) EXPECT_EQ(t, 1.0f);

  // One click: the direct sound (2 m, the strongest arrival; the first
  // reflection comes 4.5 ms later) is louder in the near ear. (The whole
  // output's energy is mostly the reverberation's, whose noise differs
  // between the ears by chance.)
  std::vector<float> dry(8192, 0.0f), left(8192), right(8192);
  dry[0] = 1.0f;
  std::vector<const float*> inputs(source.index() + 1, nullptr);
  inputs[source.index()] = dry.data();
  ASSERT_EQ(context.process(inputs, left.data(), right.data(), dry.size()), EARSHOT_OK);
  EXPECT_TRUE(allFinite(left) && allFinite(right));
  size_t peak = 0;
  for (size_t i = 0; i < left.size(); ++i)
    if (left[i] * left[i] + right[i] * right[i] > left[peak] * left[peak] + right[peak] * right[peak]) peak = i;
  const size_t from = peak > 48 ? peak - 48 : 0, to = std::min(left.size(), peak + 48);
  const std::vector<float> directLeft(left.begin() + long(from), left.begin() + long(to)),
      directRight(right.begin() + long(from), right.begin() + long(to));
  EXPECT_GT(energy(directRight), 2.0 * energy(directLeft));  // the near ear, by more than 3 dB

  // Errors throw earshot::Error with the C status and message.
  try {
    source.setGainDb(NAN);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.status(), EARSHOT_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(e.what()).find("earshot_source_set_gain_db"), std::string::npos) << e.what();
  }
  EXPECT_THROW(scene.findMesh("window"), Error);
  EXPECT_THROW(Mesh(context, std::vector<float>{0, 0}, std::vector<uint32_t>{0, 0, 0}, {"brick"}), Error);

  // Copies share the object (a reference each); moves transfer; empty handles throw.
  Source copy = source;
  EXPECT_EQ(copy.get(), source.get());
  Source moved = std::move(source);
  EXPECT_FALSE(source);  // NOLINT(bugprone-use-after-move): moved-from handles are empty by contract
  EXPECT_THROW(source.index(), Error);
  EXPECT_EQ(moved.index(), copy.index());
  moved.reset();
  EXPECT_NO_THROW(copy.setPosition(vec3(5, 3, 1.5f)));  // still alive through `copy`
  EXPECT_EQ(context.info().active_sources, 1u);
  copy.reset();
  EXPECT_EQ(context.info().active_sources, 0u);

  // Spans view arrays of every kind without copying.
  float carr[6] = {1, 2, 3, 4, 5, 6};
  std::array<float, 3> arr{7, 8, 9};
  Span<const float> a(carr), b(arr), c(dry);
  EXPECT_EQ(a.size(), 6u);
  EXPECT_EQ(b[2], 9.0f);
  EXPECT_EQ(c.data(), dry.data());
  const float* cptrs[2] = {dry.data(), nullptr};
  Span<const float* const> d(cptrs);
  EXPECT_EQ(d.size(), 2u);
}

TEST(CppApi, ContextCreationErrorsThrow) {
  ContextSettings settings;
  settings.sample_rate_hz = -1;
  EXPECT_THROW(Context{settings}, Error);
  settings = ContextSettings();
  settings.hrtf_path = "/nonexistent.sofa";
  try {
    Context c(settings);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_NE(e.status(), EARSHOT_OK);
    EXPECT_NE(std::string(e.what()).find("/nonexistent.sofa"), std::string::npos) << e.what();
  }
}

}  // namespace earshot::capi::test
