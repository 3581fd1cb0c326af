#pragma once
/** @file Temporary files an interrupted program removes.
 *
 *  Every output is written to a temporary file beside its target and
 *  renamed over it (atomic_file.h, WavStreamWriter). A program stopped by a
 *  signal (Ctrl-C, kill) never reaches the rename nor the removal on
 *  failure, and the temporary file, as large as the output so far, stays.
 *  While a TempFileGuard lives its path is registered; removeTempFilesNow()
 *  removes every registered path and is async-signal-safe. A library never
 *  installs signal handlers: a program (the earshot command) asks with
 *  removeTempFilesOnTerminationSignals(). */
#include <string>

namespace earshot {

/** Registers `path` for removal by removeTempFilesNow() while it lives.
 *  At most kMaxTempFiles paths (each under 4096 bytes) at a time; beyond,
 *  a path is not registered (nothing else changes). */
class TempFileGuard {
 public:
  static constexpr int kMaxTempFiles = 64;
  explicit TempFileGuard(const std::string& path);
  ~TempFileGuard();
  TempFileGuard(const TempFileGuard&) = delete;
  TempFileGuard& operator=(const TempFileGuard&) = delete;
  /** Whether the path is registered. */
  bool registered() const { return mSlot >= 0; }

 private:
  int mSlot = -1;
};

/** Removes every registered path (unlink), once: a path stays registered,
 *  as removed, until its guard ends. Async-signal-safe:
 *  lock-free atomics and unlink() only. Returns how many it removed. */
int removeTempFilesNow() noexcept;

/** Installs handlers for SIGINT, SIGTERM and SIGHUP (each unless ignored
 *  when called, as a shell does for background jobs) that remove the
 *  registered temporary files and then end the process by the same signal
 *  (its default action: the parent sees how it ended). For programs only. */
void removeTempFilesOnTerminationSignals();

}  // namespace earshot
