#pragma once
// Frequency of a steady tone, for tests that measure Doppler shifts.
#include <cstddef>
#include <vector>

namespace earshot::test {

/** Frequency (Hz) of a sine in x[from, from + n) at rate fs, from its upward
 *  zero crossings with linear interpolation between samples (accurate to
 *  ~0.01 % over a few hundred periods). 0 if fewer than two crossings. */
inline double sineFrequency(const std::vector<float>& x, size_t from, size_t n, double fs) {
  double first = -1, last = -1;
  int crossings = 0;
  for (size_t i = from + 1; i < from + n && i < x.size(); ++i)
    if (x[i - 1] < 0 && x[i] >= 0) {
      const double t = double(i - 1) + double(x[i - 1]) / double(x[i - 1] - x[i]);
      if (first < 0) first = t;
      last = t;
      ++crossings;
    }
  return crossings > 1 ? (crossings - 1) * fs / (last - first) : 0.0;
}

}  // namespace earshot::test
