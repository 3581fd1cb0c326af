#pragma once
/** @file A direct-form FIR over a block: y[i] = sum_j h[j] x[i + j] for
 *  i < frames, x holding frames + taps - 1 samples (h reversed for a
 *  convolution). The direct voices' HRIRs and the IR synthesis's band
 *  envelopes use it. On x86-64 (GCC) an AVX2+FMA clone is chosen at load
 *  time where the CPU has it; each output sums its taps in the order
 *  j = 0 .. taps - 1 either way. Real-time safe: no allocation. */
#include <cstddef>

namespace earshot {

void firInto(const float* h, size_t taps, const float* x, float* y, size_t frames);

}  // namespace earshot
