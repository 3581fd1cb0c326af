#include "earshot/core/thread_pool.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>

#include "earshot/core/denormals.h"

namespace earshot {

void lowerThisThreadsPriority(int niceIncrement) {
  if (niceIncrement <= 0) return;
#if defined(__linux__)
  // Linux keeps a nice value per thread (PRIO_PROCESS with a thread id).
  const id_t tid = id_t(::syscall(SYS_gettid));
  errno = 0;
  const int now = ::getpriority(PRIO_PROCESS, tid);
  if (errno == 0) (void)::setpriority(PRIO_PROCESS, tid, std::min(19, now + niceIncrement));
#endif
}

ThreadPool::ThreadPool(unsigned threads, int niceIncrement) {
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  for (unsigned i = 1; i < threads; ++i)
    mWorkers.emplace_back([this, i, niceIncrement] {
      lowerThisThreadsPriority(niceIncrement);
      workerLoop(i);
    });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mMutex);
    mStop = true;
  }
  mWake.notify_all();
  for (auto& t : mWorkers) t.join();
}

void ThreadPool::runTasks(unsigned workerIndex) {
  ScopedFlushDenormals ftz;
  for (;;) {
    size_t task;
    {
      std::lock_guard<std::mutex> lock(mMutex);
      if (mNextTask >= mTaskCount) return;
      task = mNextTask++;
    }
    try {
      (*mFn)(task, workerIndex);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mMutex);
      if (!mError) mError = std::current_exception();
      mNextTask = mTaskCount;  // no further task starts
    }
  }
}

void ThreadPool::workerLoop(unsigned workerIndex) {
  uint64_t seen = 0;
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mMutex);
      mWake.wait(lock, [&] { return mStop || mGeneration != seen; });
      if (mStop) return;
      seen = mGeneration;
      ++mBusy;
    }
    runTasks(workerIndex);
    {
      std::lock_guard<std::mutex> lock(mMutex);
      --mBusy;
    }
    mDone.notify_all();
  }
}

void ThreadPool::parallelFor(size_t taskCount, const std::function<void(size_t, unsigned)>& fn) {
  if (taskCount == 0) return;
  {
    std::lock_guard<std::mutex> lock(mMutex);
    mFn = &fn;
    mTaskCount = taskCount;
    mNextTask = 0;
    ++mGeneration;
  }
  mWake.notify_all();
  runTasks(0);
  std::unique_lock<std::mutex> lock(mMutex);
  // All tasks handed out; wait until every worker that joined has finished.
  mDone.wait(lock, [&] { return mBusy == 0 && mNextTask >= mTaskCount; });
  mFn = nullptr;
  if (mError) {
    std::exception_ptr error = std::move(mError);
    mError = nullptr;
    lock.unlock();
    std::rethrow_exception(error);
  }
}

}  // namespace earshot
