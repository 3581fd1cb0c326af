// Partitions an IR for a PartitionLayout and stores each partition's
// spectrum (real FFT of the partition zero-padded to 2P, scaled by 1/(2P) so
// the convolver's inverse FFT needs no scaling) in split real/imaginary form.
#include "earshot/dsp/prepared_ir.h"

#include <kiss_fftr.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>

#include "aligned_floats.h"
#include "mac_kernels.h"

namespace earshot {

using dsp_detail::padBins;

PreparedIr::~PreparedIr() {
  std::free(mData);
  std::free(mHalf);
}

const float* PreparedIr::spectrum(size_t level, size_t channel, size_t k) const {
  if (!mData) return nullptr;
  const PartitionLevel& lv = mLayout.levels()[level];
  size_t stride = mStride[level];
  return mData + mLevelOffset[level] + (channel * lv.partitionCount + k) * 2 * stride;
}

const uint16_t* PreparedIr::compactSpectra(size_t level, size_t channel) const {
  if (!mHalf) return nullptr;
  const PartitionLevel& lv = mLayout.levels()[level];
  return mHalf + mLevelOffset[level] + channel * lv.partitionCount * 2 * mStride[level];
}

Result<std::shared_ptr<const PreparedIr>> PreparedIr::create(const AudioBuffer& ir, const PartitionLayout& layout) {
  return create(ir.channels, layout);
}

Result<std::shared_ptr<const PreparedIr>> PreparedIr::create(const std::vector<std::vector<float>>& channels,
                                                             const PartitionLayout& layout) {
  if (layout.levels().empty()) return invalidArgument("prepared IR: layout is empty (not created)");
  if (channels.empty() || channels.size() > 64)
    return invalidArgument("prepared IR: channel count " + std::to_string(channels.size()) + " must be in [1, 64]");
  const size_t frames = channels[0].size();
  for (size_t c = 0; c < channels.size(); ++c) {
    if (channels[c].size() != frames)
      return invalidArgument("prepared IR: channel " + std::to_string(c) + " has " +
                             std::to_string(channels[c].size()) + " frames, channel 0 has " + std::to_string(frames));
    for (size_t t = 0; t < frames; ++t)
      if (!std::isfinite(channels[c][t]))
        return invalidArgument("prepared IR: channel " + std::to_string(c) + " tap " + std::to_string(t) +
                               " is not finite");
  }
  if (frames > layout.capacityFrames())
    return outOfRange("prepared IR: " + std::to_string(frames) + " frames exceed the layout capacity " +
                      std::to_string(layout.capacityFrames()));

  std::shared_ptr<PreparedIr> out(new PreparedIr());
  out->mLayout = layout;
  out->mChannels = channels.size();
  out->mIrFrames = frames;
  const auto& levels = layout.levels();
  size_t total = 0;
  for (const auto& lv : levels) {
    size_t stride = padBins(lv.partitionFrames + 1);
    out->mStride.push_back(stride);
    out->mLevelOffset.push_back(total);
    total += channels.size() * lv.partitionCount * 2 * stride;
    // Active partitions: those holding at least one tap of the IR.
    size_t active = 0;
    if (frames > lv.offsetFrames)
      active = std::min(lv.partitionCount, (frames - lv.offsetFrames + lv.partitionFrames - 1) / lv.partitionFrames);
    out->mActive.push_back(active);
    // Leading silent partitions (all channels zero over the partition).
    size_t first = 0;
    for (; first < active; ++first) {
      const size_t start = lv.offsetFrames + first * lv.partitionFrames;
      const size_t end = std::min(frames, start + lv.partitionFrames);
      bool silent = true;
      for (size_t c = 0; c < channels.size() && silent; ++c)
        for (size_t t = start; t < end; ++t)
          if (channels[c][t] != 0.0f) {
            silent = false;
            break;
          }
      if (!silent) break;
    }
    out->mFirstActive.push_back(first);
  }
  size_t bytes = ((total * sizeof(float) + 63) / 64) * 64;
  out->mData = static_cast<float*>(std::aligned_alloc(64, bytes ? bytes : 64));
  if (!out->mData) return outOfRange("prepared IR: cannot allocate " + std::to_string(bytes) + " bytes");
  std::memset(out->mData, 0, bytes ? bytes : 64);

  for (size_t l = 0; l < levels.size(); ++l) {
    const auto& lv = levels[l];
    const size_t p = lv.partitionFrames;
    const size_t nfft = 2 * p;
    const float scale = 1.0f / static_cast<float>(nfft);
    kiss_fftr_cfg cfg = kiss_fftr_alloc(static_cast<int>(nfft), 0, nullptr, nullptr);
    if (!cfg) return outOfRange("prepared IR: cannot create an FFT of size " + std::to_string(nfft));
    std::vector<float> time(nfft, 0.0f);
    std::vector<kiss_fft_cpx> freq(p + 1);
    for (size_t c = 0; c < channels.size(); ++c) {
      for (size_t k = out->mFirstActive[l]; k < out->mActive[l]; ++k) {
        std::fill(time.begin(), time.end(), 0.0f);
        size_t start = lv.offsetFrames + k * p;
        size_t n = std::min(p, frames - start);
        std::memcpy(time.data(), channels[c].data() + start, n * sizeof(float));
        kiss_fftr(cfg, time.data(), freq.data());
        float* re = const_cast<float*>(out->spectrum(l, c, k));
        float* im = re + out->mStride[l];
        for (size_t b = 0; b <= p; ++b) {
          re[b] = freq[b].r * scale;
          im[b] = freq[b].i * scale;
        }
      }
    }
    kiss_fftr_free(cfg);
  }
  if (layout.compactSpectra()) {
    // Each level's channel under a power of two that puts its largest value
    // at <= 2^14 (binary16 holds up to 65504, and values 2^-24 of that scale
    // still count), rounded to binary16 and laid out by bin tiles
    // (compactTileOffset); the floats are dropped.
    const size_t halfBytes = ((total * sizeof(uint16_t) + 63) / 64) * 64;
    out->mHalf = static_cast<uint16_t*>(std::aligned_alloc(64, halfBytes ? halfBytes : 64));
    if (!out->mHalf) return outOfRange("prepared IR: cannot allocate " + std::to_string(halfBytes) + " bytes");
    std::memset(out->mHalf, 0, halfBytes ? halfBytes : 64);
    out->mScale.assign(levels.size() * channels.size(), 1.0f);
    for (size_t l = 0; l < levels.size(); ++l)
      for (size_t c = 0; c < channels.size(); ++c) {
        const size_t n = levels[l].partitionCount * 2 * out->mStride[l];
        const float* v = out->spectrum(l, c, 0);
        const float peak = dsp_detail::peakMagnitude(v, n);
        // peak / scale < 2^14; never below the least normal float (a
        // spectrum of denormals made a zero scale, and 0 / 0 a NaN).
        const float scale = peak > 0.0f ? std::max(std::ldexp(1.0f, std::ilogb(peak) - 13),
                                                   std::numeric_limits<float>::min())
                                        : 1.0f;
        out->mScale[l * channels.size() + c] = scale;
        uint16_t* h = const_cast<uint16_t*>(out->compactSpectra(l, c));
        const size_t parts = levels[l].partitionCount, st = out->mStride[l];
        for (size_t k = 0; k < parts; ++k)
          for (size_t i = 0; i < st; i += dsp_detail::compactTileWidth(i, st)) {
            const size_t w = dsp_detail::compactTileWidth(i, st);
            uint16_t* t = h + dsp_detail::compactTileOffset(i, k, parts, st);
            const float* re = v + k * 2 * st + i;
            dsp_detail::floatsToHalves(re, scale, t, w);
            dsp_detail::floatsToHalves(re + st, scale, t + w, w);
          }
      }
    std::free(out->mData);
    out->mData = nullptr;
  }
  return std::shared_ptr<const PreparedIr>(std::move(out));
}

}  // namespace earshot
