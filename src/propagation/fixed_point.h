// The reflection tracer's fixed-point sums (internal): histogram adds
// that give the same bits in any order, hence whatever the thread count.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define EARSHOT_FIXED_AVX 1
#endif

namespace earshot::detail {

// Fixed point for order-independent (hence thread-count-independent) sums:
// 2^-50 ~ 8.9e-16 of the energy of a direct sound at 1 m; the largest bin
// value is 2^13 = 8192 (a reflection 1 cm away is 1e4; saturates there).
constexpr double kFixedScale = 1125899906842624.0;  // 2^50
constexpr double kFixedMax = 9.2e18;

// Saturating add: a bin of an absurd scene (a 1 cm room, 1000 bounces) can
// exceed the format's 2^13 range; it then stays at the limit instead of
// overflowing. For non-negative sums (energies) saturation is associative,
// so results stay thread-count independent; only a saturated signed
// direction sum could depend on the order.
inline void addSat(int64_t& acc, int64_t v) {
  if (__builtin_add_overflow(acc, v, &acc)) acc = v > 0 ? INT64_MAX : INT64_MIN;
}

// Round to nearest (ties away from zero) by truncation: no libm call. The
// clamp keeps NaN at +kFixedMax. Branch-free (minsd/maxsd, copysign): the
// tracer makes ~20 of these per segment.
inline int64_t toFixed(double v) {
#if defined(__SSE2__)
  __m128d x = _mm_set_sd(v * kFixedScale);
  x = _mm_min_sd(x, _mm_set_sd(kFixedMax));   // x < max ? x : max (NaN -> max)
  x = _mm_max_sd(x, _mm_set_sd(-kFixedMax));  // x > -max ? x : -max
  const double s = _mm_cvtsd_f64(x);
#else
  double s = v * kFixedScale;
  s = std::max(-kFixedMax, std::min(kFixedMax, s));
#endif
  return int64_t(s + std::copysign(0.5, s));
}

// toFixed() of v[0, kFixedBatch) into q, the same bits: with AVX four at a
// time (the half added, truncated, and the exact integer moved into a
// double's mantissa by adding 2^52 + 2^51), the scalar code for a group
// with a value at or beyond 2^51 - 2 of the fixed scale (or NaN), where
// that move is not exact. A deposit's ten values at once (with the held adds
// kept as runs: 32 sources detected in kept paths, 195 -> 172 ms).
constexpr size_t kFixedBatch = 12;
#if defined(EARSHOT_FIXED_AVX)
__attribute__((target("avx"))) inline void toFixedBatchAvx(const double* v, int64_t* q) {
  const __m256d scale = _mm256_set1_pd(kFixedScale), sign = _mm256_set1_pd(-0.0);
  const __m256d limit = _mm256_set1_pd(2251799813685246.0);  // 2^51 - 2
  const __m256d magic = _mm256_set1_pd(6755399441055744.0);  // 2^52 + 2^51
  const __m128i magicBits = _mm_set1_epi64x(0x4338000000000000LL);
  for (size_t i = 0; i < kFixedBatch; i += 4) {
    const __m256d s = _mm256_mul_pd(_mm256_loadu_pd(v + i), scale);
    if (_mm256_movemask_pd(_mm256_cmp_pd(_mm256_andnot_pd(sign, s), limit, _CMP_LT_OQ)) != 0xF) {
      for (size_t k = i; k < i + 4; ++k) q[k] = toFixed(v[k]);
      continue;
    }
    const __m256d half = _mm256_or_pd(_mm256_and_pd(s, sign), _mm256_set1_pd(0.5));
    const __m256d t = _mm256_round_pd(_mm256_add_pd(s, half), _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC);
    const __m256i u = _mm256_castpd_si256(_mm256_add_pd(t, magic));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(q + i), _mm_sub_epi64(_mm256_castsi256_si128(u), magicBits));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(q + i + 2),
                     _mm_sub_epi64(_mm256_extractf128_si256(u, 1), magicBits));
  }
}
#endif
inline void toFixedBatch(const double* v, int64_t* q, bool avx) {
#if defined(EARSHOT_FIXED_AVX)
  if (avx) return toFixedBatchAvx(v, q);
#endif
  (void)avx;
  for (size_t k = 0; k < kFixedBatch; ++k) q[k] = toFixed(v[k]);
}

}  // namespace earshot::detail
