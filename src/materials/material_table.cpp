#include "earshot/materials/material.h"

#include <algorithm>

namespace earshot {

MaterialTable::MaterialTable() {
  Material m;
  m.name = "default";
  mIndex[m.name] = 0;
  mMaterials.push_back(std::move(m));
}

uint32_t MaterialTable::add(Material m) {
  if (auto id = find(m.name)) {
    mMaterials[*id] = std::move(m);
    return *id;
  }
  const auto id = static_cast<uint32_t>(mMaterials.size());
  mIndex.emplace(m.name, id);
  mMaterials.push_back(std::move(m));
  return id;
}

// NOTE: a hash index; a linear search made loading n materials O(n^2)
// (40k materials took 10 s; found by the robustness work).
std::optional<uint32_t> MaterialTable::find(const std::string& name) const {
  const auto it = mIndex.find(name);
  if (it == mIndex.end()) return std::nullopt;
  return it->second;
}

MaterialTable MaterialTable::atBandShift(double octaves) const {
  MaterialTable t = *this;
  if (octaves == 0.0) return t;
  std::vector<double> engineHz(kBandCentersHz.begin(), kBandCentersHz.end()), a(kNumBands), s(kNumBands), x(kNumBands);
  for (Material& m : t.mMaterials) {
    if (m.givenBandsHz.empty()) {  // made in code: its arrays are the data
      for (int b = 0; b < kNumBands; ++b) {
        a[size_t(b)] = m.absorption[size_t(b)];
        s[size_t(b)] = m.scattering[size_t(b)];
        x[size_t(b)] = m.transmission[size_t(b)];
      }
      m.absorption = interpolateToBands(engineHz, a, octaves);
      m.scattering = interpolateToBands(engineHz, s, octaves);
      m.transmission = interpolateToBands(engineHz, x, octaves);
    } else {
      m.absorption = interpolateToBands(m.givenBandsHz, m.givenAbsorption, octaves);
      m.scattering = interpolateToBands(m.givenBandsHz, m.givenScattering, octaves);
      m.transmission = interpolateToBands(m.givenBandsHz, m.givenTransmission, octaves);
    }
    // Interpolation keeps transmission <= absorption (both are the same
    // convex combination of values that satisfy it); float rounding might not.
    for (int b = 0; b < kNumBands; ++b) m.transmission[size_t(b)] = std::min(m.transmission[size_t(b)], m.absorption[size_t(b)]);
  }
  return t;
}

Status MaterialTable::setDefault(const std::string& name) {
  const auto id = find(name);
  if (!id) return notFound("material " + quotedName(name) + " is not in the table, cannot make it the default");
  const auto old = mIndex.find(mMaterials[0].name);
  if (old != mIndex.end() && old->second == 0) mIndex.erase(old);
  mMaterials[0] = mMaterials[*id];
  mIndex[name] = 0;  // id 0 is now the lowest id with that name
  return Status::ok();
}

}  // namespace earshot
