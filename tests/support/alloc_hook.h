#pragma once
// Allocation hook for real-time tests (alloc_hook.cpp replaces the global
// allocation functions of the test binary it is linked into).
namespace earshot::test {

/** While alive, counts every heap allocation and release made by the thread
 *  that created it (other threads are not counted). Counts start at zero. One
 *  counter at a time per process. */
class AllocationCounter {
 public:
  AllocationCounter();
  ~AllocationCounter();
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;
  long allocations() const;
  long releases() const;
  /** pthread mutex and rwlock acquisitions (counted when mallocIsHooked()). */
  long locks() const;
  /** Stops / restarts counting on this thread (e.g. around test bookkeeping). */
  void pause();
  void resume();
};

/** Page faults (minor and major) the calling thread has taken so far, or -1.
 *  A fault on the audio thread (memory it is the first to touch, or that the
 *  kernel took back) is a trap into the kernel that no allocation hook sees:
 *  ~12 us each in this project's guest machine (docs/performance.md). */
long threadPageFaults();

/** True when malloc/free themselves are hooked (glibc, no sanitizer); else
 *  only operator new/delete are seen. */
bool mallocIsHooked();

}  // namespace earshot::test
