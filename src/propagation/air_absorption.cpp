// ISO 9613-1:1993, Acoustics - Attenuation of sound during propagation
// outdoors - Part 1: Calculation of the absorption of sound by the atmosphere.
// alpha [dB/m] = 8.686 f^2 [1.84e-11 (pa/pr)^-1 (T/T0)^1/2
//   + (T/T0)^-5/2 (0.01275 e^{-2239.1/T} / (frO + f^2/frO)
//                 + 0.1068 e^{-3352.0/T} / (frN + f^2/frN))]
// with the relaxation frequencies of oxygen and nitrogen frO, frN from the
// molar concentration of water vapour h (annex B).
#include "earshot/propagation/air_absorption.h"

#include <cmath>
#include <sstream>
#include <string>

namespace earshot {

Status validate(const AirConditions& air) {
  if (!(air.bandShiftOctaves >= -1.0 && air.bandShiftOctaves <= 1.0))
    return invalidArgument("air band shift " + std::to_string(air.bandShiftOctaves) + " octaves is outside [-1, 1]");
  if (!air.enabled) return Status::ok();
  if (!(air.temperatureC >= -20.0 && air.temperatureC <= 50.0))
    return invalidArgument("air temperature " + std::to_string(air.temperatureC) + " C is outside [-20, 50]");
  if (!(air.humidityPercent >= 0.0 && air.humidityPercent <= 100.0))
    return invalidArgument("air humidity " + std::to_string(air.humidityPercent) + " % is outside [0, 100]");
  if (!(air.pressureKpa >= 50.0 && air.pressureKpa <= 120.0))
    return invalidArgument("air pressure " + std::to_string(air.pressureKpa) + " kPa is outside [50, 120]");
  return Status::ok();
}

Result<AirConditions> parseAirConditions(const std::string& text) {
  AirConditions air;
  if (text == "off") {
    air.enabled = false;
    return air;
  }
  double t = 0, h = 0;
  char comma = 0, extra = 0;
  std::istringstream ss(text);
  if (!(ss >> t >> comma >> h) || comma != ',' || (ss >> extra))
    return invalidArgument("air " + quotedName(text) + " is not TEMP_C,HUMIDITY_PCT or 'off'");
  air.temperatureC = t;
  air.humidityPercent = h;
  EARSHOT_RETURN_IF_ERROR(validate(air));
  return air;
}

double airAttenuationDbPerMeter(double f, const AirConditions& air) {
  if (!air.enabled) return 0.0;
  constexpr double kT0 = 293.15, kT01 = 273.16, kPr = 101.325;
  const double T = air.temperatureC + 273.15;
  const double paRel = air.pressureKpa / kPr;
  // Saturation vapour pressure relative to pr (annex B) and molar concentration h (%).
  const double C = -6.8346 * std::pow(kT01 / T, 1.261) + 4.6151;
  const double psatRel = std::pow(10.0, C);
  const double h = air.humidityPercent * psatRel / paRel;
  const double frO = paRel * (24.0 + 4.04e4 * h * (0.02 + h) / (0.391 + h));
  const double frN = paRel * std::pow(T / kT0, -0.5) * (9.0 + 280.0 * h * std::exp(-4.170 * (std::pow(T / kT0, -1.0 / 3.0) - 1.0)));
  const double f2 = f * f;
  return 8.686 * f2 *
         (1.84e-11 / paRel * std::sqrt(T / kT0) +
          std::pow(T / kT0, -2.5) * (0.01275 * std::exp(-2239.1 / T) / (frO + f2 / frO) +
                                     0.1068 * std::exp(-3352.0 / T) / (frN + f2 / frN)));
}

BandArrayD airAttenuationDbPerMeter(const AirConditions& air) {
  BandArrayD a{};
  const double shift = std::exp2(air.bandShiftOctaves);  // exactly 1 for the octaves
  for (int b = 0; b < kNumBands; ++b) a[b] = airAttenuationDbPerMeter(kBandCentersHz[b] * shift, air);
  return a;
}

BandArrayD airEnergyAttenuationPerMeter(const AirConditions& air) {
  BandArrayD m = airAttenuationDbPerMeter(air);
  for (auto& x : m) x /= 10.0 * std::log10(std::exp(1.0));  // dB -> nepers of energy
  return m;
}

}  // namespace earshot
