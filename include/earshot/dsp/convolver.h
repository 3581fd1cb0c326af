#pragma once
/** @file Streaming partitioned FFT convolution of one mono input with a
 *  multichannel IR (binaural: one input FFT serves both ears), non-uniformly
 *  partitioned (Gardner 1995; Garcia 2002), with click-free, lock-free IR
 *  replacement. A thin wrapper over a ConvolutionMixer of one source; see
 *  convolution_mixer.h for the threading contract.
 *
 *  Typical use:
 *  @code
 *    ConvolverSettings s; s.latencyFrames = 256; s.maxIrFrames = 96000; s.channels = 2;
 *    auto conv = Convolver::create(s);                          // control thread
 *    auto ir = PreparedIr::create(irChannels, (*conv)->layout()); // worker thread
 *    (*conv)->setIr(*ir);                                        // control thread
 *    (*conv)->process(in, outs, frames);                         // audio thread
 *  @endcode */
#include <cstddef>
#include <memory>

#include "earshot/dsp/convolution_mixer.h"

namespace earshot {

class Convolver {
 public:
  /** Thread: any but the audio thread (allocates). */
  static Result<std::unique_ptr<Convolver>> create(const ConvolverSettings& settings);

  const PartitionLayout& layout() const { return mMixer->layout(); }
  const ConvolverSettings& settings() const { return mMixer->settings(); }
  /** Output frame t is the convolution at t - latencyFrames() exactly. */
  size_t latencyFrames() const { return mMixer->latencyFrames(); }

  /** See ConvolutionMixer::setIr. Thread: control side. */
  Status setIr(std::shared_ptr<const PreparedIr> ir) { return mMixer->setIr(0, std::move(ir)); }
  /** See ConvolutionMixer::collectGarbage. Thread: control side. */
  void collectGarbage() { mMixer->collectGarbage(); }

  /** Convolves `frames` frames of `in` (nullptr = silence) into
   *  out[0..channels) (overwritten; out[0] may be `in`, in place). Any frame
   *  count, changing between calls.
   *  Thread: audio thread only. Real-time safe. */
  void process(const float* in, float* const* out, size_t frames) { mMixer->process(&in, out, frames); }

  /** See ConvolutionMixer::countSubnormalsInState. */
  size_t countSubnormalsInState() const { return mMixer->countSubnormalsInState(); }

 private:
  explicit Convolver(std::unique_ptr<ConvolutionMixer> m) : mMixer(std::move(m)) {}
  std::unique_ptr<ConvolutionMixer> mMixer;
};

}  // namespace earshot
