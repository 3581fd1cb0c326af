#pragma once
/** @file Per-band, per-time-bin energy arriving at the listener, with the
 *  energy-weighted direction of arrival of each bin (a first-order energy
 *  field: binaural synthesis decodes it per ear). The direction is weighted
 *  by the band-mean energy of each arrival: one direction per bin, shared by
 *  the bands (arrivals differ between bands in level, not in direction).
 *
 *  Energy convention: a direct sound of pressure amplitude 1/r has energy
 *  1/r^2 (the sum of its squared samples); a bin holds the energy of the
 *  broadband pressure IR within it, as it would be with that band's
 *  attenuation applied to all frequencies. */
#include <cstddef>
#include <vector>

#include "earshot/core/bands.h"
#include "earshot/core/vec3.h"

namespace earshot {

class EnergyHistogram {
 public:
  /** Values per bin: kNumBands energies, then the direction sum (x, y, z). */
  static constexpr int kStride = kNumBands + 3;

  EnergyHistogram() = default;
  EnergyHistogram(double binSeconds, size_t binCount) : mBinSeconds(binSeconds), mData(binCount * kStride, 0.0) {}

  double binSeconds() const { return mBinSeconds; }
  size_t binCount() const { return mData.size() / kStride; }
  double durationSeconds() const { return mBinSeconds * double(binCount()); }

  double energy(size_t bin, int band) const { return mData[bin * kStride + size_t(band)]; }
  /** Sum of unit arrival directions (world frame, from the listener toward
   *  where the sound comes from) weighted by each arrival's band-mean energy.
   *  Its length over the bin's band-mean energy is 1 for a single direction
   *  and 0 for a perfectly diffuse bin. */
  Vec3d directionSum(size_t bin) const {
    const double* d = &mData[bin * kStride + kNumBands];
    return {d[0], d[1], d[2]};
  }
  /** Adds one arrival with per-band energies. */
  void add(size_t bin, const BandArrayD& energy, const Vec3d& direction) {
    double* d = &mData[bin * kStride];
    double mean = 0;
    for (int b = 0; b < kNumBands; ++b) {
      d[b] += energy[b];
      mean += energy[b] / kNumBands;
    }
    d[kNumBands] += mean * direction.x;
    d[kNumBands + 1] += mean * direction.y;
    d[kNumBands + 2] += mean * direction.z;
  }
  /** Total energy per band. */
  BandArrayD totalEnergy() const;
  /** Index of the last bin with any energy in any band, or -1 when empty. */
  long lastNonEmptyBin() const;

  /** Raw storage: [bin][kStride]. */
  std::vector<double>& data() { return mData; }
  const std::vector<double>& data() const { return mData; }

 private:
  double mBinSeconds = 0.001;
  std::vector<double> mData;
};

}  // namespace earshot
