#pragma once
/** @file Many mono sources, each convolved with its own multichannel IR, summed
 *  into one multichannel output: the frequency-domain products of all sources
 *  are accumulated per partition level before one inverse FFT per output
 *  channel and level, so adding a source costs its forward FFTs and
 *  multiply-accumulates but no inverse FFT. A Convolver is a mixer of one
 *  source.
 *
 *  Threading: one audio thread calls process(); any other threads (the
 *  "control side") call setIr() and collectGarbage(). process() never
 *  allocates, locks, or makes a system call, and it flushes denormals for its
 *  duration. IRs reach the audio thread through a lock-free mailbox (one
 *  atomic pointer exchange per source); IRs the audio thread no longer uses go
 *  back through a lock-free queue and are released by the next setIr() or
 *  collectGarbage() call, never on the audio thread. */
#include <cstddef>
#include <memory>

#include "earshot/core/status.h"
#include "earshot/dsp/partition_layout.h"
#include "earshot/dsp/prepared_ir.h"

namespace earshot {

class ConvolutionMixer {
 public:
  /** Builds a mixer of `sourceCount` sources (in [1, 4096]) with the layout
   *  PartitionLayout::create(settings, sourceCount). Every source starts with no IR
   *  (silence) and no state: a source's input history and spectra (about
   *  4 x maxIrFrames floats) are allocated by reserveSource() or its first
   *  setIr(), so that creating a mixer of many slots costs only the shared
   *  buffers. Thread: any but the audio thread. */
  static Result<std::unique_ptr<ConvolutionMixer>> create(const ConvolverSettings& settings, size_t sourceCount);
  ~ConvolutionMixer();

  /** Layout that every IR given to setIr() must be prepared for. */
  const PartitionLayout& layout() const;
  const ConvolverSettings& settings() const;
  size_t sourceCount() const;
  /** Output delay in frames: output frame t is the exact convolution at
   *  t - latencyFrames(). Equal to settings().latencyFrames. */
  size_t latencyFrames() const;

  /** Replaces the IR of `source` (nullptr = silence). The audio thread picks
   *  it up at its next latency block and crossfades each partition level from
   *  the previous IR over settings().fadeFrames (equal-gain sin^2 ramp), level
   *  by level as each level starts a new block; while a level is fading it
   *  keeps the newest IR waiting. Posting faster than the audio thread
   *  consumes simply replaces the waiting IR. Fails (and changes nothing) when
   *  the IR's layout or channel count differ. Thread: control side (any
   *  thread but the audio thread; may allocate and free). */
  Status setIr(size_t source, std::shared_ptr<const PreparedIr> ir);
  /** setIr() without freeing anything, for a caller that posts under a
   *  lock of its own and frees outside it: the IR this one replaced (posted
   *  before and never taken up by the audio thread; null if none) is moved
   *  into *replaced (may be null: then it is freed here), and the IRs the
   *  audio thread retired wait for the next collectGarbage() or setIr(). */
  Status postIr(size_t source, std::shared_ptr<const PreparedIr> ir, std::shared_ptr<const PreparedIr>* replaced);

  /** Allocates `source`'s state if it has none yet (a no-op after the first
   *  call); the audio thread takes it up at its next latency block. Until
   *  then the source's input is not heard (it has no IR either). Call it
   *  before feeding a source input that must reach its first IR's output.
   *  Thread: control side. Error: out of range, or out of memory. */
  Status reserveSource(size_t source);
  /** The bytes reserveSource() allocates for one source (its IRs apart:
   *  PreparedIr::bytesFor each). */
  size_t sourceStateBytes() const;
  /** Sources whose state has been allocated. Thread: control side. */
  size_t reservedSources() const;
  /** Releases IRs the audio thread has finished with. Thread: control side.
   *  Call it now and then if setIr() is called rarely; otherwise optional. */
  void collectGarbage();

  /** Convolves `frames` frames (any count, may change every call, 0 allowed).
   *  inputs[s] is source s's mono input (nullptr = silence for this call);
   *  outputs[c] receives output channel c (settings().channels of them,
   *  overwritten, not added). An output may be the same buffer as an input
   *  (in place): every input frame is read before that frame is written.
   *  Thread: the audio thread only. Real-time safe. */
  void process(const float* const* inputs, float* const* outputs, size_t frames);

  /** Whether `source`'s convolution uses an IR now or is to use one at its
   *  levels' next blocks (the latest IR the audio thread took, or a level's
   *  current or fading one): false for a source with no state or whose IR
   *  is silence (nullptr) and has faded in everywhere. An IR posted but
   *  not yet taken up does not count. Thread: the audio thread only.
   *  Real-time safe. */
  bool holdsIr(size_t source) const;

  /** Starts `source` anew: its IRs are dropped at once (no fade; an IR
   *  posted but not yet taken up stays posted) and its input history and
   *  spectra zeroed, as a source that was never fed. What its convolution
   *  would still have played stops at once, so call it when that is
   *  silence (every input within its IR's length was silent) or when its
   *  IR has faded out (holdsIr() false). For a source whose slot is taken
   *  by another. Thread: the audio thread only. Real-time safe (no
   *  allocation or lock; time in proportion to the source's state). */
  void resetSource(size_t source);

  /** Zeroes every source's input history and spectra and every pending
   *  output (the IRs stay): the mixer continues as if all inputs had been
   *  silent. For the engine's containment of a state that became non-finite.
   *  Thread: the audio thread only. Real-time safe (no allocation or lock;
   *  time in proportion to the state, ~ sources x longest IR). */
  void clearState();

  /** Diagnostic for tests: counts subnormal floats in the internal state
   *  (input history, spectra, accumulators, output buffers). Thread: the
   *  audio thread or while no one calls process(). Not real-time safe in
   *  time (scans everything). */
  size_t countSubnormalsInState() const;

  ConvolutionMixer(const ConvolutionMixer&) = delete;
  ConvolutionMixer& operator=(const ConvolutionMixer&) = delete;

  struct Impl;

 private:
  explicit ConvolutionMixer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> mImpl;
};

}  // namespace earshot
