#pragma once
/** @file A value a game or simulation thread sets whole (a position, the
 *  listener's pose, a source's controls, its direct path's occlusion) and
 *  other threads read whole, never mixed.
 *
 *  Each number in an atomic of its own let a reader (the audio thread, a
 *  simulation) take some from one update and the rest from the next: a
 *  source teleported from (100, 0, 0) to (0, 100, 0) could be read at
 *  (0, 0, 0) for a block, a listener's pitch snapped by 90 degrees could be
 *  read with the new forward and the old up (parallel: no right-hand
 *  vector), and a fade from "direct sound off" to "source off" heard at
 *  full level.
 *
 *  LatestValues is a triple buffer. Writers (game and simulation threads)
 *  take a mutex, keep the values, copy them into the spare buffer and swap
 *  it with the middle one (an atomic exchange). The one taker, the audio
 *  thread, swaps the middle buffer with its own when it is newer: it never
 *  waits, never retries and always gets one store whole, the latest
 *  published (a sequence lock, which this replaced, gave up after a few
 *  reads that overlapped stores, and the audio thread then kept what it had
 *  read last: the slot's earlier controls for a new source's first block).
 *  Other readers (any thread but the audio thread) copy the kept values
 *  under the mutex. */
#include <atomic>
#include <cstdint>
#include <mutex>
#include <type_traits>

namespace earshot::runtime {

template <class T>
class LatestValues {
 public:
  // Plain values, owning no memory: a copy of what the taker takes must
  // not allocate.
  static_assert(std::is_trivially_destructible_v<T> && std::is_copy_assignable_v<T>,
                "LatestValues holds plain values");
  using Values = T;

  explicit LatestValues(const Values& initial = Values{}) : mKept(initial) {
    for (auto& b : mBuffers) b = initial;
  }
  LatestValues(const LatestValues&) = delete;
  LatestValues& operator=(const LatestValues&) = delete;

  /** Sets the whole value. Thread: any but the audio thread (it may wait for
   *  another writer). */
  void store(const Values& v) {
    std::lock_guard<std::mutex> lock(mWriters);
    mKept = v;
    publishLocked();
  }

  /** Changes part of the value, the rest as the last store left it: `f`
   *  gets it and changes it in place, then it is stored whole. Two
   *  writers' update() and store() never lose each other's changes.
   *  Thread: as store(). */
  template <class F>
  void update(F&& f) {
    std::lock_guard<std::mutex> lock(mWriters);
    f(mKept);
    publishLocked();
  }

  /** The value of the last store (or the initial one). Thread: any but the
   *  audio thread (it may wait for a writer). */
  Values load() const {
    std::lock_guard<std::mutex> lock(mWriters);
    return mKept;
  }

  /** The value of the latest store published (or the initial one), whole.
   *  Thread: one taker only, the audio thread; valid until its next take().
   *  Real-time safe (no lock, no wait, no retry). */
  const Values& take() {
    if (mMiddle.load(std::memory_order_relaxed) & kFresh)
      mFront = uint8_t(mMiddle.exchange(mFront, std::memory_order_acq_rel) & kIndex);
    return mBuffers[mFront];
  }

 private:
  static constexpr uint8_t kIndex = 3, kFresh = 4;

  // Writes the spare buffer, then makes it the middle one (fresh) and the
  // old middle the spare. The exchange's release publishes the buffer to
  // the taker's acquire; its acquire orders the taker's reads of a buffer
  // it gave back before these writes to it. (mWriters held.)
  void publishLocked() {
    mBuffers[mBack] = mKept;
    mBack = uint8_t(mMiddle.exchange(uint8_t(mBack | kFresh), std::memory_order_acq_rel) & kIndex);
  }

  mutable std::mutex mWriters;
  Values mKept;               // the last store (mWriters)
  Values mBuffers[3];         // spare (writers'), middle, front (the taker's)
  uint8_t mBack = 0;          // the spare's index (mWriters)
  std::atomic<uint8_t> mMiddle{1};  // the middle's index, | kFresh once published and not yet taken
  uint8_t mFront = 2;         // the taker's index
};

}  // namespace earshot::runtime
