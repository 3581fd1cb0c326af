// Multiply-accumulate over IR spectra stored as 16-bit floats (binary16):
// the ambisonic bus streams its sources' spectra from memory every block
// (32 sources' 0.16 s 4-channel IRs are 3 MB per block, beyond the L2
// cache), so half the bytes is most of half the time. On x86-64 an AVX2 +
// F16C version (vcvtph2ps) is chosen once when the CPU has it; elsewhere a
// portable loop with the conversion in software.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "mac_kernels.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <cpuid.h>
#include <immintrin.h>
#define EARSHOT_HAVE_F16C_PATH 1
#endif

namespace earshot::dsp_detail {

uint16_t floatToHalf(float v) {
  uint32_t f;
  std::memcpy(&f, &v, sizeof f);
  const uint32_t sign = (f >> 16) & 0x8000u;
  const uint32_t absf = f & 0x7FFFFFFFu;
  if (absf >= 0x7F800000u) return uint16_t(sign | (absf > 0x7F800000u ? 0x7E00u : 0x7C00u));  // NaN, inf
  if (absf >= 0x477FF000u) return uint16_t(sign | 0x7C00u);  // rounds to >= 65520: inf
  if (absf < 0x33000001u) return uint16_t(sign);             // below half the smallest subnormal: 0
  const int exp = int(absf >> 23) - 127;
  uint32_t mant = (absf & 0x7FFFFFu) | 0x800000u;  // 24 bits with the implicit one
  if (exp < -14) {
    // Subnormal half: value = mant * 2^(exp - 23) = m * 2^-24, m = mant >> (-exp - 1).
    const int shift = -exp - 1;  // 14 .. 24
    const uint32_t m = mant >> shift, rest = mant & ((1u << shift) - 1), halfway = 1u << (shift - 1);
    const uint32_t r = m + ((rest > halfway || (rest == halfway && (m & 1u))) ? 1u : 0u);
    return uint16_t(sign | r);  // r may carry into the smallest normal: still right
  }
  // Normal: 10 mantissa bits kept of 23, rounded to nearest even.
  uint32_t h = (uint32_t(exp + 15) << 10) | ((mant >> 13) & 0x3FFu);
  const uint32_t rest = mant & 0x1FFFu;
  if (rest > 0x1000u || (rest == 0x1000u && (h & 1u))) ++h;  // may carry into the exponent: still right
  return uint16_t(sign | h);
}

float halfToFloat(uint16_t h) {
  const uint32_t sign = uint32_t(h & 0x8000u) << 16;
  const uint32_t exp = (h >> 10) & 0x1Fu, mant = h & 0x3FFu;
  uint32_t f;
  if (exp == 0) {
    if (mant == 0) {
      f = sign;
    } else {  // subnormal: mant * 2^-24
      float v = float(mant) * (1.0f / 16777216.0f);
      std::memcpy(&f, &v, sizeof f);
      f |= sign;
    }
  } else if (exp == 31) {
    f = sign | 0x7F800000u | (mant << 13);
  } else {
    f = sign | ((exp + 112) << 23) | (mant << 13);
  }
  float v;
  std::memcpy(&v, &f, sizeof v);
  return v;
}

namespace {

#ifdef EARSHOT_HAVE_F16C_PATH
#define EARSHOT_F16C __attribute__((target("avx2,fma,f16c")))

EARSHOT_F16C static inline __m256 loadHalves(const uint16_t* p) {
  return _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
}

// As complexMacBatch: a tile of 32 bins' sums in registers over all
// partitions, added to the accumulator once, times the scale; the spectra's
// tiles are consecutive in memory (compactTileOffset).
EARSHOT_F16C void complexMacBatchHalfAvx(float* __restrict ar, float* __restrict ai, const float* const* x,
                                         const uint16_t* h, size_t k0, size_t parts, size_t partitions,
                                         size_t stride, float scale) {
  const __m256 s = _mm256_set1_ps(scale);
  const size_t full = stride / 32 * 32;
  size_t i = 0;
  for (; i < full; i += 32) {
    __m256 r[4], m[4];
    for (int t = 0; t < 4; ++t) r[t] = m[t] = _mm256_setzero_ps();
    const uint16_t* hp = h + compactTileOffset(i, k0, partitions, stride);
    for (size_t j = 0; j < parts; ++j, hp += 64) {
      const float* xr = x[j] + i;
      const float* xi = xr + stride;
      for (int t = 0; t < 4; ++t) {
        const __m256 a = _mm256_loadu_ps(xr + 8 * t), b = _mm256_loadu_ps(xi + 8 * t);
        const __m256 c = loadHalves(hp + 8 * t), d = loadHalves(hp + 32 + 8 * t);
        r[t] = _mm256_fmadd_ps(a, c, _mm256_fnmadd_ps(b, d, r[t]));
        m[t] = _mm256_fmadd_ps(a, d, _mm256_fmadd_ps(b, c, m[t]));
      }
    }
    for (int t = 0; t < 4; ++t) {
      _mm256_storeu_ps(ar + i + 8 * t, _mm256_fmadd_ps(s, r[t], _mm256_loadu_ps(ar + i + 8 * t)));
      _mm256_storeu_ps(ai + i + 8 * t, _mm256_fmadd_ps(s, m[t], _mm256_loadu_ps(ai + i + 8 * t)));
    }
  }
  for (; i < stride; i += 8) {  // 8-bin tiles
    __m256 r = _mm256_setzero_ps(), m = _mm256_setzero_ps();
    const uint16_t* hp = h + compactTileOffset(i, k0, partitions, stride);
    for (size_t j = 0; j < parts; ++j, hp += 16) {
      const __m256 a = _mm256_loadu_ps(x[j] + i), b = _mm256_loadu_ps(x[j] + i + stride);
      const __m256 c = loadHalves(hp), d = loadHalves(hp + 8);
      r = _mm256_fmadd_ps(a, c, _mm256_fnmadd_ps(b, d, r));
      m = _mm256_fmadd_ps(a, d, _mm256_fmadd_ps(b, c, m));
    }
    _mm256_storeu_ps(ar + i, _mm256_fmadd_ps(s, r, _mm256_loadu_ps(ar + i)));
    _mm256_storeu_ps(ai + i, _mm256_fmadd_ps(s, m, _mm256_loadu_ps(ai + i)));
  }
}

// complexMacDiffBatchHalf: as complexMacBatchHalfAvx, over the
// differences sp * p - sc * c (a multiply each and a subtraction, no fused
// multiply-add: equal IRs give exactly zero).
EARSHOT_F16C static inline __m256 halvesDiff(__m256 vp, const uint16_t* a, __m256 vc, const uint16_t* b) {
  return _mm256_sub_ps(_mm256_mul_ps(vp, loadHalves(a)), _mm256_mul_ps(vc, loadHalves(b)));
}

EARSHOT_F16C void complexMacDiffBatchHalfAvx(float* __restrict ar, float* __restrict ai, const float* const* x,
                                             const uint16_t* p, float sp, const uint16_t* c, float sc, size_t k0,
                                             size_t parts, size_t partitions, size_t stride) {
  const __m256 vp = _mm256_set1_ps(sp), vc = _mm256_set1_ps(sc);
  const size_t full = stride / 32 * 32;
  size_t i = 0;
  for (; i < full; i += 32) {
    __m256 r[4], m[4];
    for (int t = 0; t < 4; ++t) r[t] = m[t] = _mm256_setzero_ps();
    const size_t off = compactTileOffset(i, k0, partitions, stride);
    const uint16_t* pp = p + off;
    const uint16_t* cp = c + off;
    for (size_t j = 0; j < parts; ++j, pp += 64, cp += 64) {
      const float* xr = x[j] + i;
      const float* xi = xr + stride;
      for (int t = 0; t < 4; ++t) {
        const __m256 a = _mm256_loadu_ps(xr + 8 * t), b = _mm256_loadu_ps(xi + 8 * t);
        const __m256 dr = halvesDiff(vp, pp + 8 * t, vc, cp + 8 * t);
        const __m256 di = halvesDiff(vp, pp + 32 + 8 * t, vc, cp + 32 + 8 * t);
        r[t] = _mm256_fmadd_ps(a, dr, _mm256_fnmadd_ps(b, di, r[t]));
        m[t] = _mm256_fmadd_ps(a, di, _mm256_fmadd_ps(b, dr, m[t]));
      }
    }
    for (int t = 0; t < 4; ++t) {
      _mm256_storeu_ps(ar + i + 8 * t, _mm256_add_ps(r[t], _mm256_loadu_ps(ar + i + 8 * t)));
      _mm256_storeu_ps(ai + i + 8 * t, _mm256_add_ps(m[t], _mm256_loadu_ps(ai + i + 8 * t)));
    }
  }
  for (; i < stride; i += 8) {  // 8-bin tiles
    __m256 r = _mm256_setzero_ps(), m = _mm256_setzero_ps();
    const size_t off = compactTileOffset(i, k0, partitions, stride);
    const uint16_t* pp = p + off;
    const uint16_t* cp = c + off;
    for (size_t j = 0; j < parts; ++j, pp += 16, cp += 16) {
      const __m256 a = _mm256_loadu_ps(x[j] + i), b = _mm256_loadu_ps(x[j] + i + stride);
      const __m256 dr = halvesDiff(vp, pp, vc, cp), di = halvesDiff(vp, pp + 8, vc, cp + 8);
      r = _mm256_fmadd_ps(a, dr, _mm256_fnmadd_ps(b, di, r));
      m = _mm256_fmadd_ps(a, di, _mm256_fmadd_ps(b, dr, m));
    }
    _mm256_storeu_ps(ar + i, _mm256_add_ps(r, _mm256_loadu_ps(ar + i)));
    _mm256_storeu_ps(ai + i, _mm256_add_ps(m, _mm256_loadu_ps(ai + i)));
  }
}

// compactPartitionToFloats with vcvtph2ps (the tiles are 32 or 8 bins
// wide): the same values, the conversion being exact and the scaling one
// rounding either way. In software it took more of the audio thread than
// the fading multiply-adds it feeds.
EARSHOT_F16C void compactPartitionToFloatsAvx(const uint16_t* h, size_t k, size_t partitions, size_t stride,
                                              float scale, float* out) {
  const __m256 s = _mm256_set1_ps(scale);
  for (size_t i = 0; i < stride; i += compactTileWidth(i, stride)) {
    const size_t w = compactTileWidth(i, stride);
    const uint16_t* t = h + compactTileOffset(i, k, partitions, stride);
    for (size_t b = 0; b < w; b += 8) {
      _mm256_storeu_ps(out + i + b, _mm256_mul_ps(s, loadHalves(t + b)));
      _mm256_storeu_ps(out + stride + i + b, _mm256_mul_ps(s, loadHalves(t + w + b)));
    }
  }
}

// floatsToHalves with vcvtps2ph: IEEE rounding to nearest even, as
// floatToHalf (the division the same IEEE operation); MXCSR's flush to zero
// does not apply to the conversion, and a float denormal is a half zero
// either way.
EARSHOT_F16C void floatsToHalvesAvx(const float* in, float scale, uint16_t* out, size_t n) {
  const __m256 s = _mm256_set1_ps(scale);
  size_t i = 0;
  for (; i + 8 <= n; i += 8)
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i),
                     _mm256_cvtps_ph(_mm256_div_ps(_mm256_loadu_ps(in + i), s),
                                     _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC));
  for (; i < n; ++i) out[i] = floatToHalf(in[i] / scale);
}

