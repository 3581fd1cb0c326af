#pragma once
// Complex multiply-accumulate kernels over split real/imaginary arrays, the
// convolver's hot loop. `count` is a multiple of 8; arrays are 64-byte
// aligned and do not alias. Internal to src/dsp.
#include <cstddef>

namespace earshot::dsp_detail {

/** (ar, ai) += (xr, xi) * (hr, hi), element-wise complex. */
void complexMac(float* ar, float* ai, const float* xr, const float* xi, const float* hr, const float* hi,
                size_t count);
/** (ar, ai) += sum_j X_j * H_j over `parts` pairs, where x[j] and h[j] each
 *  point at `count` real parts followed (at + stride) by the imaginary parts.
 *  Keeps a tile of the accumulator in registers across all pairs, so the
 *  accumulator is read and written once instead of once per partition. */
void complexMacBatch(float* ar, float* ai, const float* const* x, const float* const* h, size_t parts,
                     size_t stride, size_t count);
/** Two channels at once (binaural): (a0r, a0i) += sum_j X_j * H0_j and
 *  (a1r, a1i) += sum_j X_j * H1_j, reading each X_j once. */
void complexMacBatch2(float* a0r, float* a0i, float* a1r, float* a1i, const float* const* x,
                      const float* const* h0, const float* const* h1, size_t parts, size_t stride, size_t count);
/** (ar, ai) -= (xr, xi) * (hr, hi). */
void complexMacNeg(float* ar, float* ai, const float* xr, const float* xi, const float* hr, const float* hi,
                   size_t count);
/** (ar, ai) += (xr, xi) * ((pr, pi) - (cr, ci)). */
void complexMacDiff(float* ar, float* ai, const float* xr, const float* xi, const float* pr, const float* pi,
                    const float* cr, const float* ci, size_t count);

}  // namespace earshot::dsp_detail
