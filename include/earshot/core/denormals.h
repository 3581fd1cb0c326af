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

/** The calling thread's denormal mode (flush-to-zero and denormals-are-zero
 *  on or off), for a helper thread to take on with ScopedDenormalMode: what
 *  it computes is then bit for bit what the caller would have. */
uint32_t currentDenormalMode();

/** Sets the denormal mode currentDenormalMode() returned, and restores the
 *  thread's own on exit. */
class ScopedDenormalMode {
 public:
  explicit ScopedDenormalMode(uint32_t mode);
  ~ScopedDenormalMode();
  ScopedDenormalMode(const ScopedDenormalMode&) = delete;
  ScopedDenormalMode& operator=(const ScopedDenormalMode&) = delete;

 private:
  uint32_t mSaved = 0;
};

}  // namespace earshot
