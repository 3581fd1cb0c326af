#include "earshot/core/denormals.h"

#if defined(__SSE__) || defined(__x86_64__)
#include <xmmintrin.h>
#define EARSHOT_HAVE_MXCSR 1
#endif

namespace earshot {

ScopedFlushDenormals::ScopedFlushDenormals() {
#ifdef EARSHOT_HAVE_MXCSR
  mSaved = _mm_getcsr();
  // FTZ (bit 15) and DAZ (bit 6).
  _mm_setcsr(mSaved | 0x8040u);
#endif
}

ScopedFlushDenormals::~ScopedFlushDenormals() {
#ifdef EARSHOT_HAVE_MXCSR
  _mm_setcsr(mSaved);
#endif
}

}  // namespace earshot
