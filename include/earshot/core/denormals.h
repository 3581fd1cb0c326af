#pragma once
/** @file Scope guard that sets flush-to-zero and denormals-are-zero (SSE MXCSR)
 *  and restores the previous mode on exit. Use in every tracing thread and on
 *  the audio thread. Real-time safe: no allocation, no system call. */
#include <cstdint>

namespace earshot {

class ScopedFlushDenormals {
 public:
  ScopedFlushDenormals();
  ~ScopedFlushDenormals();
  ScopedFlushDenormals(const ScopedFlushDenormals&) = delete;
  ScopedFlushDenormals& operator=(const ScopedFlushDenormals&) = delete;

 private:
  uint32_t mSaved = 0;
};

}  // namespace earshot
