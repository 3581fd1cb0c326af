// Temporary files an interrupted program removes: see temp_files.h.
#include "earshot/io/temp_files.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>

namespace earshot {

namespace {

// A slot's state: free, being filled, registered, being removed by
// removeTempFilesNow(), removed. Only the guard that filled a slot frees it,
// so a removal never reads a path another guard is writing.
enum : int { kFree = 0, kFilling = 1, kRegistered = 2, kRemoving = 3, kRemoved = 4 };
constexpr size_t kMaxPath = 4096;

struct Slot {
  std::atomic<int> state{kFree};
  char path[kMaxPath];
};
static_assert(std::atomic<int>::is_always_lock_free, "a signal handler reads the slots");

Slot gSlots[TempFileGuard::kMaxTempFiles];

extern "C" void onTerminationSignal(int sig) {
  const int savedErrno = errno;
  removeTempFilesNow();
  // Die of the same signal, as if it had not been caught.
  ::signal(sig, SIG_DFL);
  errno = savedErrno;
  ::raise(sig);
}

}  // namespace

TempFileGuard::TempFileGuard(const std::string& path) {
  if (path.empty() || path.size() >= kMaxPath || path.find('\0') != std::string::npos) return;
  for (int i = 0; i < kMaxTempFiles; ++i) {
    int expected = kFree;
    if (!gSlots[i].state.compare_exchange_strong(expected, kFilling, std::memory_order_acquire)) continue;
    std::memcpy(gSlots[i].path, path.c_str(), path.size() + 1);
    gSlots[i].state.store(kRegistered, std::memory_order_release);
    mSlot = i;
    return;
  }
}

TempFileGuard::~TempFileGuard() {
  if (mSlot < 0) return;
  std::atomic<int>& state = gSlots[mSlot].state;
  for (;;) {
    int expected = kRegistered;
    if (state.compare_exchange_strong(expected, kFree, std::memory_order_acq_rel)) return;
    if (expected == kRemoved) {
      state.store(kFree, std::memory_order_release);
      return;
    }
    // kRemoving: a removal on another thread is unlinking it (a few
    // microseconds; a signal's removal then ends the process).
  }
}

int removeTempFilesNow() noexcept {
  int removed = 0;
  for (Slot& s : gSlots) {
    int expected = kRegistered;
    if (!s.state.compare_exchange_strong(expected, kRemoving, std::memory_order_acq_rel)) continue;
    removed += ::unlink(s.path) == 0;
    s.state.store(kRemoved, std::memory_order_release);
  }
  return removed;
}

void removeTempFilesOnTerminationSignals() {
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction old {};
    if (::sigaction(sig, nullptr, &old) != 0 || old.sa_handler == SIG_IGN) continue;
    struct sigaction sa {};
    sa.sa_handler = onTerminationSignal;
    sigemptyset(&sa.sa_mask);
    // Another of these signals while removing waits (no second handler on top).
    sigaddset(&sa.sa_mask, SIGINT);
    sigaddset(&sa.sa_mask, SIGTERM);
    sigaddset(&sa.sa_mask, SIGHUP);
    sa.sa_flags = SA_RESETHAND;
    ::sigaction(sig, &sa, nullptr);
  }
}

}  // namespace earshot
