#pragma once
// Shared helpers for the dsp tests: deterministic signals and a
// double-precision direct convolution used as the reference.
#include <cmath>
#include <cstddef>
#include <vector>

#include "earshot/core/random.h"

namespace earshot::test {

/** Uniform noise in [-1, 1) with an exponential decay to `endDb` at the end. */
inline std::vector<float> decayingNoise(size_t frames, uint64_t seed, double endDb = -60.0) {
  Pcg32 rng(seed, 1);
  std::vector<float> v(frames);
  for (size_t i = 0; i < frames; ++i) {
    double env = std::pow(10.0, endDb / 20.0 * static_cast<double>(i) / static_cast<double>(frames));
    v[i] = static_cast<float>((2.0 * rng.uniformDouble() - 1.0) * env);
  }
  return v;
}

/** y = x * h in double precision, skipping zero input samples. */
inline std::vector<double> directConvolve(const std::vector<float>& x, const std::vector<float>& h, size_t outLen) {
  std::vector<double> y(outLen, 0.0);
  for (size_t n = 0; n < x.size() && n < outLen; ++n) {
    if (x[n] == 0.0f) continue;
    const double xn = x[n];
    const size_t m1 = std::min(h.size(), outLen - n);
    for (size_t m = 0; m < m1; ++m) y[n + m] += xn * h[m];
  }
  return y;
}

}  // namespace earshot::test
