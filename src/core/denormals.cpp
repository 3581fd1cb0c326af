#include "earshot/core/denormals.h"

#include <cstdint>

#if defined(__SSE__) || defined(__x86_64__)
#include <xmmintrin.h>
#define EARSHOT_HAVE_MXCSR 1
#elif defined(__aarch64__)
#define EARSHOT_HAVE_FPCR 1   // AArch64: FPCR.FZ (bit 24) flushes denormals
#elif defined(__arm__) && defined(__ARM_FP)
#define EARSHOT_HAVE_FPSCR 1  // ARMv7 VFP/NEON: FPSCR.FZ (bit 24)
#endif

namespace earshot {

ScopedFlushDenormals::ScopedFlushDenormals() {
#if defined(EARSHOT_HAVE_MXCSR)
  mSaved = _mm_getcsr();
  // FTZ (bit 15) and DAZ (bit 6).
  _mm_setcsr(mSaved | 0x8040u);
#elif defined(EARSHOT_HAVE_FPCR)
  uint64_t fpcr;
  __asm__ __volatile__("mrs %0, fpcr" : "=r"(fpcr));
  mSaved = uint32_t(fpcr);
  __asm__ __volatile__("msr fpcr, %0" : : "r"(fpcr | (uint64_t(1) << 24)));
#elif defined(EARSHOT_HAVE_FPSCR)
  uint32_t fpscr;
  __asm__ __volatile__("vmrs %0, fpscr" : "=r"(fpscr));
  mSaved = fpscr;
  __asm__ __volatile__("vmsr fpscr, %0" : : "r"(fpscr | (uint32_t(1) << 24)));
#endif
}

ScopedFlushDenormals::~ScopedFlushDenormals() {
#if defined(EARSHOT_HAVE_MXCSR)
  _mm_setcsr(mSaved);
#elif defined(EARSHOT_HAVE_FPCR)
  uint64_t fpcr;
  __asm__ __volatile__("mrs %0, fpcr" : "=r"(fpcr));
  // Only FZ is restored; the rest of FPCR is left as it is now.
  fpcr = (fpcr & ~(uint64_t(1) << 24)) | (uint64_t(mSaved) & (uint64_t(1) << 24));
  __asm__ __volatile__("msr fpcr, %0" : : "r"(fpcr));
#elif defined(EARSHOT_HAVE_FPSCR)
  __asm__ __volatile__("vmsr fpscr, %0" : : "r"(mSaved));
#endif
}

namespace {
#if defined(EARSHOT_HAVE_MXCSR)
constexpr uint32_t kModeBits = 0x8040u;  // FTZ, DAZ
#else
constexpr uint32_t kModeBits = uint32_t(1) << 24;  // FZ
#endif

uint32_t readControl() {
#if defined(EARSHOT_HAVE_MXCSR)
  return _mm_getcsr();
#elif defined(EARSHOT_HAVE_FPCR)
  uint64_t fpcr;
  __asm__ __volatile__("mrs %0, fpcr" : "=r"(fpcr));
  return uint32_t(fpcr);
#elif defined(EARSHOT_HAVE_FPSCR)
  uint32_t fpscr;
  __asm__ __volatile__("vmrs %0, fpscr" : "=r"(fpscr));
  return fpscr;
#else
  return 0;
#endif
}

// The mode bits set to `mode`'s, the rest of the control state kept.
void writeModeBits(uint32_t mode) {
#if defined(EARSHOT_HAVE_MXCSR)
  _mm_setcsr((_mm_getcsr() & ~kModeBits) | (mode & kModeBits));
#elif defined(EARSHOT_HAVE_FPCR)
  uint64_t fpcr;
  __asm__ __volatile__("mrs %0, fpcr" : "=r"(fpcr));
  fpcr = (fpcr & ~uint64_t(kModeBits)) | uint64_t(mode & kModeBits);
  __asm__ __volatile__("msr fpcr, %0" : : "r"(fpcr));
#elif defined(EARSHOT_HAVE_FPSCR)
  uint32_t fpscr;
  __asm__ __volatile__("vmrs %0, fpscr" : "=r"(fpscr));
  fpscr = (fpscr & ~kModeBits) | (mode & kModeBits);
  __asm__ __volatile__("vmsr fpscr, %0" : : "r"(fpscr));
#else
  (void)mode;
#endif
}
}  // namespace

uint32_t currentDenormalMode() { return readControl() & kModeBits; }

ScopedDenormalMode::ScopedDenormalMode(uint32_t mode) : mSaved(currentDenormalMode()) { writeModeBits(mode); }

ScopedDenormalMode::~ScopedDenormalMode() { writeModeBits(mSaved); }

}  // namespace earshot
