#pragma once
/** @file Ambisonic impulse responses (AmbiX: ACN channel order, SN3D; up to
 *  order 3; spherical_harmonics.h) in a chosen frame.
 *
 *  Discrete arrivals (the direct sound, image sources): the omni arrival
 *  (ir_synthesis.h: exact fractional delay, band gains) times the real
 *  harmonics of its own direction in the frame, so W is the omni IR's
 *  arrival (1/r) and each channel carries its exact direction.
 *
 *  Late reflections: W is the omni IR's late field (same seed and noise key,
 *  so W equals the omni IR). The other channels follow what the tracer saw
 *  per histogram bin: the energy-weighted sum of arrival directions gives a
 *  direction d and a directional fraction a = |sum| / energy (0 diffuse,
 *  1 one direction), and the field is modelled as a from d plus 1 - a
 *  diffuse. Channel c of order n then has energy a Y_c(d)^2 + (1 - a) / (2n+1)
 *  of W's (a diffuse field's SN3D channels have 1/(2n+1) of W's energy and
 *  are mutually uncorrelated) and correlation a Y_c(d) with W; it is made as
 *      c = a Y_c(d) W_late + sqrt(a Y_c^2 + (1 - a)/(2n+1) - a^2 Y_c^2) N_c,
 *  with N_c the late field's synthesis run on an independent noise of the
 *  same seed (its own stream per channel), under the same band envelopes.
 *  The tracer records the first moment of the directions only, so the
 *  model's directional part is one direction per bin; the rest is diffuse.
 *
 *  Conventions: time 0 is the emission; W is the omni pressure (1/r);
 *  float; channels 0 .. (order+1)^2 - 1 in ACN order. */
#include <vector>

#include "earshot/core/audio_buffer.h"
#include "earshot/core/status.h"
#include "earshot/ir/ir_synthesis.h"
#include "earshot/ir/spherical_harmonics.h"

namespace earshot {

/** The frame of an ambisonic IR: the rotation from world directions into
 *  it (rows: the frame's x forward, y left, z up, in world coordinates). */
struct AmbisonicFrame {
  Rotation3 worldToFrame = worldToAmbisonicFrame({0.0, 0.0, -1.0}, {0.0, 1.0, 0.0});
};

/** The world frame of earshot's ambisonic bus: the glTF default listener
 *  (forward -Z, up +Y), so x = -Z, y = -X, z = +Y of the world. */
AmbisonicFrame worldAmbisonicFrame();

/** (order+1)^2 channels from discrete arrivals (world-frame directions) and a
 *  late energy histogram (may be null). order in [1, kMaxAmbisonicOrder]. */
Result<AudioBuffer> synthesizeAmbisonicIr(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                                          const IrSynthesisSettings& settings, int order,
                                          const AmbisonicFrame& frame);

}  // namespace earshot
