// Complex multiply-accumulate kernels. Plain loops over split real/imaginary
// arrays with restrict pointers, which GCC and Clang vectorise; on x86-64 an
// AVX2+FMA clone is chosen at load time (ifunc) when the CPU has it.
#include "mac_kernels.h"

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__) && \
    !defined(__SANITIZE_ADDRESS__)
#define EARSHOT_MAC_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define EARSHOT_MAC_CLONES
#endif

namespace earshot::dsp_detail {

EARSHOT_MAC_CLONES
void complexMac(float* __restrict ar, float* __restrict ai, const float* __restrict xr, const float* __restrict xi,
                const float* __restrict hr, const float* __restrict hi, size_t count) {
  for (size_t i = 0; i < count; ++i) {
    ar[i] += xr[i] * hr[i] - xi[i] * hi[i];
    ai[i] += xr[i] * hi[i] + xi[i] * hr[i];
  }
}

EARSHOT_MAC_CLONES
void complexMacNeg(float* __restrict ar, float* __restrict ai, const float* __restrict xr,
                   const float* __restrict xi, const float* __restrict hr, const float* __restrict hi,
                   size_t count) {
  for (size_t i = 0; i < count; ++i) {
    ar[i] -= xr[i] * hr[i] - xi[i] * hi[i];
    ai[i] -= xr[i] * hi[i] + xi[i] * hr[i];
  }
}

EARSHOT_MAC_CLONES
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
