#include <algorithm>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "earshot/materials/material.h"
#include "earshot/scene/gltf_loader.h"

namespace earshot {
namespace {

// Positions are stored as float after double-precision transforms; values
// here are below 20 m, so float rounding is below 2e-6 m. 1e-5 m leaves margin.
constexpr float kTol = 1e-5f;

std::string data(const std::string& name) { return std::string(EARSHOT_TEST_DATA_DIR) + "/gltf/" + name; }

uint32_t idOf(const std::string& name) {
  auto id = defaultMaterials().find(name);
  EXPECT_TRUE(id.has_value()) << name;
  return id.value_or(0);
}

void expectVertex(const TriangleMesh& m, size_t tri, int corner, Vec3f expected) {
  const Vec3f v = m.positions[m.triangles[tri][corner]];
  EXPECT_NEAR(v.x, expected.x, kTol) << "triangle " << tri << " corner " << corner;
  EXPECT_NEAR(v.y, expected.y, kTol) << "triangle " << tri << " corner " << corner;
  EXPECT_NEAR(v.z, expected.z, kTol) << "triangle " << tri << " corner " << corner;
}

Vec3f normalOf(const TriangleMesh& m, size_t tri) {
  const auto& t = m.triangles[tri];
  return cross(m.positions[t[1]] - m.positions[t[0]], m.positions[t[2]] - m.positions[t[0]]);
}

bool anyWarningContains(const std::vector<std::string>& w, const std::string& s) {
  return std::any_of(w.begin(), w.end(), [&](const std::string& x) { return x.find(s) != std::string::npos; });
}

// The triangle (0,0,0) (1,0,0) (0,1,0) placed by four nodes of the default
// scene; the node of the second scene must not appear.
void checkTransforms(const GltfLoadResult& r) {
  const TriangleMesh& m = r.mesh;
  ASSERT_EQ(m.triangleCount(), 4u);
  ASSERT_EQ(m.materialIds.size(), 4u);
  // parent: translation (10, 0, 0).
  expectVertex(m, 0, 0, {10, 0, 0});
  expectVertex(m, 0, 1, {11, 0, 0});
  expectVertex(m, 0, 2, {10, 1, 0});
  // child of parent: scale 2, then 90 degrees about +z, then the parent's move.
  expectVertex(m, 1, 0, {10, 0, 0});
  expectVertex(m, 1, 1, {10, 2, 0});
  expectVertex(m, 1, 2, {8, 0, 0});
  // matrix node (column-major): x scaled by 3, moved to z = 5.
  expectVertex(m, 2, 1, {3, 0, 5});
  expectVertex(m, 2, 2, {0, 1, 5});
  // mirror x: vertices mirrored, winding reversed so the normal stays +z.
  for (size_t t = 0; t < 4; ++t) EXPECT_GT(normalOf(m, t).z, 0.0f) << t;
  const auto& mt = m.triangles[3];
  std::vector<float> xs = {m.positions[mt[0]].x, m.positions[mt[1]].x, m.positions[mt[2]].x};
  std::sort(xs.begin(), xs.end());
  EXPECT_NEAR(xs[0], -1.0f, kTol);
  for (const auto& p : m.positions) EXPECT_LT(p.x, 50.0f);  // the other scene's node sits at x = 100
  for (uint32_t id : m.materialIds) EXPECT_EQ(id, idOf("concrete"));
  EXPECT_TRUE(r.warnings.empty());
}

TEST(GltfLoad, NodeTransformsComposeDownTheHierarchy) {
  auto r = loadGltf(data("transforms.gltf"), defaultMaterials());
  ASSERT_TRUE(r.isOk()) << r.status().message();
  checkTransforms(*r);
}

TEST(GltfLoad, GlbGivesTheSameMeshAsGltf) {
  auto r = loadGltf(data("transforms.glb"), defaultMaterials());
  ASSERT_TRUE(r.isOk()) << r.status().message();
  checkTransforms(*r);
  auto a = loadGltf(data("transforms.gltf"), defaultMaterials());
  ASSERT_TRUE(a.isOk());
  EXPECT_EQ(a->mesh.triangles, r->mesh.triangles);
  ASSERT_EQ(a->mesh.positions.size(), r->mesh.positions.size());
  for (size_t i = 0; i < a->mesh.positions.size(); ++i) EXPECT_EQ(a->mesh.positions[i], r->mesh.positions[i]);
}

TEST(GltfLoad, MaterialMappingPrecedenceMapThenExtrasThenNameThenDefault) {
  const std::map<std::string, std::string> map = {{"wall_a", "brick"}, {"typo_target", "no_such_material"}};
  auto r = loadGltf(data("mapping.gltf"), defaultMaterials(), map);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const auto& ids = r->mesh.materialIds;
  ASSERT_EQ(ids.size(), 6u);
  EXPECT_EQ(ids[0], idOf("brick"));         // map beats extras (glass_window)
  EXPECT_EQ(ids[1], idOf("carpet_thick"));  // extras beat the name "concrete"
  EXPECT_EQ(ids[2], idOf("marble"));        // own name
  EXPECT_EQ(ids[3], 0u);                    // "mystery": default
  EXPECT_EQ(ids[4], 0u);                    // no material: default
  EXPECT_EQ(ids[5], 0u);                    // map to an unknown name, own name unknown: default
  const auto& w = r->warnings;
  EXPECT_TRUE(anyWarningContains(w, "glTF material \"mystery\" maps to no acoustic material")) << w.size();
  EXPECT_TRUE(anyWarningContains(w, "mesh \"mapped\" primitive 4 has no material"));
  EXPECT_TRUE(anyWarningContains(w, "unknown acoustic material \"no_such_material\""));
  EXPECT_TRUE(anyWarningContains(w, "glTF material \"typo_target\" maps to no acoustic material"));
  EXPECT_FALSE(anyWarningContains(w, "wall_a"));
  EXPECT_EQ(w.size(), 4u);

  auto noMap = loadGltf(data("mapping.gltf"), defaultMaterials());
  ASSERT_TRUE(noMap.isOk());
  EXPECT_EQ(noMap->mesh.materialIds[0], idOf("glass_window"));  // without the map, extras win
}

// A file's names reach warnings and errors quoted on one line (quotedName):
// a newline or a terminal escape in a glTF material name or a material
// map's key must not split the line or reach the terminal.
TEST(GltfLoad, NamesFromTheFileStayOnOneLineInWarningsAndErrors) {
  std::ifstream in(data("mapping.gltf"));
  nlohmann::json j = nlohmann::json::parse(in);
  j["materials"][3]["name"] = "mys\ntery\x1b[2J";
  j["materials"][4]["name"] = std::string(5000, 'n');
  const std::string dir = ::testing::TempDir();
  const std::string path = dir + "/names_on_one_line.gltf";
  std::ofstream(path) << j.dump();
  auto r = loadGltf(path, defaultMaterials());
  ASSERT_TRUE(r.isOk()) << r.status().message();
  ASSERT_FALSE(r->warnings.empty());
  for (const std::string& w : r->warnings) {
    EXPECT_EQ(w.find_first_of("\n\r\x1b"), std::string::npos) << w;
    EXPECT_LT(w.size(), path.size() + 200) << w;
  }
  EXPECT_TRUE(anyWarningContains(r->warnings, "glTF material \"mys\\ntery\\u001b[2J\" maps to no acoustic material"));
  EXPECT_TRUE(anyWarningContains(r->warnings, "glTF material \"" + std::string(kQuotedNameBytes, 'n') + "\"... maps"));

  const std::string mapPath = dir + "/names_on_one_line_map.json";
  std::ofstream(mapPath) << R"({"wall_a": "brick", "a\nFAKE LOG LINE": 5})";
  auto map = loadMaterialMap(mapPath);
  ASSERT_FALSE(map.isOk());
  EXPECT_EQ(map.status().message(), mapPath + ": \"a\\nFAKE LOG LINE\" must map to a material name (string)");
}

TEST(GltfLoad, IndexTypesAndNonIndexedLoadOtherModesAreSkippedWithWarnings) {
  auto r = loadGltf(data("modes.gltf"), defaultMaterials());
  ASSERT_TRUE(r.isOk()) << r.status().message();
  // u8: 1, u16: 2, u32: 1, non-indexed: 2 triangles.
  EXPECT_EQ(r->mesh.triangleCount(), 6u);
  const auto& w = r->warnings;
  ASSERT_EQ(w.size(), 3u);
  EXPECT_TRUE(anyWarningContains(w, "mesh \"mixed\" primitive 4: mode LINES (1) skipped"));
  EXPECT_TRUE(anyWarningContains(w, "mesh \"mixed\" primitive 5: mode POINTS (0) skipped"));
  EXPECT_TRUE(anyWarningContains(w, "mesh \"mixed\" primitive 6: mode TRIANGLE_STRIP (5) skipped"));
  // The non-indexed primitive's second triangle lies at z = 1.
  expectVertex(r->mesh, 5, 0, {0, 0, 1});
  expectVertex(r->mesh, 5, 2, {0, 1, 1});
}

TEST(GltfLoad, SparseAccessorOverridesAVertex) {
  auto r = loadGltf(data("sparse.gltf"), defaultMaterials());
  ASSERT_TRUE(r.isOk()) << r.status().message();
  ASSERT_EQ(r->mesh.triangleCount(), 1u);
  expectVertex(r->mesh, 0, 1, {1, 0, 0});
  expectVertex(r->mesh, 0, 2, {0, 5, 0});
}

TEST(GltfLoad, NormalizedIntegerPositionsAreScaledToUnitRange) {
  auto r = loadGltf(data("normalized.gltf"), defaultMaterials());
  ASSERT_TRUE(r.isOk()) << r.status().message();
  ASSERT_EQ(r->mesh.triangleCount(), 1u);
  // u16 65535 -> 1.0 (glTF normalized unsigned: c / 65535), then node scale 2.
  expectVertex(r->mesh, 0, 1, {2, 0, 0});
  expectVertex(r->mesh, 0, 2, {0, 2, 0});
}

TEST(GltfLoad, WithoutScenesAllRootNodesAndTheirChildrenLoad) {
  auto r = loadGltf(data("no_scene.gltf"), defaultMaterials());
  ASSERT_TRUE(r.isOk()) << r.status().message();
  ASSERT_EQ(r->mesh.triangleCount(), 3u);
  std::vector<float> zs;
  for (const auto& t : r->mesh.triangles) zs.push_back(r->mesh.positions[t[0]].z);
  std::sort(zs.begin(), zs.end());
  EXPECT_EQ(zs, (std::vector<float>{0, 1, 2}));
}

TEST(GltfLoad, HostileOrBrokenFilesGiveOneLineErrorsNamingFileAndProblem) {
  struct Case {
    const char* file;
    const char* expected;
  };
  const Case cases[] = {
      {"huge_count.gltf", "1000000000000 elements do not fit in buffer view"},
      {"view_outside_buffer.gltf", "lies outside its buffer"},
      {"accessor_outside_view.gltf", "do not fit in buffer view"},
      {"index_out_of_range.gltf", "index 9 at position 2 is beyond its 3 vertices"},
      {"node_cycle.gltf", "is its own ancestor"},
      {"bad_material_index.gltf", "material 7 does not exist"},
      {"nan_vertex.gltf", "mesh \"bad_mesh\" primitive 0: vertex 1"},
      {"malformed.gltf", "invalid glTF"},
      {"truncated.glb", "invalid glTF"},
      {"buffer_length_lie.gltf", "invalid glTF"},
  };
  for (const auto& c : cases) {
    auto r = loadGltf(data(c.file), defaultMaterials());
    ASSERT_FALSE(r.isOk()) << c.file;
    const std::string& msg = r.status().message();
    EXPECT_EQ(msg.rfind(data(c.file) + ": ", 0), 0u) << msg;
    EXPECT_NE(msg.find(c.expected), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    EXPECT_LT(msg.size(), 400u) << msg;  // tinygltf may quote a whole data URI; we cut it
  }
}

TEST(GltfLoad, NanVertexNamesTheMeshAndVertex) {
  auto r = loadGltf(data("nan_vertex.gltf"), defaultMaterials());
  ASSERT_FALSE(r.isOk());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("vertex 1 = (nan, 0, 0) is not finite"), std::string::npos)
      << r.status().message();
}

TEST(GltfLoad, MissingFileIsNotFound) {
  auto r = loadGltf(data("does_not_exist.gltf"), defaultMaterials());
  ASSERT_FALSE(r.isOk());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  EXPECT_NE(r.status().message().find("does_not_exist.gltf"), std::string::npos);
}

// ---- samples/ -------------------------------------------------------------

std::map<std::string, std::string> readMap(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  const auto j = nlohmann::json::parse(in, nullptr, false);
  EXPECT_FALSE(j.is_discarded()) << path;
  std::map<std::string, std::string> m;
  if (j.is_object())
    for (const auto& item : j.items()) m[item.key()] = item.value().get<std::string>();
  return m;
}

struct Sample {
  std::string dir, file;
};

GltfLoadResult loadSample(const Sample& s) {
  const std::string base = std::string(EARSHOT_SOURCE_DIR) + "/samples/" + s.dir + "/";
  const auto map = readMap(base + "materials_map.json");
  for (const auto& kv : map) EXPECT_TRUE(defaultMaterials().find(kv.second).has_value()) << s.dir << ": " << kv.second;
  auto r = loadGltf(base + s.file, defaultMaterials(), map);
  EXPECT_TRUE(r.isOk()) << r.status().message();
  if (!r) return {};
  EXPECT_TRUE(r->warnings.empty()) << s.dir << ": " << (r->warnings.empty() ? "" : r->warnings[0]);
  return std::move(r).value();
}

TEST(Samples, EverySampleLoadsWithEveryMaterialMapped) {
  for (const Sample& s : {Sample{"shoebox", "shoebox.gltf"}, Sample{"furnished_room", "furnished_room.glb"},
                          Sample{"two_rooms", "two_rooms.gltf"}, Sample{"hall", "hall.glb"},
                          Sample{"outdoor", "outdoor.gltf"}}) {
    const GltfLoadResult r = loadSample(s);
    EXPECT_GT(r.mesh.triangleCount(), 0u) << s.dir;
    for (uint32_t id : r.mesh.materialIds) EXPECT_NE(id, 0u) << s.dir;  // nothing falls back to the default
  }
}

TEST(Samples, ShoeboxIsTheReferenceRoomWithOneMaterialPerWall) {
  const GltfLoadResult r = loadSample({"shoebox", "shoebox.gltf"});
  ASSERT_EQ(r.mesh.triangleCount(), 12u);
  Vec3f lo{1e9f, 1e9f, 1e9f}, hi{-1e9f, -1e9f, -1e9f};
  for (const auto& p : r.mesh.positions) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  EXPECT_EQ(lo, (Vec3f{0, 0, 0}));
  EXPECT_EQ(hi, (Vec3f{10, 7, 3}));
  // Normals point into the room: the centre lies on the positive side of every triangle.
  const Vec3f centre{5, 3.5f, 1.5f};
  for (size_t t = 0; t < 12; ++t)
    EXPECT_GT(dot(normalOf(r.mesh, t), centre - r.mesh.positions[r.mesh.triangles[t][0]]), 0.0f) << t;
  // Six different materials, two triangles each.
  std::vector<uint32_t> ids = r.mesh.materialIds;
  std::sort(ids.begin(), ids.end());
  EXPECT_EQ(std::unique(ids.begin(), ids.end()) - ids.begin(), 6);
}

TEST(Samples, FurnishedRoomHas22kTo26kTriangles) {
  const GltfLoadResult r = loadSample({"furnished_room", "furnished_room.glb"});
  EXPECT_GE(r.mesh.triangleCount(), 22000u);
  EXPECT_LE(r.mesh.triangleCount(), 26000u);
}

}  // namespace
}  // namespace earshot
