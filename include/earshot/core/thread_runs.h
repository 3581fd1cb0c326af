#pragma once
/** @file forRuns: a piece of work over [0, count) cut into runs on plain
 *  threads, for work done once in a while off the audio thread (an
 *  ambisonic decoder's design, a late noise's bands) and possibly from
 *  inside a ThreadPool's task. */
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

#include "earshot/core/denormals.h"

namespace earshot {

/** body(begin, end) over [0, count) cut into at most `parts` runs whose
 *  starts are multiples of `align`: the first on this thread, the others on
 *  threads of their own in this thread's denormal mode (ScopedDenormalMode),
 *  a run with no thread to be had on this one. Work whose elements do not
 *  depend on the cut is then the same bit for bit whatever `parts`. Plain
 *  threads rather than a ThreadPool: its workers flush denormals whatever
 *  the caller does, and a pool's task cannot wait on the same pool. False
 *  if a body returned false or threw (e.g. out of memory); every run has
 *  ended when it returns. */
template <typename Body>
bool forRuns(size_t count, size_t align, size_t parts, const Body& body) {
  align = std::max<size_t>(1, align);
  const size_t per = std::max(align, (count / std::max<size_t>(1, parts) + align - 1) / align * align);
  std::atomic<bool> ok{true};
  const uint32_t mode = currentDenormalMode();
  auto run = [&](size_t begin, size_t end) {
    ScopedDenormalMode same(mode);
    try {
      if (!body(begin, end)) ok = false;
    } catch (...) {
      ok = false;
    }
  };
  std::vector<std::thread> threads;
  for (size_t begin = per; begin < count; begin += per) {
    const size_t end = std::min(count, begin + per);
    try {
      threads.emplace_back(run, begin, end);
    } catch (...) {
      run(begin, end);  // no thread to be had: this one does the run
    }
  }
  run(0, std::min(count, per));
  for (auto& t : threads) t.join();
  return ok;
}

}  // namespace earshot
