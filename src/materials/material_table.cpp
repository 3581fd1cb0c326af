#include "earshot/materials/material.h"

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

Status MaterialTable::setDefault(const std::string& name) {
  const auto id = find(name);
  if (!id) return notFound("material \"" + name + "\" is not in the table, cannot make it the default");
  const auto old = mIndex.find(mMaterials[0].name);
  if (old != mIndex.end() && old->second == 0) mIndex.erase(old);
  mMaterials[0] = mMaterials[*id];
  mIndex[name] = 0;  // id 0 is now the lowest id with that name
  return Status::ok();
}

}  // namespace earshot
