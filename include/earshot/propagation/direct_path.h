#pragma once
/** @file The direct sound from a source to a listener: delay r/c, 1/r
 *  spreading, air absorption, and transmission through every surface crossed. */
#include "earshot/core/bands.h"
#include "earshot/core/vec3.h"
#include "earshot/materials/material.h"
#include "earshot/propagation/air_absorption.h"

namespace earshot {

class RayTracer;

struct DirectPathSettings {
  double speedOfSound = 343.0;        ///< m/s
  double minDistanceMeters = 0.1;     ///< spreading is clamped here (1/r would diverge at 0)
  AirConditions air;
};

struct DirectPath {
  double distanceMeters = 0.0;
  double delaySeconds = 0.0;        ///< r / c
  double spreadingGain = 1.0;       ///< pressure: 1 / max(r, minDistance) (1.0 at 1 m)
  BandArrayD bandGain{};            ///< pressure factor per band: air x transmission (spreading excluded)
  int surfacesCrossed = 0;          ///< occluders between source and listener
  bool occlusionTested = false;     ///< false: no geometry, or provably nothing between (RayTracer::nothingBetween)
  bool audible = true;              ///< false when fully blocked (some band gain > 0 otherwise)
  Vec3d directionFromListener;      ///< unit vector from the listener toward the source (world frame)
};

/** Computes the direct path. `tracer` may be null (free field). Each surface
 *  crossed multiplies the band energy by its material's transmission. */
DirectPath computeDirectPath(const RayTracer* tracer, const MaterialTable& materials, const Vec3d& source,
                             const Vec3d& listener, const DirectPathSettings& settings);

}  // namespace earshot
