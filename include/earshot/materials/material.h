#pragma once
/** @file Acoustic materials: per-band energy fractions, and the table that
 *  scenes index by material id. File format: DESIGN.md "Materials file". */
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "earshot/core/bands.h"
#include "earshot/core/status.h"

namespace earshot {

struct Material {
  std::string name;
  BandArray absorption = filledBands(0.1f);    ///< energy fraction absorbed per reflection, [0, 1]
  BandArray scattering = filledBands(0.1f);    ///< fraction of reflected energy scattered diffusely, [0, 1]
  BandArray transmission = filledBands(0.0f);  ///< energy fraction passing through the surface, [0, 1]
};

/** Materials by id (their index). Id 0 is always the default material, given
 *  to surfaces whose glTF material maps to nothing. */
class MaterialTable {
 public:
  MaterialTable();  ///< just the built-in default material at id 0
  /** Adds or replaces (by name) a material; returns its id. */
  uint32_t add(Material m);
  std::optional<uint32_t> find(const std::string& name) const;
  const Material& operator[](uint32_t id) const { return mMaterials[id]; }
  size_t size() const { return mMaterials.size(); }
  const std::vector<Material>& all() const { return mMaterials; }
  /** Makes an existing material the default (copied to id 0 under its own name). */
  Status setDefault(const std::string& name);

 private:
  std::vector<Material> mMaterials;
};

/** Parses a materials JSON text; `sourceName` (a file name) prefixes errors:
 *  `file: material "x": absorption[3] = 1.7 is outside [0, 1]`. Values given
 *  at other centre frequencies (bands_hz) are interpolated to the engine's bands. */
Result<MaterialTable> parseMaterials(const std::string& jsonText, const std::string& sourceName);
/** Reads and parses a materials file. */
Result<MaterialTable> loadMaterials(const std::string& path);
/** The library's default set (materials/default.json, compiled in). */
const MaterialTable& defaultMaterials();

}  // namespace earshot
