#include "earshot/materials/material.h"

namespace earshot {

MaterialTable::MaterialTable() {
  Material m;
  m.name = "default";
  mMaterials.push_back(std::move(m));
}

uint32_t MaterialTable::add(Material m) {
  if (auto id = find(m.name)) {
    mMaterials[*id] = std::move(m);
    return *id;
  }
  mMaterials.push_back(std::move(m));
  return static_cast<uint32_t>(mMaterials.size() - 1);
}

std::optional<uint32_t> MaterialTable::find(const std::string& name) const {
  for (size_t i = 0; i < mMaterials.size(); ++i)
    if (mMaterials[i].name == name) return static_cast<uint32_t>(i);
  return std::nullopt;
}

Status MaterialTable::setDefault(const std::string& name) {
  const auto id = find(name);
  if (!id) return notFound("material \"" + name + "\" is not in the table, cannot make it the default");
  mMaterials[0] = mMaterials[*id];
  return Status::ok();
}

}  // namespace earshot
