#pragma once
// Shared by the runtime tests: the KU100 model (loaded once per binary), a
// 10 x 7 x 3 m room, and simulation settings small enough for fast tests.
#include <memory>
#include <string>

#include "earshot/ir/binaural_synthesis.h"
#include "earshot/materials/material.h"
#include "earshot/runtime/engine.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot::runtime::test {

constexpr double kFs = 48000.0;

inline std::shared_ptr<const BinauralModel> ku100() {
  static std::shared_ptr<const BinauralModel> model = [] {
    auto m = loadBinauralModel(std::string(EARSHOT_SOURCE_DIR) + "/hrtf/FHK_HRIR_L2354.sofa", kFs);
    return m.isOk() ? *m : nullptr;
  }();
  return model;
}

struct Room {
  std::shared_ptr<MaterialTable> materials = std::make_shared<MaterialTable>();
  std::shared_ptr<const RayTracer> tracer;
  explicit Room(float absorption = 0.2f) {
    Material m;
    m.name = "wall";
    m.absorption = filledBands(absorption);
    m.scattering = filledBands(0.3f);
    m.transmission = filledBands(0.0f);
    auto rt = RayTracer::create(makeBox({0, 0, 0}, {10, 7, 3}, materials->add(m)));
    if (rt.isOk()) tracer = std::move(rt.value());
  }
};

inline EngineSettings fastSettings() {
  EngineSettings s;
  s.simulation.rays = 2000;
  s.simulation.bounces = 8;
  s.simulation.imageSourceOrder = 2;
  s.maxIrSeconds = 1.5;
  s.maxSources = 4;
  s.threads = 2;
  return s;
}

}  // namespace earshot::runtime::test
