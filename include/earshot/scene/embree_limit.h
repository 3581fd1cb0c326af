#pragma once
/** @file The Embree limit of a trace (issue 16): the queries a RayTracer
 *  answered, recorded, then replayed through plain Embree calls with nothing
 *  else around them (no materials, energies or histograms), in the modes
 *  Embree offers for such rays. `earshot bench trace` prints the tracer's
 *  time beside the fastest replay of the same rays measured in the same run.
 *  A measuring tool, not an engine path: recording takes a lock per query. */
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

#include "earshot/scene/ray_tracer.h"

namespace earshot {

class ThreadPool;

/** Every intersect() and occluded() call a tracer answered while recording. */
struct QueryLog {
  std::mutex mutex;
  std::vector<Ray> rays;
  std::vector<uint8_t> shadow;  ///< 1: an occluded() query, 0: intersect()
  size_t shadowCount() const;
};

/** Records every query `tracer` answers, from any thread, into `log` for its
 *  lifetime (one recording per tracer at a time). */
class QueryRecording {
 public:
  QueryRecording(const RayTracer& tracer, QueryLog& log);
  ~QueryRecording();
  QueryRecording(const QueryRecording&) = delete;
  QueryRecording& operator=(const QueryRecording&) = delete;

 private:
  const RayTracer& mTracer;
};

enum class EmbreeMode {
  kSingle,   ///< rtcIntersect1 / rtcOccluded1 per ray (what RayTracer does)
  kStream,   ///< rtcIntersect1M / rtcOccluded1M over 256 rays at a time
  kPacket8,  ///< rtcIntersect8 / rtcOccluded8, 8 rays in recorded order
};
const char* embreeModeName(EmbreeMode mode);

/** The log's rays in Embree's frame, split into nearest-hit and shadow
 *  queries, ready to replay (made once, outside any timing). */
class EmbreeReplay {
 public:
  EmbreeReplay(const RayTracer& tracer, const QueryLog& log);
  ~EmbreeReplay();
  EmbreeReplay(const EmbreeReplay&) = delete;
  EmbreeReplay& operator=(const EmbreeReplay&) = delete;
  size_t intersectCount() const;
  size_t shadowCount() const;
  /** Traces every ray once on `pool` (chunks of 256 rays per task); returns
   *  the number of hits plus occluded shadow rays, the same in every mode. */
  size_t run(EmbreeMode mode, ThreadPool& pool) const;

  struct Impl;

 private:
  std::unique_ptr<Impl> mImpl;
};

}  // namespace earshot