bool cpuHasF16cPath() {
  __builtin_cpu_init();
  if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma")) return false;  // (AVX state enabled by the OS)
  // F16C from CPUID leaf 1 (ECX bit 29): not every compiler's
  // __builtin_cpu_supports knows "f16c" (clang 14 does not).
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  if (!__get_cpuid(1, &eax, &ebx, &ecx, &edx)) return false;
  return (ecx & (1u << 29)) != 0;
}
#else
bool cpuHasF16cPath() { return false; }
#endif

const bool kF16cPath = cpuHasF16cPath();

}  // namespace

void complexMacBatchHalfPortable(float* ar, float* ai, const float* const* x, const uint16_t* h, size_t k0,
                                 size_t parts, size_t partitions, size_t stride, float scale) {
  for (size_t i = 0; i < stride; i += compactTileWidth(i, stride)) {
    const size_t w = compactTileWidth(i, stride);
    const uint16_t* tile = h + compactTileOffset(i, k0, partitions, stride);  // partition k0 + j at + 2 w j
    for (size_t b = 0; b < w; ++b) {
      float r = 0.0f, m = 0.0f;
      for (size_t j = 0; j < parts; ++j) {
        const uint16_t* t = tile + 2 * w * j;
        const float a = x[j][i + b], bb = x[j][i + b + stride];
        const float c = halfToFloat(t[b]), d = halfToFloat(t[w + b]);
        r += a * c - bb * d;
        m += a * d + bb * c;
      }
      ar[i + b] += scale * r;
      ai[i + b] += scale * m;
    }
  }
}

