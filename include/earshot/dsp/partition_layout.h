#pragma once
/** @file How an impulse response is cut into partitions for the streaming
 *  convolver: a non-uniform layout (Gardner 1995; Garcia 2002) of "levels",
 *  each a run of equal partitions whose size grows by a power of two from
 *  one level to the next, so the first partitions are as short as the latency and the tail is
 *  handled by large, cheap FFTs.
 *
 *  The layout is immutable and depends only on the latency, the longest IR it
 *  must hold and the maximum partition size; every PreparedIr handed to a
 *  Convolver or ConvolutionMixer must be built for an equal layout. */
#include <cstddef>
#include <cstdint>
#include <vector>

#include "earshot/core/status.h"

namespace earshot {

/** Settings of a Convolver or ConvolutionMixer. */
struct ConvolverSettings {
  /** Processing latency N in frames, which is also the first (smallest)
   *  partition size. The output is the exact convolution delayed by exactly N
   *  frames whatever the host block sizes are. Even, in [8, 65536]. Set it to
   *  the host block size when that is fixed (latency = one host block, and the
   *  work is spread evenly over host blocks); powers of two are fastest. */
  size_t latencyFrames = 256;
  /** Longest IR (frames) that the convolver must accept, >= 1. Shorter IRs are
   *  zero-padded and cost less (empty partitions are skipped). */
  size_t maxIrFrames = 48000;
  /** Output (IR) channels, in [1, 64]; 2 for binaural (left, right). */
  size_t channels = 2;
  /** Crossfade length (frames) used when the IR changes, in
   *  [0, 1 << 20]; 0 means one latency block (latencyFrames). */
  size_t fadeFrames = 0;
  /** Largest partition (frames); 0 = automatic: min(8192, 64 *
   *  latencyFrames), so that no single FFT makes a block spike. Larger
   *  partitions are cheaper on average but make rarer, larger spikes. Otherwise a multiple of latencyFrames times a
   *  power of two, >= latencyFrames. */
  size_t maxPartitionFrames = 0;
  /** Stagger of the large-partition schedule, in latency blocks (any value).
   *  Give each of many independent convolvers a different phase (e.g. its
   *  index) so that their large FFTs fall on different blocks. */
  uint32_t phase = 0;
  /** Store the IRs' spectra as 16-bit floats (IEEE binary16), each channel
   *  of each level under its own power-of-two scale: half the memory, and
   *  half the bytes the audio thread streams from memory for IRs beyond the
   *  CPU's cache (what limits many sources' convolution). Each spectrum
   *  value keeps 11 significant bits (relative error <= 2^-11, about -66
   *  dB; the output's error is ~-75 dB of its level, measured in
   *  ConvolutionMixer.CompactSpectraErrorIsSmallAndBounded). Off: float,
   *  the exact convolution to float precision. */
  bool compactSpectra = false;
};

/** One level of a PartitionLayout: partitionCount partitions of
 *  partitionFrames each, covering IR taps [offsetFrames, offsetFrames +
 *  partitionCount * partitionFrames). Its work for one partition-sized input
 *  block is spread over stepsPerBlock latency blocks; it reads the input
 *  delayed by inputDelayFrames so that its results arrive exactly on time. */
struct PartitionLevel {
  size_t partitionFrames = 0;
  size_t partitionCount = 0;
  size_t offsetFrames = 0;
  size_t inputDelayFrames = 0;
  size_t stepsPerBlock = 0;
};

/** An immutable non-uniform partition layout. Cheap to copy. */
class PartitionLayout {
 public:
  PartitionLayout() = default;

  /** Chooses the cheapest layout (by an operation-count model of KissFFT and
   *  the multiply-accumulate) for the settings' latency, maximum IR length,
   *  channel count and maximum partition, per source of a mixer of `sources`
   *  sources (which share the inverse FFTs; 1 for a lone convolver). Fails
   *  with a message naming the field when a setting or `sources` (in
   *  [1, 4096]) is out of range. Any thread; allocates. */
  static Result<PartitionLayout> create(const ConvolverSettings& settings, size_t sources = 1);

  size_t latencyFrames() const { return mLatency; }
  /** IR taps the layout holds (>= maxIrFrames). */
  size_t capacityFrames() const { return mCapacity; }
  const std::vector<PartitionLevel>& levels() const { return mLevels; }
  /** Input history (frames) a source must keep for this layout. */
  size_t historyFrames() const { return mHistory; }
  /** IR spectra stored as 16-bit floats (ConvolverSettings::compactSpectra). */
  bool compactSpectra() const { return mCompact; }

  bool operator==(const PartitionLayout& o) const;
  bool operator!=(const PartitionLayout& o) const { return !(*this == o); }

 private:
  size_t mLatency = 0;
  size_t mCapacity = 0;
  size_t mHistory = 0;
  bool mCompact = false;
  std::vector<PartitionLevel> mLevels;
};

}  // namespace earshot
