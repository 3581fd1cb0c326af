#pragma once
/** @file The direct sound from a source to a listener: delay r/c, 1/r
 *  spreading, air absorption, and transmission through every surface crossed. */
#include "earshot/core/bands.h"
#include "earshot/core/status.h"
#include "earshot/core/vec3.h"
#include "earshot/materials/material.h"
#include "earshot/propagation/air_absorption.h"

namespace earshot {

class RayTracer;

/** A source's directivity: the dipole family g(theta) = |(1 - alpha) +
 *  alpha cos(theta)|^sharpness about the source's forward axis (alpha 0
 *  omni, 0.5 cardioid, 1 figure-8). Power-normalised: the source radiates
 *  the same total power as an omni source of the same gain, in direction u
 *  the energy factor D(u) = g^2 / <g^2> (mean over the sphere), so its
 *  reverberation matches the omni source's whatever it faces, and on its
 *  axis it is louder by its directivity index (cardioid: 4.8 dB). The
 *  direct sound is scaled by sqrt(D(toward the listener)), each image
 *  source by sqrt(D(its first segment)), each traced ray's energy by D(its
 *  emission direction). */
struct Directivity {
  double alpha = 0.0;      ///< [0, 1], every band (unless perBand)
  double sharpness = 1.0;  ///< [1, 16]
  Vec3d forward{0.0, 0.0, -1.0};  ///< the axis, world frame (normalised on use)
  /** A per-band table instead of `alpha`: e.g. a loudspeaker omni at 125 Hz
   *  and cardioid at 4 kHz. */
  bool perBand = false;
  BandArrayD bandAlpha{};  ///< [0, 1] per band (perBand)
  double alphaOf(int band) const { return perBand ? bandAlpha[size_t(band)] : alpha; }
  bool isOmni() const;
  /** <g^2> over the sphere per band (4096-point quadrature in cos(theta)). */
  BandArrayD meanSquares() const;
  /** D(u) per band: energy factors in the unit direction u (1 for omni),
   *  with meanSquares() computed once by the caller. */
  BandArrayD energyFactors(const Vec3d& u, const BandArrayD& meanSquares) const;
  BandArrayD energyFactors(const Vec3d& u) const { return energyFactors(u, meanSquares()); }
};
/** Error unless every band's alpha is in [0, 1], sharpness in [1, 16] and
 *  forward finite and non-zero. */
Status validate(const Directivity& d);

struct DirectPathSettings {
  Directivity directivity;            ///< the source's; the gain toward the listener scales bandGain
  double speedOfSound = 343.0;        ///< m/s
  double minDistanceMeters = 0.1;     ///< spreading is clamped here (1/r would diverge at 0)
  AirConditions air;
};

struct DirectPath {
  double distanceMeters = 0.0;
  double delaySeconds = 0.0;        ///< r / c
  double spreadingGain = 1.0;       ///< pressure: 1 / max(r, minDistance) (1.0 at 1 m)
  BandArrayD bandGain{};            ///< pressure factor per band: air x transmission (spreading excluded)
  /** Pressure factor per band through the occluders alone (air excluded):
   *  the square root of the product of their transmissions; 1 with none. */
  BandArrayD transmissionGain = filledBands(1.0);
  int surfacesCrossed = 0;          ///< occluders between source and listener
  bool occlusionTested = false;     ///< false: no geometry, or provably nothing between (RayTracer::nothingBetween)
  bool audible = true;              ///< false when fully blocked (some band gain > 0 otherwise)
  Vec3d directionFromListener;      ///< unit vector from the listener toward the source (world frame)
  /** Pressure factor of the source's directivity toward the listener,
   *  sqrt(D) (DirectPathSettings::directivity); not in bandGain, which stays
   *  the path's own (air, transmission). */
  BandArrayD directivityGain = filledBands(1.0);
};

/** Computes the direct path. `tracer` may be null (free field). Each surface
 *  crossed multiplies the band energy by its material's transmission. */
DirectPath computeDirectPath(const RayTracer* tracer, const MaterialTable& materials, const Vec3d& source,
                             const Vec3d& listener, const DirectPathSettings& settings);

}  // namespace earshot