void complexMacDiffBatchHalfPortable(float* ar, float* ai, const float* const* x, const uint16_t* p, float sp,
                                     const uint16_t* c, float sc, size_t k0, size_t parts, size_t partitions,
                                     size_t stride) {
  for (size_t i = 0; i < stride; i += compactTileWidth(i, stride)) {
    const size_t w = compactTileWidth(i, stride);
    const size_t off = compactTileOffset(i, k0, partitions, stride);  // partition k0 + j at + 2 w j
    for (size_t b = 0; b < w; ++b) {
      float r = 0.0f, m = 0.0f;
      for (size_t j = 0; j < parts; ++j) {
        const uint16_t* tp = p + off + 2 * w * j;
        const uint16_t* tc = c + off + 2 * w * j;
        const float a = x[j][i + b], bb = x[j][i + b + stride];
        // Products apart from the subtraction (no contraction into a fused
        // multiply-add where the target has one): equal IRs give zero.
        const float pr = sp * halfToFloat(tp[b]), cr = sc * halfToFloat(tc[b]);
        const float pi = sp * halfToFloat(tp[w + b]), ci = sc * halfToFloat(tc[w + b]);
        const float dr = pr - cr, di = pi - ci;
        r += a * dr - bb * di;
        m += a * di + bb * dr;
      }
      ar[i + b] += r;
      ai[i + b] += m;
    }
  }
}

