#include "earshot/propagation/energy_histogram.h"

namespace earshot {

BandArrayD EnergyHistogram::totalEnergy() const {
  BandArrayD total{};
  for (size_t bin = 0; bin < binCount(); ++bin)
    for (int b = 0; b < kNumBands; ++b) total[b] += energy(bin, b);
  return total;
}

long EnergyHistogram::lastNonEmptyBin() const {
  for (long bin = long(binCount()) - 1; bin >= 0; --bin)
    for (int b = 0; b < kNumBands; ++b)
      if (energy(size_t(bin), b) != 0.0) return bin;
  return -1;
}

}  // namespace earshot
