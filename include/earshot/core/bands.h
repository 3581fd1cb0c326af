#pragma once
/** @file The engine's frequency bands: octaves 125 Hz .. 8 kHz. */
#include <array>
#include <cstddef>

namespace earshot {

constexpr int kNumBands = 7;
constexpr std::array<double, kNumBands> kBandCentersHz = {125, 250, 500, 1000, 2000, 4000, 8000};

/** One value per band (energy fractions, gains, energies). */
template <class T>
using BandArrayT = std::array<T, kNumBands>;
using BandArray = BandArrayT<float>;
using BandArrayD = BandArrayT<double>;

template <class T>
constexpr BandArrayT<T> filledBands(T v) {
  BandArrayT<T> a{};
  for (auto& x : a) x = v;
  return a;
}

}  // namespace earshot
