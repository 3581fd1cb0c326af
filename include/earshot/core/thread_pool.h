#pragma once
/** @file A persistent worker pool (spawning a thread costs ~26 us; docs/design.md).
 *  parallelFor hands out task indices dynamically; callers that need
 *  bit-identical results for any thread count make each task's output depend
 *  only on its index and combine outputs in index order afterwards. */
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace earshot {

/** Raises the calling thread's nice value by `niceIncrement` (Linux; no-op
 *  elsewhere, for <= 0, or where refused). */
void lowerThisThreadsPriority(int niceIncrement);

class ThreadPool {
 public:
  /** @param threads total threads that work in parallelFor, including the
   *  caller; 0 = hardware concurrency.
   *  @param niceIncrement added to the pool's own threads' nice value (Linux:
   *  per thread; > 0 runs them below other work, e.g. an audio thread; not
   *  the caller's thread). Where the system refuses, they run as they are. */
  explicit ThreadPool(unsigned threads = 0, int niceIncrement = 0);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  unsigned threadCount() const { return unsigned(mWorkers.size()) + 1; }

  /** Calls fn(taskIndex, workerIndex) for every taskIndex in [0, taskCount),
   *  on the pool's threads and the caller's; returns when all are done.
   *  workerIndex is in [0, threadCount()). Every worker runs with denormals
   *  flushed. If fn throws (e.g. std::bad_alloc), no further task starts
   *  and the first exception is rethrown here once the running ones have
   *  finished (a worker thread never terminates the process). Not
   *  reentrant. */
  void parallelFor(size_t taskCount, const std::function<void(size_t, unsigned)>& fn);

 private:
  void workerLoop(unsigned workerIndex);
  void runTasks(unsigned workerIndex);

  std::vector<std::thread> mWorkers;
  std::mutex mMutex;
  std::condition_variable mWake, mDone;
  const std::function<void(size_t, unsigned)>* mFn = nullptr;
  std::exception_ptr mError;  // the first task's exception in this parallelFor
  size_t mTaskCount = 0;
  size_t mNextTask = 0;
  unsigned mBusy = 0;
  uint64_t mGeneration = 0;
  bool mStop = false;
};

}  // namespace earshot
