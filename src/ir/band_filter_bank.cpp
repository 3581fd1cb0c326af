#include "earshot/ir/band_filter_bank.h"

#include <cmath>

#include "earshot/core/math.h"

namespace earshot {

namespace {
// Raised-cosine step from 0 to 1 over `width` octaves centred on crossover k.
double step(int k, double log2f, double width = 1.0) {
  if (k < 0) return 1.0;               // below band 0 there is no crossover: all "above"
  if (k >= kNumBands - 1) return 0.0;  // above the top band likewise
  // Crossovers at the geometric means of neighbouring centres (octaves: 125 * 2^(k + 1/2)).
  const double x0 = std::log2(kBandCentersHz[0]) + double(k) + 0.5;
  const double u = (log2f - x0) / width;  // transition widths from the crossover
  if (u <= -0.5) return 0.0;
  if (u >= 0.5) return 1.0;
  return 0.5 * (1.0 + std::sin(kPi * u));
}
}  // namespace

double bandWeight(int band, double hz) {
  // step(k) = S_k of the header; the sum over bands telescopes to 1.
  const double lf = hz > 0 ? std::log2(hz) : -1e9;
  return step(band - 1, lf) - step(band, lf);
}

namespace {
// The weights of crossovers `width` octaves wide: step(k) = S_k of the
// header; the sum over bands telescopes to 1.
BandArrayD weightsWith(double hz, double width) {
  const double lf = hz > 0 ? std::log2(hz) : -1e9;
  BandArrayD w{};
  double below = 1.0;  // step(-1)
  for (int b = 0; b < kNumBands; ++b) {
    const double above = step(b, lf, width);
    w[b] = below - above;
    below = above;
  }
  return w;
}
}  // namespace

BandArrayD bandWeights(double hz) { return weightsWith(hz, 1.0); }

BandArrayD noiseBandWeights(double hz) { return weightsWith(hz, kNoiseCrossoverOctaves); }

}  // namespace earshot
