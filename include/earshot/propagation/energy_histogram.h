#pragma once
/** @file Per-band, per-time-bin energy arriving at the listener, with the
 *  energy-weighted direction of arrival of each bin (a first-order energy
 *  field: binaural synthesis decodes it per ear).
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
  static constexpr int kComponents = 4;  ///< energy, then energy x (x, y, z) of the arrival direction

  EnergyHistogram() = default;
  EnergyHistogram(double binSeconds, size_t binCount)
      : mBinSeconds(binSeconds), mData(binCount * kNumBands * kComponents, 0.0) {}

  double binSeconds() const { return mBinSeconds; }
  size_t binCount() const { return mData.size() / (kNumBands * kComponents); }
  double durationSeconds() const { return mBinSeconds * double(binCount()); }

  double energy(size_t bin, int band) const { return mData[index(bin, band)]; }
  /** Energy-weighted sum of unit arrival directions (world frame, from the
   *  listener toward where the sound comes from). Its length over energy is
   *  1 for a single direction, 0 for a perfectly diffuse bin. */
  Vec3d directionSum(size_t bin, int band) const {
    size_t i = index(bin, band);
    return {mData[i + 1], mData[i + 2], mData[i + 3]};
  }
  void add(size_t bin, int band, double energy, const Vec3d& direction) {
    size_t i = index(bin, band);
    mData[i] += energy;
    mData[i + 1] += energy * direction.x;
    mData[i + 2] += energy * direction.y;
    mData[i + 3] += energy * direction.z;
  }
  /** Total energy per band. */
  BandArrayD totalEnergy() const;
  /** Index of the last bin with any energy in any band, or -1 when empty. */
  long lastNonEmptyBin() const;

  /** Raw storage: [bin][band][component]. */
  std::vector<double>& data() { return mData; }
  const std::vector<double>& data() const { return mData; }

 private:
  size_t index(size_t bin, int band) const { return (bin * kNumBands + size_t(band)) * kComponents; }
  double mBinSeconds = 0.001;
  std::vector<double> mData;
};

}  // namespace earshot
