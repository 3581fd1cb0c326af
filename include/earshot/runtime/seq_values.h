#pragma once
/** @file A few numbers a game thread sets together (a position, the
 *  listener's pose) and other threads read together, never mixed.
 *
 *  Each number in an atomic of its own let a reader (the audio thread, a
 *  simulation) take some from one update and the rest from the next: a
 *  source teleported from (100, 0, 0) to (0, 100, 0) could be read at
 *  (0, 0, 0) for a block, and a listener's pitch snapped by 90 degrees could
 *  be read with the new forward and the old up, parallel, a frame with no
 *  right-hand vector. SeqValues is a sequence lock: a store() makes the
 *  count odd, writes, and makes it even again; a reader keeps what it read
 *  only if the count was even and unchanged around its reads.
 *
 *  A reader never waits: tryLoad() tries kTries times and, if each overlapped
 *  a store (a writer preempted in the middle of its few stores), gives up,
 *  and the audio thread keeps what it read last. Writers wait for each other
 *  (a mutex: game and simulation threads only). Every number is an atomic
 *  (release stores, acquire loads), so no read is a data race. */
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <thread>

namespace earshot::runtime {

template <size_t N>
class SeqValues {
 public:
  static constexpr int kTries = 4;

  explicit SeqValues(const std::array<double, N>& initial = {}) {
    for (size_t i = 0; i < N; ++i) mValues[i].store(initial[i], std::memory_order_relaxed);
  }
  SeqValues(const SeqValues&) = delete;
  SeqValues& operator=(const SeqValues&) = delete;

  /** Sets all N at once. Thread: any but the audio thread (it may wait for
   *  another writer). */
  void store(const std::array<double, N>& v) {
    std::lock_guard<std::mutex> lock(mWriters);
    storeLocked(v);
  }

  /** Changes some of the N, the rest as the last store() left them: `f`
   *  gets them and changes them in place, then they are stored whole. Two
   *  writers' update() and store() never lose each other's numbers.
   *  Thread: as store(). */
  template <class F>
  void update(F&& f) {
    std::lock_guard<std::mutex> lock(mWriters);
    std::array<double, N> v;
    for (size_t i = 0; i < N; ++i) v[i] = mValues[i].load(std::memory_order_relaxed);  // (only writers change them)
    f(v);
    storeLocked(v);
  }

  /** The N of one store() (or the initial ones) into `out`, true; false with
   *  `out` unchanged when each of kTries reads overlapped a store. Thread:
   *  any. Real-time safe (no lock, no wait, bounded time). */
  bool tryLoad(std::array<double, N>& out) const {
    for (int t = 0; t < kTries; ++t) {
      const uint32_t s1 = mSeq.load(std::memory_order_acquire);
      if (s1 & 1u) continue;
      std::array<double, N> v;
      for (size_t i = 0; i < N; ++i) v[i] = mValues[i].load(std::memory_order_acquire);
      if (mSeq.load(std::memory_order_relaxed) == s1) {
        out = v;
        return true;
      }
    }
    return false;
  }

  /** tryLoad() until it succeeds (yielding in between). Thread: any but the
   *  audio thread. */
  std::array<double, N> load() const {
    std::array<double, N> v{};
    while (!tryLoad(v)) std::this_thread::yield();
    return v;
  }

 private:
  void storeLocked(const std::array<double, N>& v) {  // (mWriters held)
    // Each number a release store after the odd count, each read an
    // acquire: a reader that reads a number of this store then sees the
    // count changed (no standalone fence, which ThreadSanitizer does not
    // model; on x86 these are plain moves all the same).
    const uint32_t s = mSeq.load(std::memory_order_relaxed);
    mSeq.store(s + 1, std::memory_order_relaxed);
    for (size_t i = 0; i < N; ++i) mValues[i].store(v[i], std::memory_order_release);
    mSeq.store(s + 2, std::memory_order_release);
  }

  std::atomic<uint32_t> mSeq{0};
  std::atomic<double> mValues[N];
  std::mutex mWriters;
};

}  // namespace earshot::runtime
