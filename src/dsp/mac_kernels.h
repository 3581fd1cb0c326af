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

#include <cstdint>

namespace earshot::dsp_detail {

/** IEEE 754 binary16 from float, rounded to nearest even (overflow to inf,
 *  which PreparedIr's per-channel scale rules out). */
uint16_t floatToHalf(float v);
/** float from IEEE 754 binary16 (exact). */
float halfToFloat(uint16_t h);

/** complexMacBatch with the H spectra in binary16 (count re, then at
 *  + stride count im halves per partition), all under one `scale`:
 *  (ar, ai) += scale * sum_j X_j * H_j. AVX2+F16C where the CPU has them
 *  (chosen once), else a portable loop. */
void complexMacBatchHalf(float* ar, float* ai, const float* const* x, const uint16_t* const* h, size_t parts,
                         size_t stride, size_t count, float scale);
/** The portable loop complexMacBatchHalf falls back to (tested against
 *  the AVX2 + F16C version where the CPU has it). */
void complexMacBatchHalfPortable(float* ar, float* ai, const float* const* x, const uint16_t* const* h,
                                 size_t parts, size_t stride, size_t count, float scale);
/** `count` halves to floats times `scale` (a partition's spectrum for the
 *  float kernels while an IR fades). */
void halvesToFloats(const uint16_t* h, float* out, size_t count, float scale);

}  // namespace earshot::dsp_detail
