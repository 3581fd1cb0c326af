#pragma once
/** @file Acoustic materials: per-band energy fractions, and the table that
 *  scenes index by material id. File format: docs/design.md "Materials file". */
#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "earshot/core/bands.h"
#include "earshot/core/status.h"

namespace earshot {

/** An acoustic material: per-band energy fractions on the engine's bands
 *  (kBandCentersHz).
 *
 *  How the fractions relate (the engine's convention): of the energy hitting
 *  the surface, `1 - absorption` is reflected; of that reflected part,
 *  `scattering` leaves diffusely (Lambert) and the rest specularly;
 *  `transmission` is the part of the *absorbed* energy that passes through
 *  the surface (the rest turns into heat). Hence 0 <= transmission <=
 *  absorption <= 1 in every band; the loader reports a violation as an error.
 *  Plain data: copy freely; read-only use from any thread is safe. */
struct Material {
  std::string name;
  BandArray absorption = filledBands(0.1f);    ///< energy fraction absorbed per reflection, [0, 1]
  BandArray scattering = filledBands(0.1f);    ///< fraction of reflected energy scattered diffusely, [0, 1]
  BandArray transmission = filledBands(0.0f);  ///< energy fraction passing through the surface, [0, 1]
  /** The values as a materials file gave them, at its bands_hz (each array
   *  as long): what MaterialTable::atBandShift resamples, so that a file in
   *  third octaves is used as such by third-octave IRs. Empty: the arrays
   *  above are the data (given at kBandCentersHz). */
  std::vector<double> givenBandsHz, givenAbsorption, givenScattering, givenTransmission;
};

/** Materials by id (their index). Id 0 is always the default material, given
 *  to surfaces whose glTF material maps to nothing. Ids are dense, stable
 *  once assigned, and never removed. Threading: not synchronised; build it on
 *  one thread, then share it read-only (const methods only) freely. */
class MaterialTable {
 public:
  MaterialTable();  ///< just the built-in default material at id 0
  /** Adds or replaces (by name) a material; returns its id. */
  uint32_t add(Material m);
  std::optional<uint32_t> find(const std::string& name) const;
  const Material& operator[](uint32_t id) const { return mMaterials[id]; }
  size_t size() const { return mMaterials.size(); }
  const std::vector<Material>& all() const { return mMaterials; }
  /** The same table (ids, names) with every material's bands at
   *  kBandCentersHz x 2^octaves, resampled from what its file gave
   *  (Material::givenBandsHz) as interpolateToEngineBands does: a
   *  third-octave pass's materials (bands.h). octaves 0 gives the table. */
  MaterialTable atBandShift(double octaves) const;
  /** Makes an existing material the default (copied to id 0 under its own name). */
  Status setDefault(const std::string& name);

 private:
  std::vector<Material> mMaterials;
  std::unordered_map<std::string, uint32_t> mIndex;  // name -> lowest id with that name
};

/** Parses a materials JSON text; `sourceName` (a file name) prefixes errors:
 *  `file: material "x": absorption[3] = 1.7 is outside [0, 1]`. Values given
 *  at other centre frequencies (bands_hz) are interpolated to the engine's bands.
 *
 *  Accepted keys: top level `bands_hz` (required, ascending, positive, finite),
 *  `materials` (required object, name -> material), `description`, `license`
 *  (strings), `sources` (anything, ignored); per material `absorption`
 *  (required, one value per band), `scattering` (number or one value per band;
 *  default 0.1), `transmission` (optional, one value per band; default 0),
 *  `source`, `description` (strings). Any other key is an error. Every value
 *  must be finite, in [0, 1], and transmission <= absorption band by band
 *  (checked at the given bands). A material named "default" becomes id 0;
 *  otherwise id 0 is the built-in default (Material{}). Other materials get
 *  ids 1.. in file order. Errors are one line. Thread-safe (no shared state). */
Result<MaterialTable> parseMaterials(const std::string& jsonText, const std::string& sourceName);
/** Reads and parses a materials file (`path` prefixes errors; a missing or
 *  unreadable file is a kNotFound / kIoError status). Thread-safe. */
Result<MaterialTable> loadMaterials(const std::string& path);
/** The library's default set (materials/default.json, compiled in at build
 *  time), parsed once on first use; thread-safe; the reference stays valid
 *  for the life of the program. */
const MaterialTable& defaultMaterials();

/** Resamples values given at centre frequencies `bandsHz` (ascending,
 *  positive; same length as `values`, at least 1) to the engine's bands:
 *  linear in log-frequency between neighbouring centres, held constant below
 *  the first and above the last; a given centre within 1/12 octave of a
 *  band's is that band's nominal name (400 Hz for the third octave at
 *  396.9 Hz) and gives its value. Precondition violations give all zeros. */
BandArray interpolateToEngineBands(const std::vector<double>& bandsHz, const std::vector<double>& values);
/** As interpolateToEngineBands, to the engine's bands shifted by
 *  `shiftOctaves` (kBandCentersHz x 2^shiftOctaves). */
BandArray interpolateToBands(const std::vector<double>& bandsHz, const std::vector<double>& values,
                             double shiftOctaves);

}  // namespace earshot
