#pragma once
// Exact image sources of a rectangular room (Allen & Berkley, "Image method
// for efficiently simulating small-room acoustics", JASA 65, 1979), written
// independently of earshot's geometric image-source code, as a reference for
// the regression tests. Room [0,Lx]x[0,Ly]x[0,Lz]; walls in the order west
// (x=0), east (x=Lx), south, north, floor, ceiling; specular, angle-independent
// pressure reflection factor sqrt(1 - alpha) per band; 1/r spreading; air as
// dB per metre per band.
#include <array>
#include <cmath>
#include <vector>

namespace earshot::reference {

constexpr int kBands = 7;

struct Image {
  double delaySeconds;
  std::array<double, kBands> amplitude;  // pressure, 1/r convention
};

inline std::vector<Image> latticeImages(const std::array<double, 3>& room, const std::array<double, 3>& src,
                                        const std::array<double, 3>& rcv,
                                        const std::array<std::array<double, kBands>, 6>& alpha,
                                        const std::array<double, kBands>& airDbPerM, double c, double maxSeconds) {
  std::vector<Image> out;
  const double maxDist = maxSeconds * c;
  int nMax[3];
  for (int a = 0; a < 3; ++a) nMax[a] = int(std::ceil(maxDist / (2 * room[a]))) + 1;
  // Per axis, the image coordinate 2 n L + (1 - 2p) s hits the low wall
  // |n - p| times and the high wall |n| times.
  for (int nx = -nMax[0]; nx <= nMax[0]; ++nx)
    for (int px = 0; px < 2; ++px) {
      const double dx = 2 * nx * room[0] + (1 - 2 * px) * src[0] - rcv[0];
      if (std::fabs(dx) > maxDist) continue;
      for (int ny = -nMax[1]; ny <= nMax[1]; ++ny)
        for (int py = 0; py < 2; ++py) {
          const double dy = 2 * ny * room[1] + (1 - 2 * py) * src[1] - rcv[1];
          if (dx * dx + dy * dy > maxDist * maxDist) continue;
          for (int nz = -nMax[2]; nz <= nMax[2]; ++nz)
            for (int pz = 0; pz < 2; ++pz) {
              const double dz = 2 * nz * room[2] + (1 - 2 * pz) * src[2] - rcv[2];
              const double d = std::sqrt(dx * dx + dy * dy + dz * dz);
              if (d > maxDist) continue;
              const int hits[6] = {std::abs(nx - px), std::abs(nx), std::abs(ny - py),
                                   std::abs(ny), std::abs(nz - pz), std::abs(nz)};
              Image im;
              im.delaySeconds = d / c;
              for (int b = 0; b < kBands; ++b) {
                double g = std::pow(10.0, -airDbPerM[b] * d / 20.0) / d;
                for (int w = 0; w < 6; ++w) g *= std::pow(1.0 - alpha[w][b], 0.5 * hits[w]);
                im.amplitude[b] = g;
              }
              out.push_back(im);
            }
        }
    }
  return out;
}

// Coherent: each image at its nearest sample (amplitudes of coincident images add).
inline std::vector<float> coherentTrain(const std::vector<Image>& images, int band, double fs, double seconds) {
  std::vector<double> x(size_t(seconds * fs) + 1, 0.0);
  for (const Image& im : images) {
    const size_t i = size_t(std::lround(im.delaySeconds * fs));
    if (i < x.size()) x[i] += band < 0 ? im.amplitude[3] : im.amplitude[size_t(band)];
  }
  return std::vector<float>(x.begin(), x.end());
}

// Incoherent: energy per bin (what an energy method computes), returned as the
// square root of each bin's energy at rate 1 / binSeconds, so that energy
// metrics computed on the "signal" are those of the energy histogram.
inline std::vector<float> incoherentEnvelope(const std::vector<Image>& images, int band, double binSeconds,
                                             double seconds) {
  std::vector<double> e(size_t(seconds / binSeconds) + 1, 0.0);
  for (const Image& im : images) {
    const size_t i = size_t(im.delaySeconds / binSeconds);
    if (i < e.size()) e[i] += im.amplitude[size_t(band)] * im.amplitude[size_t(band)];
  }
  std::vector<float> out(e.size());
  for (size_t i = 0; i < e.size(); ++i) out[i] = float(std::sqrt(e[i]));
  return out;
}

}  // namespace earshot::reference
