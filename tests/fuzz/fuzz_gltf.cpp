// libFuzzer target: loadGltf (tinygltf parse + earshot's accessor/index
// checks) on arbitrary bytes, as .gltf text or .glb (told by magic bytes).
// loadGltf takes a path, so each input is written to a private temp file.
#include <cmath>
#include <cstdint>

#include "earshot/scene/gltf_loader.h"
#include "fuzz_temp_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static earshot::fuzz::TempFile file("in.gltf");
  static const earshot::MaterialTable& materials = earshot::defaultMaterials();
  const std::string& path = file.write(data, size);
  auto result = earshot::loadGltf(path, materials, {{"wall", "brick"}, {"floor", "no_such_material"}});
  if (!result.isOk()) {
    EARSHOT_FUZZ_CHECK(earshot::fuzz::oneLine(result.status().message()));  // errors say what is wrong
    return 0;
  }
  // What the loader accepts must be safe to trace: the header's promises.
  for (const std::string& w : result.value().warnings) EARSHOT_FUZZ_CHECK(earshot::fuzz::oneLine(w));
  const earshot::TriangleMesh& mesh = result.value().mesh;
  EARSHOT_FUZZ_CHECK(mesh.materialIds.size() == mesh.triangles.size());
  for (const auto& p : mesh.positions)
    EARSHOT_FUZZ_CHECK(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (uint32_t v : mesh.triangles[t]) EARSHOT_FUZZ_CHECK(v < mesh.positions.size());
    EARSHOT_FUZZ_CHECK(mesh.materialIds[t] < materials.size());
  }
  return 0;
}
