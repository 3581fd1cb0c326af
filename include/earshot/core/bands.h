#pragma once
/** @file The engine's frequency bands: octaves 125 Hz .. 8 kHz. */
#include <array>
#include <cmath>
#include <cstddef>

namespace earshot {

constexpr int kNumBands = 7;
constexpr std::array<double, kNumBands> kBandCentersHz = {125, 250, 500, 1000, 2000, 4000, 8000};

/** One value per band (energy fractions, gains, energies). */
template <class T>
using BandArrayT = std::array<T, kNumBands>;
using BandArray = BandArrayT<float>;
using BandArrayD = BandArrayT<double>;

/** Third-octave bands (issue 20, an option of offline IRs): the 21 base-2
 *  third octaves 125 * 2^((j - 1) / 3) Hz, j = 0 .. 20 (99.2 Hz .. 10.08
 *  kHz; nominal 100 Hz .. 10 kHz). The engine computes them in three passes
 *  of its octave bands shifted by -1/3, 0 and +1/3 of an octave
 *  (thirdOctavePassShift): band j is pass j % 3's band j / 3. */
constexpr int kNumThirdOctaveBands = 3 * kNumBands;
constexpr int kThirdOctavePasses = 3;
/** Centre of third-octave band j (Hz). */
inline double thirdOctaveCenterHz(int j) { return 125.0 * std::exp2(double(j - 1) / 3.0); }
/** The shift of pass p (0, 1, 2) in octaves: -1/3, 0, +1/3. */
inline double thirdOctavePassShift(int p) { return double(p - 1) / 3.0; }
/** The nominal (IEC 61260) label of third-octave band j: 100, 125, 160 .. 10000. */
constexpr std::array<double, kNumThirdOctaveBands> kThirdOctaveNominalHz = {
    100, 125, 160, 200, 250, 315, 400, 500, 630, 800, 1000, 1250, 1600, 2000, 2500, 3150, 4000, 5000, 6300, 8000, 10000};

template <class T>
constexpr BandArrayT<T> filledBands(T v) {
  BandArrayT<T> a{};
  for (auto& x : a) x = v;
  return a;
}

}  // namespace earshot
