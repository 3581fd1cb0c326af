#pragma once
/** @file Atmospheric absorption of sound, ISO 9613-1:1993 (pure-tone formula,
 *  eqs. 3-5 and annex B for the saturation vapour pressure). */
#include <string>

#include "earshot/core/bands.h"
#include "earshot/core/status.h"

namespace earshot {

struct AirConditions {
  double temperatureC = 20.0;     ///< [-20, 50] C
  double humidityPercent = 50.0;  ///< relative humidity, [0, 100] %
  double pressureKpa = 101.325;   ///< [50, 120] kPa
  bool enabled = true;            ///< false: no air absorption
  /** The bands' centres are kBandCentersHz x 2^this: a third-octave pass
   *  (bands.h) sets -1/3 or +1/3; 0 for the engine's octaves. [-1, 1] */
  double bandShiftOctaves = 0.0;
};

/** Parses "TEMP_C,HUMIDITY_PCT" (e.g. "20,50") or "off"; checks ranges. */
Result<AirConditions> parseAirConditions(const std::string& text);

/** Checks ranges; the message names the field. */
Status validate(const AirConditions& air);

/** Attenuation coefficient in dB per metre at frequency `hz` (ISO 9613-1 eq. 5). */
double airAttenuationDbPerMeter(double hz, const AirConditions& air);

/** Per band, at the engine's nominal centre frequencies (shifted by
 *  air.bandShiftOctaves); zero when disabled. */
BandArrayD airAttenuationDbPerMeter(const AirConditions& air);

/** Energy attenuation coefficient m (1/m) per band: energy falls as exp(-m d). */
BandArrayD airEnergyAttenuationPerMeter(const AirConditions& air);

}  // namespace earshot
