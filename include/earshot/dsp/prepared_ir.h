#pragma once
/** @file An impulse response cut into partitions and transformed to the
 *  frequency domain for one PartitionLayout: what the audio thread convolves
 *  with. Built off the audio thread (it allocates and runs FFTs), immutable
 *  afterwards, shared with std::shared_ptr<const PreparedIr>. */
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "earshot/core/audio_buffer.h"
#include "earshot/core/status.h"
#include "earshot/dsp/partition_layout.h"

namespace earshot {

class ThreadPool;

class PreparedIr {
 public:
  /** Partitions and transforms `channels` (channels[c][tap], all of equal
   *  length in [0, layout.capacityFrames()], finite samples) for `layout`.
   *  An empty IR (0 taps) is allowed and convolves to silence.
   *  Thread: any thread except the audio thread (allocates, runs FFTs).
   *  With a `pool`, its threads and the caller's share the levels and
   *  channels (the pool must be idle: parallelFor is not reentrant); the
   *  result is the same bits as without one (the caller's denormal mode is
   *  used throughout).
   *  Fails with a message naming the channel/tap on bad input. */
  static Result<std::shared_ptr<const PreparedIr>> create(const std::vector<std::vector<float>>& channels,
                                                          const PartitionLayout& layout, ThreadPool* pool = nullptr);
  /** Same, from an AudioBuffer (its sample rate is not checked here). */
  static Result<std::shared_ptr<const PreparedIr>> create(const AudioBuffer& ir, const PartitionLayout& layout,
                                                          ThreadPool* pool = nullptr);

  /** The spectra's bytes of an IR of `channels` channels for `layout`
   *  (whatever its length: every partition of the layout is stored), what
   *  create() allocates beside a few per-level numbers. */
  static size_t bytesFor(const PartitionLayout& layout, size_t channels);

  const PartitionLayout& layout() const { return mLayout; }
  size_t channelCount() const { return mChannels; }
  /** Length of the IR it was built from (frames). */
  size_t irFrames() const { return mIrFrames; }

  /** NOTE: spectra are stored split (all real parts, then all imaginary
   *  parts) per partition, padded to binStride() floats, already scaled by
   *  1/FFT size. Internal to the convolver; read-only. */
  size_t binStride(size_t level) const { return mStride[level]; }
  /** Number of non-empty partitions of `level` (trailing empty ones skipped). */
  size_t activePartitions(size_t level) const { return mActive[level]; }
  /** First partition of `level` with a non-zero tap in any channel (the
   *  ones before it are silent: a reflection IR starts with the sound's
   *  travel time); activePartitions(level) when all are silent. */
  size_t firstActivePartition(size_t level) const { return mFirstActive[level]; }
  /** Real parts of partition `k` of `level`, channel `channel`; the imaginary
   *  parts follow at + binStride(level). Null when compact(). */
  const float* spectrum(size_t level, size_t channel, size_t k) const;
  /** The layout's compactSpectra(): spectra as binary16 halves, read with
   *  compactSpectra() and multiplied by spectrumScale(). */
  bool compact() const { return mHalf != nullptr; }
  /** When compact(): the binary16 spectra of `level`'s partitions for
   *  `channel`, interleaved by bin tiles (dsp_detail::compactTileOffset, in
   *  src/dsp/mac_kernels.h: the multiply-accumulate reads them as one
   *  stream). Null otherwise. */
  const uint16_t* compactSpectra(size_t level, size_t channel) const;
  /** The power of two that halfSpectrum(level, channel, .) values are
   *  multiplied by (the channel's largest value is stored at <= 2^14). */
  float spectrumScale(size_t level, size_t channel) const { return mScale[level * mChannels + channel]; }

  ~PreparedIr();
  PreparedIr(const PreparedIr&) = delete;
  PreparedIr& operator=(const PreparedIr&) = delete;

 private:
  PreparedIr() = default;
  PartitionLayout mLayout;
  size_t mChannels = 0;
  size_t mIrFrames = 0;
  std::vector<size_t> mStride, mActive, mFirstActive, mLevelOffset;  // per level
  float* mData = nullptr;                              // owned, 64-byte aligned (float spectra)
  uint16_t* mHalf = nullptr;                           // owned, 64-byte aligned (compact spectra)
  std::vector<float> mScale;                           // compact: per level and channel
};

}  // namespace earshot
