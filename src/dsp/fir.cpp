// FIR over a block: see include/earshot/dsp/fir.h.
#include "earshot/dsp/fir.h"

#include <cstring>

#include "earshot/core/target_clones.h"

namespace earshot {

// An AVX2+FMA clone where the CPU has it (EARSHOT_CLONES). Written with GCC/Clang vector extensions: a tile of 32 outputs stays in
// four 8-float registers over all taps, so each tap costs four loads and
// four multiply-adds instead of a load and a store of every output (the
// plain loop was bound by that traffic). Each output sums its taps in the
// same order either way.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
typedef float FirV8 __attribute__((vector_size(32)));
EARSHOT_CLONES
void firInto(const float* __restrict h, size_t taps, const float* __restrict x, float* __restrict y, size_t frames) {
  size_t i = 0;
  for (; i + 32 <= frames; i += 32) {
    FirV8 a0 = {}, a1 = {}, a2 = {}, a3 = {};
    for (size_t j = 0; j < taps; ++j) {
      const float c = h[j];
      const float* xj = x + i + j;
      FirV8 x0, x1, x2, x3;
      std::memcpy(&x0, xj, sizeof x0);
      std::memcpy(&x1, xj + 8, sizeof x1);
      std::memcpy(&x2, xj + 16, sizeof x2);
      std::memcpy(&x3, xj + 24, sizeof x3);
      a0 += c * x0;
      a1 += c * x1;
      a2 += c * x2;
      a3 += c * x3;
    }
    std::memcpy(y + i, &a0, sizeof a0);
    std::memcpy(y + i + 8, &a1, sizeof a1);
    std::memcpy(y + i + 16, &a2, sizeof a2);
    std::memcpy(y + i + 24, &a3, sizeof a3);
  }
  for (; i < frames; ++i) {
    float acc = 0.0f;
    for (size_t j = 0; j < taps; ++j) acc += h[j] * x[i + j];
    y[i] = acc;
  }
}
#pragma GCC diagnostic pop

}  // namespace earshot
