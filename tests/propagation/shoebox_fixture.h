#pragma once
// The 10 x 7 x 3 m shoebox of the reference data with one uniform material,
// shared by the propagation tests.
#include <gtest/gtest.h>

#include <memory>

#include "earshot/materials/material.h"
#include "earshot/scene/ray_tracer.h"

namespace earshot::testing {

struct Shoebox {
  MaterialTable materials;
  std::unique_ptr<RayTracer> tracer;
  static constexpr double kVolume = 10.0 * 7.0 * 3.0;
  static constexpr double kSurface = 2.0 * (10.0 * 7.0 + 10.0 * 3.0 + 7.0 * 3.0);
  Shoebox(float absorption, float scattering) {
    Material m;
    m.name = "wall";
    m.absorption = filledBands(absorption);
    m.scattering = filledBands(scattering);
    m.transmission = filledBands(0.0f);
    auto rt = RayTracer::create(makeBox({0, 0, 0}, {10, 7, 3}, materials.add(m)));
    EXPECT_TRUE(rt.isOk());
    tracer = std::move(rt.value());
  }
};

}  // namespace earshot::testing