void compactPartitionToFloatsPortable(const uint16_t* h, size_t k, size_t partitions, size_t stride, float scale,
                                      float* out) {
  for (size_t i = 0; i < stride; i += compactTileWidth(i, stride)) {
    const size_t w = compactTileWidth(i, stride);
    const uint16_t* t = h + compactTileOffset(i, k, partitions, stride);
    for (size_t b = 0; b < w; ++b) {
      out[i + b] = scale * halfToFloat(t[b]);
      out[stride + i + b] = scale * halfToFloat(t[w + b]);
    }
  }
}

void floatsToHalvesPortable(const float* in, float scale, uint16_t* out, size_t n) {
  for (size_t i = 0; i < n; ++i) out[i] = floatToHalf(in[i] / scale);
}

void floatsToHalves(const float* in, float scale, uint16_t* out, size_t n) {
#ifdef EARSHOT_HAVE_F16C_PATH
  if (kF16cPath) return floatsToHalvesAvx(in, scale, out, n);
#endif
  floatsToHalvesPortable(in, scale, out, n);
}

float peakMagnitude(const float* v, size_t n) {
  float peak = 0.0f;
  size_t i = 0;
#if defined(__SSE2__)
  const __m128 mask = _mm_castsi128_ps(_mm_set1_epi32(0x7FFFFFFF));
  __m128 m = _mm_setzero_ps();
  for (; i + 4 <= n; i += 4) m = _mm_max_ps(m, _mm_and_ps(mask, _mm_loadu_ps(v + i)));
  float lanes[4];
  _mm_storeu_ps(lanes, m);
  for (float l : lanes) peak = std::max(peak, l);
#endif
  for (; i < n; ++i) peak = std::max(peak, std::fabs(v[i]));
  return peak;
}

void compactPartitionToFloats(const uint16_t* h, size_t k, size_t partitions, size_t stride, float scale,
                              float* out) {
#ifdef EARSHOT_HAVE_F16C_PATH
  if (kF16cPath) return compactPartitionToFloatsAvx(h, k, partitions, stride, scale, out);
#endif
  compactPartitionToFloatsPortable(h, k, partitions, stride, scale, out);
}

void complexMacDiffBatchHalf(float* ar, float* ai, const float* const* x, const uint16_t* p, float sp,
                             const uint16_t* c, float sc, size_t k0, size_t parts, size_t partitions,
                             size_t stride) {
#ifdef EARSHOT_HAVE_F16C_PATH
  if (kF16cPath) return complexMacDiffBatchHalfAvx(ar, ai, x, p, sp, c, sc, k0, parts, partitions, stride);
#endif
  complexMacDiffBatchHalfPortable(ar, ai, x, p, sp, c, sc, k0, parts, partitions, stride);
}

void complexMacBatchHalf(float* ar, float* ai, const float* const* x, const uint16_t* h, size_t k0, size_t parts,
                         size_t partitions, size_t stride, float scale) {
#ifdef EARSHOT_HAVE_F16C_PATH
  if (kF16cPath) return complexMacBatchHalfAvx(ar, ai, x, h, k0, parts, partitions, stride, scale);
#endif
  complexMacBatchHalfPortable(ar, ai, x, h, k0, parts, partitions, stride, scale);
}

}  // namespace earshot::dsp_detail
