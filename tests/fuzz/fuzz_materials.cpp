// libFuzzer target: parseMaterials on arbitrary text (nlohmann_json parse,
// key validation, band interpolation); the tolerance and material-map
// parsers on the same text.
#include <cmath>
#include <cstdint>
#include <string>

#include "earshot/analysis/compare.h"
#include "earshot/materials/material.h"
#include "earshot/scene/gltf_loader.h"
#include "fuzz_temp_file.h"

namespace {

// The other small JSON files a user hands earshot, on the same text: a
// tolerance file (earshot compare) and a glTF material map (--material-map).
void otherJsonFiles(const std::string& text, const uint8_t* data, size_t size) {
  auto tolerance = earshot::analysis::parseTolerance(text, "fuzz.json");
  if (!tolerance.isOk()) {
    EARSHOT_FUZZ_CHECK(earshot::fuzz::oneLine(tolerance.status().message()));
  } else {
    for (size_t m = 0; m < tolerance->limitJnd.size(); ++m)
      for (double limit : tolerance->limitJnd[m]) EARSHOT_FUZZ_CHECK(std::isfinite(limit) && limit > 0);
  }
  static earshot::fuzz::TempFile file("map.json");
  auto map = earshot::loadMaterialMap(file.write(data, size));
  if (!map.isOk()) EARSHOT_FUZZ_CHECK(earshot::fuzz::oneLine(map.status().message()));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  otherJsonFiles(text, data, size);
  auto result = earshot::parseMaterials(text, "fuzz.json");
  if (!result.isOk()) {
    EARSHOT_FUZZ_CHECK(earshot::fuzz::oneLine(result.status().message()));
    return 0;
  }
  // Accepted tables keep the documented invariants in every engine band.
  const earshot::MaterialTable& table = result.value();
  EARSHOT_FUZZ_CHECK(table.size() >= 1);
  for (const auto& m : table.all()) {
    for (size_t b = 0; b < m.absorption.size(); ++b) {
      const float a = m.absorption[b], s = m.scattering[b], t = m.transmission[b];
      EARSHOT_FUZZ_CHECK(std::isfinite(a) && a >= 0.0f && a <= 1.0f);
      EARSHOT_FUZZ_CHECK(std::isfinite(s) && s >= 0.0f && s <= 1.0f);
      EARSHOT_FUZZ_CHECK(std::isfinite(t) && t >= 0.0f && t <= 1.0f);
      // Interpolation between checked bands keeps t <= a up to float rounding.
      EARSHOT_FUZZ_CHECK(t <= a + 1e-6f);
    }
  }
  return 0;
}
