#pragma once
// Complex multiply-accumulate kernels over split real/imaginary arrays, the
// convolver's hot loop. `count` is a multiple of 8; arrays are 64-byte
// aligned and do not alias. Internal to src/dsp.
#include <cstddef>
#include <cstdint>

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

/** IEEE 754 binary16 from float, rounded to nearest even (overflow to inf,
 *  which PreparedIr's per-channel scale rules out). */
uint16_t floatToHalf(float v);
/** float from IEEE 754 binary16 (exact). */
float halfToFloat(uint16_t h);
/** out[i] = floatToHalf(in[i] / scale) for n finite values: eight at a time
 *  with F16C's conversion (the same rounding) where the CPU has it.
 *  PreparedIr's compact spectra: in software the conversion and division
 *  were a quarter of an offline render. */
void floatsToHalves(const float* in, float scale, uint16_t* out, size_t n);
/** The software loop floatsToHalves falls back to (tested against it). */
void floatsToHalvesPortable(const float* in, float scale, uint16_t* out, size_t n);
/** The largest |v[i]| of n finite values (SSE2: four at a time; the same value). */
float peakMagnitude(const float* v, size_t n);

/** Compact (binary16) spectra of one level and channel: its K partitions of
 *  `stride` bins (a multiple of 8) interleaved by bin tiles, so that the
 *  multiply-accumulate reads them as one stream: for each 32-bin tile t
 *  (t < stride / 32) the K partitions' 32 real then 32 imaginary halves,
 *  then for each remaining 8-bin tile u the K partitions' 8 real then 8
 *  imaginary halves. Offset of partition k's tile starting at bin i (a
 *  tile start) in the level-channel block. */
inline size_t compactTileOffset(size_t i, size_t k, size_t partitions, size_t stride) {
  const size_t full = stride / 32 * 32;
  if (i < full) return (i / 32) * partitions * 64 + k * 64;
  return full * partitions * 2 + ((i - full) / 8) * partitions * 16 + k * 16;
}
/** Width (bins) of the tile starting at bin i. */
inline size_t compactTileWidth(size_t i, size_t stride) { return i < stride / 32 * 32 ? 32 : 8; }

/** complexMacBatch over compact spectra (`h`: a level-channel block laid
 *  out as compactTileOffset says, with `partitions` partitions), for its
 *  partitions k0 .. k0 + parts - 1 against x[0 .. parts - 1], all under one
 *  `scale`: (ar, ai) += scale * sum_j X_j * H_(k0 + j), over `stride` bins.
 *  AVX2+F16C where the CPU has them (chosen once), else a portable loop. */
void complexMacBatchHalf(float* ar, float* ai, const float* const* x, const uint16_t* h, size_t k0, size_t parts,
                         size_t partitions, size_t stride, float scale);
/** The portable loop complexMacBatchHalf falls back to (tested against
 *  the AVX2 + F16C version where the CPU has it). */
void complexMacBatchHalfPortable(float* ar, float* ai, const float* const* x, const uint16_t* h, size_t k0,
                                 size_t parts, size_t partitions, size_t stride, float scale);
/** A fading source's difference over compact spectra of one layout:
 *  (ar, ai) += sum_j X_j * (sp * P_(k0 + j) - sc * C_(k0 + j)), each
 *  difference made first (sp * p and sc * c rounded, then subtracted: zero
 *  for two equal IRs), then multiplied in with the register tiles of
 *  complexMacBatchHalf. AVX2 + F16C where the CPU has them. */
void complexMacDiffBatchHalf(float* ar, float* ai, const float* const* x, const uint16_t* p, float sp,
                             const uint16_t* c, float sc, size_t k0, size_t parts, size_t partitions,
                             size_t stride);
/** The portable loop complexMacDiffBatchHalf falls back to (tested against
 *  the AVX2 + F16C version where the CPU has it). */
void complexMacDiffBatchHalfPortable(float* ar, float* ai, const float* const* x, const uint16_t* p, float sp,
                                     const uint16_t* c, float sc, size_t k0, size_t parts, size_t partitions,
                                     size_t stride);
/** Partition k of a compact level-channel block as floats times `scale`:
 *  `stride` real parts, then `stride` imaginary parts (the float kernels'
 *  layout; used while an IR fades). F16C where the CPU has it. */
void compactPartitionToFloats(const uint16_t* h, size_t k, size_t partitions, size_t stride, float scale,
                              float* out);
/** The portable loop compactPartitionToFloats falls back to (tested against
 *  the F16C version where the CPU has it). */
void compactPartitionToFloatsPortable(const uint16_t* h, size_t k, size_t partitions, size_t stride, float scale,
                                      float* out);

}  // namespace earshot::dsp_detail
