#pragma once
// Shared by the C API tests: small, fast context settings and a box room
// built through the API itself.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>
#include <vector>

#include "earshot/earshot.h"

namespace earshot::capi::test {

/** Fast settings: few rays, short IRs, 4 slots, 2 threads, the default HRTF. */
inline earshot_context_settings fastSettings() {
  earshot_context_settings s;
  earshot_context_settings_init(&s);
  s.max_sources = 4;
  s.rays = 1000;
  s.bounces = 8;
  s.image_source_order = 1;
  s.max_ir_seconds = 0.5;
  s.threads = 2;
  return s;
}

/** An axis-aligned box [lo, hi] with inward-facing triangles (12). */
struct BoxData {
  std::vector<float> vertices;
  std::vector<uint32_t> indices;
};

inline BoxData box(float x0, float y0, float z0, float x1, float y1, float z1) {
  BoxData b;
  b.vertices = {x0, y0, z0, x1, y0, z0, x1, y1, z0, x0, y1, z0, x0, y0, z1, x1, y0, z1, x1, y1, z1, x0, y1, z1};
  // Two triangles per face, wound so that the normals point inwards.
  b.indices = {0, 1, 2, 0, 2, 3,   // floor (normal +z)
               4, 6, 5, 4, 7, 6,   // ceiling (normal -z)
               0, 4, 5, 0, 5, 1,   // south y = y0 (normal +y)
               3, 2, 6, 3, 6, 7,   // north y = y1 (normal -y)
               0, 3, 7, 0, 7, 4,   // west x = x0 (normal +x)
               1, 5, 6, 1, 6, 2};  // east x = x1 (normal -x)
  return b;
}

/** A mesh made through the API; `material` from the default set. */
inline earshot_mesh* makeMesh(earshot_context* c, const BoxData& b, const char* material, earshot_mesh_motion motion,
                              const char* name) {
  const char* names[] = {material};
  earshot_mesh_settings s;
  earshot_mesh_settings_init(&s);
  s.name = name;
  s.vertices = b.vertices.data();
  s.vertex_count = b.vertices.size() / 3;
  s.indices = b.indices.data();
  s.triangle_count = b.indices.size() / 3;
  s.material_names = names;
  s.material_count = 1;
  s.motion = motion;
  earshot_mesh* m = nullptr;
  EXPECT_EQ(earshot_mesh_create(c, &s, &m), EARSHOT_OK) << earshot_last_error_message();
  return m;
}

/** Stores any integer in a C enum field, as a C caller may (a C++ cast to the
 *  enum would be undefined for values outside its enumerators). */
template <class E>
void storeRaw(E& field, std::underlying_type_t<E> value) {
  std::memcpy(&field, &value, sizeof(field));
}

inline double energy(const std::vector<float>& x) {
  double e = 0;
  for (float v : x) e += double(v) * v;
  return e;
}

inline bool allFinite(const std::vector<float>& x) {
  for (float v : x)
    if (!std::isfinite(v)) return false;
  return true;
}

}  // namespace earshot::capi::test
