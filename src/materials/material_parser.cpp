// Materials file parser (docs/design.md "Materials file"). Band resampling is
// linear interpolation in log-frequency between given centres, held constant
// beyond the ends; see interpolateToEngineBands.
#include <cmath>
#include <fstream>
#include <iterator>
#include <sstream>

#include <nlohmann/json.hpp>

#include "earshot/materials/material.h"

#include "earshot/io/input_file.h"

namespace earshot {
namespace detail {
extern const char* const kDefaultMaterialsJson;
}

namespace {

using Json = nlohmann::ordered_json;

std::string formatNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

/** Reads a JSON number array, each value checked for finiteness and [lo, hi]. */
Status readArray(const Json& j, const std::string& where, const std::string& key, std::vector<double>* out) {
  if (!j.is_array()) return parseError(where + key + " must be an array of numbers");
  out->clear();
  for (size_t i = 0; i < j.size(); ++i) {
    const std::string item = where + key + "[" + std::to_string(i) + "]";
    if (!j[i].is_number()) return parseError(item + " is not a number");
    out->push_back(j[i].get<double>());
  }
  return Status::ok();
}

Status checkUnit(const std::string& where, const std::string& key, const std::vector<double>& v) {
  for (size_t i = 0; i < v.size(); ++i) {
    const std::string item = where + key + "[" + std::to_string(i) + "] = " + formatNumber(v[i]);
    if (!std::isfinite(v[i])) return invalidArgument(item + " is not finite");
    if (v[i] < 0.0 || v[i] > 1.0) return invalidArgument(item + " is outside [0, 1]");
  }
  return Status::ok();
}

Result<Material> parseMaterial(const std::string& name, const Json& j, const std::vector<double>& bandsHz,
                               const std::string& file) {
  const std::string where = file + ": material " + quotedName(name) + ": ";
  if (name.empty()) return parseError(file + ": a material has an empty name");
  if (!j.is_object()) return parseError(where + "must be an object");
  for (const auto& item : j.items()) {
    const std::string& k = item.key();
    if (k != "absorption" && k != "scattering" && k != "transmission" && k != "source" && k != "description")
      return parseError(where + "unknown key " + quotedName(k) +
                        " (expected absorption, scattering, transmission, source, description)");
    if ((k == "source" || k == "description") && !item.value().is_string())
      return parseError(where + k + " must be a string");
  }
  const size_t n = bandsHz.size();
  auto perBand = [&](const char* key, std::vector<double>* v) -> Status {
    EARSHOT_RETURN_IF_ERROR(readArray(j.at(key), where, key, v));
    if (v->size() != n)
      return parseError(where + key + " has " + std::to_string(v->size()) + " values but bands_hz has " +
                        std::to_string(n));
    return checkUnit(where, key, *v);
  };

  Material m;
  m.name = name;
  if (!j.contains("absorption")) return parseError(where + "missing absorption");
  std::vector<double> absorption, transmission, scattering;
  EARSHOT_RETURN_IF_ERROR(perBand("absorption", &absorption));
  m.absorption = interpolateToEngineBands(bandsHz, absorption);
  m.givenBandsHz = bandsHz;
  m.givenAbsorption = absorption;
  m.givenScattering.assign(n, double(m.scattering[0]));  // the default, or one number for every band

  if (j.contains("scattering")) {
    const Json& s = j.at("scattering");
    if (s.is_number()) {
      const std::vector<double> one{s.get<double>()};
      const std::string item = where + "scattering = " + formatNumber(one[0]);
      if (!std::isfinite(one[0])) return invalidArgument(item + " is not finite");
      if (one[0] < 0.0 || one[0] > 1.0) return invalidArgument(item + " is outside [0, 1]");
      m.scattering = filledBands(static_cast<float>(one[0]));
      m.givenScattering.assign(n, one[0]);
    } else {
      EARSHOT_RETURN_IF_ERROR(perBand("scattering", &scattering));
      m.scattering = interpolateToEngineBands(bandsHz, scattering);
      m.givenScattering = scattering;
    }
  }
  if (j.contains("transmission")) {
    EARSHOT_RETURN_IF_ERROR(perBand("transmission", &transmission));
    for (size_t i = 0; i < n; ++i)
      if (transmission[i] > absorption[i])
        return invalidArgument(where + "transmission[" + std::to_string(i) + "] = " + formatNumber(transmission[i]) +
                               " exceeds absorption[" + std::to_string(i) + "] = " + formatNumber(absorption[i]) +
                               " (transmission is the part of the absorbed energy that passes through)");
    m.transmission = interpolateToEngineBands(bandsHz, transmission);
    m.givenTransmission = transmission;
  } else {
    m.transmission = filledBands(0.0f);
    m.givenTransmission.assign(n, 0.0);
  }
  return m;
}

}  // namespace

BandArray interpolateToEngineBands(const std::vector<double>& hz, const std::vector<double>& values) {
  return interpolateToBands(hz, values, 0.0);
}

BandArray interpolateToBands(const std::vector<double>& hz, const std::vector<double>& values, double shiftOctaves) {
  BandArray out = filledBands(0.0f);
  if (hz.empty() || hz.size() != values.size()) return out;
  for (size_t i = 0; i < hz.size(); ++i)
    if (!(hz[i] > 0.0) || (i > 0 && !(hz[i] > hz[i - 1]))) return out;
  const double shift = std::exp2(shiftOctaves);  // exactly 1 for the engine's octaves
  for (int b = 0; b < kNumBands; ++b) {
    const double f = kBandCentersHz[b] * shift;
    // A given band within a twelfth of an octave is this band under its
    // nominal name (IEC 61260: 400 Hz is the third octave at 396.9 Hz,
    // 160 at 157.5): its value, not a blend with the next band's.
    size_t nearest = 0;
    for (size_t i = 1; i < hz.size(); ++i)
      if (std::abs(std::log2(hz[i] / f)) < std::abs(std::log2(hz[nearest] / f))) nearest = i;
    double v;
    if (std::abs(std::log2(hz[nearest] / f)) < 1.0 / 12.0) {
      v = values[nearest];
    } else if (f <= hz.front()) {
      v = values.front();
    } else if (f >= hz.back()) {
      v = values.back();
    } else {
      size_t i = 1;
      while (hz[i] < f) ++i;  // hz[i - 1] < f <= hz[i]
      const double t = std::log(f / hz[i - 1]) / std::log(hz[i] / hz[i - 1]);
      v = values[i - 1] + t * (values[i] - values[i - 1]);
    }
    out[b] = static_cast<float>(v);
  }
  return out;
}

Result<MaterialTable> parseMaterials(const std::string& jsonText, const std::string& file) {
  EARSHOT_RETURN_IF_ERROR(checkJsonDepth(jsonText, file));
  Json doc;
  try {
    doc = Json::parse(jsonText);
  } catch (const Json::exception& e) {
    return parseError(file + ": malformed JSON: " + jsonErrorWithoutContent(e.what()));
  }
  if (!doc.is_object()) return parseError(file + ": the top level must be a JSON object");
  for (const auto& item : doc.items()) {
    const std::string& k = item.key();
    if (k == "bands_hz" || k == "materials" || k == "sources") continue;
    if (k == "description" || k == "license") {
      if (!item.value().is_string()) return parseError(file + ": " + k + " must be a string");
      continue;
    }
    return parseError(file + ": unknown key " + quotedName(k) +
                      " (expected bands_hz, materials, description, license, sources)");
  }
  if (!doc.contains("bands_hz")) return parseError(file + ": missing bands_hz");
  std::vector<double> bandsHz;
  EARSHOT_RETURN_IF_ERROR(readArray(doc["bands_hz"], file + ": ", "bands_hz", &bandsHz));
  if (bandsHz.empty()) return parseError(file + ": bands_hz is empty");
  for (size_t i = 0; i < bandsHz.size(); ++i) {
    const std::string item = file + ": bands_hz[" + std::to_string(i) + "] = " + formatNumber(bandsHz[i]);
    if (!std::isfinite(bandsHz[i]) || bandsHz[i] <= 0.0) return invalidArgument(item + " is not a positive frequency");
    if (i > 0 && bandsHz[i] <= bandsHz[i - 1]) return invalidArgument(item + " is not above the previous band");
  }
  if (!doc.contains("materials")) return parseError(file + ": missing materials");
  const Json& mats = doc["materials"];
  if (!mats.is_object()) return parseError(file + ": materials must be an object (name -> material)");

  MaterialTable table;
  for (const auto& item : mats.items()) {
    auto m = parseMaterial(item.key(), item.value(), bandsHz, file);
    if (!m) return m.status();
    table.add(std::move(m).value());
  }
  return table;
}

Result<MaterialTable> loadMaterials(const std::string& path) {
  auto text = readInputFile(path, "materials file", kMaxJsonFileBytes);
  if (!text) return text.status();
  return parseMaterials(*text, path);
}

const MaterialTable& defaultMaterials() {
  static const MaterialTable table = [] {
    auto parsed = parseMaterials(detail::kDefaultMaterialsJson, "materials/default.json");
    // The materials tests parse the same text and fail loudly; a broken build
    // still gets a usable table with the built-in default.
    return parsed ? std::move(parsed).value() : MaterialTable();
  }();
  return table;
}

}  // namespace earshot
