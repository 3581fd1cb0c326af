// Complex multiply-accumulate kernels. Plain loops over split real/imaginary
// arrays with restrict pointers, which GCC and Clang vectorise; on x86-64 an
// AVX2+FMA clone is chosen at load time (ifunc) when the CPU has it.
#include "mac_kernels.h"

#include "earshot/core/target_clones.h"

namespace earshot::dsp_detail {

EARSHOT_CLONES
void complexMac(float* __restrict ar, float* __restrict ai, const float* __restrict xr, const float* __restrict xi,
                const float* __restrict hr, const float* __restrict hi, size_t count) {
  for (size_t i = 0; i < count; ++i) {
    ar[i] += xr[i] * hr[i] - xi[i] * hi[i];
    ai[i] += xr[i] * hi[i] + xi[i] * hr[i];
  }
}

// NOTE: written with GCC/Clang vector extensions (8 floats) so that the
// 32-float accumulator tile lives in registers; plain loops over a local
// array were kept on the stack by GCC 12.
// The default clone passes V8 in memory, the AVX clone in registers; both
// inline these helpers, so the ABI note GCC emits does not apply.
#pragma GCC diagnostic ignored "-Wpsabi"
typedef float V8 __attribute__((vector_size(32)));

static inline V8 load8(const float* p) {
  V8 v;
  __builtin_memcpy(&v, p, sizeof(v));
  return v;
}
static inline void store8(float* p, V8 v) { __builtin_memcpy(p, &v, sizeof(v)); }

EARSHOT_CLONES
void complexMacBatch(float* __restrict ar, float* __restrict ai, const float* const* x, const float* const* h,
                     size_t parts, size_t stride, size_t count) {
  size_t i = 0;
  for (; i + 32 <= count; i += 32) {
    V8 r0 = load8(ar + i), r1 = load8(ar + i + 8), r2 = load8(ar + i + 16), r3 = load8(ar + i + 24);
    V8 m0 = load8(ai + i), m1 = load8(ai + i + 8), m2 = load8(ai + i + 16), m3 = load8(ai + i + 24);
    for (size_t j = 0; j < parts; ++j) {
      const float* xr = x[j] + i;
      const float* xi = xr + stride;
      const float* hr = h[j] + i;
      const float* hi = hr + stride;
#define EARSHOT_MAC8(R, M, o)                          \
  {                                                    \
    V8 a = load8(xr + o), b = load8(xi + o);           \
    V8 c = load8(hr + o), d = load8(hi + o);           \
    R += a * c - b * d;                                \
    M += a * d + b * c;                                \
  }
      EARSHOT_MAC8(r0, m0, 0)
      EARSHOT_MAC8(r1, m1, 8)
      EARSHOT_MAC8(r2, m2, 16)
      EARSHOT_MAC8(r3, m3, 24)
    }
    store8(ar + i, r0), store8(ar + i + 8, r1), store8(ar + i + 16, r2), store8(ar + i + 24, r3);
    store8(ai + i, m0), store8(ai + i + 8, m1), store8(ai + i + 16, m2), store8(ai + i + 24, m3);
  }
  for (; i < count; i += 8) {  // tail, 8 floats at a time
    V8 r0 = load8(ar + i), m0 = load8(ai + i);
    for (size_t j = 0; j < parts; ++j) {
      const float* xr = x[j] + i;
      const float* xi = xr + stride;
      const float* hr = h[j] + i;
      const float* hi = hr + stride;
      EARSHOT_MAC8(r0, m0, 0)
    }
    store8(ar + i, r0), store8(ai + i, m0);
  }
#undef EARSHOT_MAC8
}

EARSHOT_CLONES
void complexMacBatch2(float* __restrict a0r, float* __restrict a0i, float* __restrict a1r, float* __restrict a1i,
                      const float* const* x, const float* const* h0, const float* const* h1, size_t parts,
                      size_t stride, size_t count) {
  size_t i = 0;
  for (; i + 16 <= count; i += 16) {
    V8 r00 = load8(a0r + i), r01 = load8(a0r + i + 8), m00 = load8(a0i + i), m01 = load8(a0i + i + 8);
    V8 r10 = load8(a1r + i), r11 = load8(a1r + i + 8), m10 = load8(a1i + i), m11 = load8(a1i + i + 8);
    for (size_t j = 0; j < parts; ++j) {
      const float* xr = x[j] + i;
      const float* xi = xr + stride;
      const float* p0 = h0[j] + i;
      const float* p1 = h1[j] + i;
#define EARSHOT_MAC8X2(o, R0, M0, R1, M1)              \
  {                                                    \
    V8 a = load8(xr + o), b = load8(xi + o);           \
    V8 c = load8(p0 + o), d = load8(p0 + stride + o);  \
    R0 += a * c - b * d;                               \
    M0 += a * d + b * c;                               \
    c = load8(p1 + o), d = load8(p1 + stride + o);     \
    R1 += a * c - b * d;                               \
    M1 += a * d + b * c;                               \
  }
      EARSHOT_MAC8X2(0, r00, m00, r10, m10)
      EARSHOT_MAC8X2(8, r01, m01, r11, m11)
    }
    store8(a0r + i, r00), store8(a0r + i + 8, r01), store8(a0i + i, m00), store8(a0i + i + 8, m01);
    store8(a1r + i, r10), store8(a1r + i + 8, r11), store8(a1i + i, m10), store8(a1i + i + 8, m11);
  }
  if (i < count) {  // 8-float tail
    V8 r00 = load8(a0r + i), m00 = load8(a0i + i), r10 = load8(a1r + i), m10 = load8(a1i + i);
    for (size_t j = 0; j < parts; ++j) {
      const float* xr = x[j] + i;
      const float* xi = xr + stride;
      const float* p0 = h0[j] + i;
      const float* p1 = h1[j] + i;
      EARSHOT_MAC8X2(0, r00, m00, r10, m10)
    }
    store8(a0r + i, r00), store8(a0i + i, m00), store8(a1r + i, r10), store8(a1i + i, m10);
  }
#undef EARSHOT_MAC8X2
}

EARSHOT_CLONES
void complexMacNeg(float* __restrict ar, float* __restrict ai, const float* __restrict xr,
                   const float* __restrict xi, const float* __restrict hr, const float* __restrict hi,
                   size_t count) {
  for (size_t i = 0; i < count; ++i) {
    ar[i] -= xr[i] * hr[i] - xi[i] * hi[i];
    ai[i] -= xr[i] * hi[i] + xi[i] * hr[i];
  }
}

EARSHOT_CLONES
void complexMacDiff(float* __restrict ar, float* __restrict ai, const float* __restrict xr,
                    const float* __restrict xi, const float* __restrict pr, const float* __restrict pi,
                    const float* __restrict cr, const float* __restrict ci, size_t count) {
  for (size_t i = 0; i < count; ++i) {
    float hr = pr[i] - cr[i];
    float hi = pi[i] - ci[i];
    ar[i] += xr[i] * hr - xi[i] * hi;
    ai[i] += xr[i] * hi + xi[i] * hr;
  }
}

}  // namespace earshot::dsp_detail
