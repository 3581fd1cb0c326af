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
#include "earshot/core/denormals.h"
#include "earshot/core/thread_pool.h"
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

namespace {

// Values (floats, or binary16 halves when compact) a level's spectra take
// for `channels` channels: each partition's split spectrum, padded.
size_t levelValues(const PartitionLevel& lv, size_t channels) {
  return channels * lv.partitionCount * 2 * padBins(lv.partitionFrames + 1);
}

// The spectra's allocation for `values` values, in whole cache lines.
size_t spectraBytes(size_t values, bool compact) {
  const size_t bytes = values * (compact ? sizeof(uint16_t) : sizeof(float));
  return std::max<size_t>(64, (bytes + 63) / 64 * 64);
}

}  // namespace

size_t PreparedIr::bytesFor(const PartitionLayout& layout, size_t channels) {
  size_t total = 0;
  for (const auto& lv : layout.levels()) total += levelValues(lv, channels);
  return spectraBytes(total, layout.compactSpectra());
}

Result<std::shared_ptr<const PreparedIr>> PreparedIr::create(const AudioBuffer& ir, const PartitionLayout& layout,
                                                             ThreadPool* pool) {
  return create(ir.channels, layout, pool);
}

Result<std::shared_ptr<const PreparedIr>> PreparedIr::create(const std::vector<std::vector<float>>& channels,
                                                             const PartitionLayout& layout, ThreadPool* pool) {
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
    out->mStride.push_back(padBins(lv.partitionFrames + 1));
    out->mLevelOffset.push_back(total);
    total += levelValues(lv, channels.size());
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
  const bool compact = layout.compactSpectra();
  if (compact) {
    // Each level's channel under a power of two that puts its largest value
    // at <= 2^14 (binary16 holds up to 65504, and values 2^-24 of that scale
    // still count), rounded to binary16 and laid out by bin tiles
    // (compactTileOffset); no float spectra are kept.
    const size_t halfBytes = spectraBytes(total, true);
    out->mHalf = static_cast<uint16_t*>(std::aligned_alloc(64, halfBytes));
    if (!out->mHalf) return outOfRange("prepared IR: cannot allocate " + std::to_string(halfBytes) + " bytes");
    out->mScale.assign(levels.size() * channels.size(), 1.0f);
  } else {
    const size_t bytes = spectraBytes(total, false);
    out->mData = static_cast<float*>(std::aligned_alloc(64, bytes));
    if (!out->mData) return outOfRange("prepared IR: cannot allocate " + std::to_string(bytes) + " bytes");
  }

  // One task per level and channel: each transforms its own partitions
  // (FFT configurations and scratch per worker, made once), under the
  // caller's denormal mode, so that any number of threads gives the
  // caller's bits.
  const size_t tasks = levels.size() * channels.size();
  const unsigned workers = pool ? pool->threadCount() : 1u;
  struct WorkerState {
    std::vector<kiss_fftr_cfg> cfg;  // per level, made when first needed
    std::vector<float> time, spectra;
    std::vector<kiss_fft_cpx> freq;
    bool failed = false;
    WorkerState() = default;
    WorkerState(const WorkerState&) = delete;
    WorkerState& operator=(const WorkerState&) = delete;
    ~WorkerState() {
      for (kiss_fftr_cfg c : cfg) kiss_fftr_free(c);
    }
  };
  std::vector<WorkerState> state(workers);
  for (auto& w : state) w.cfg.assign(levels.size(), nullptr);
  const uint32_t callerMode = currentDenormalMode();
  PreparedIr& ir = *out;
  auto transform = [&](size_t task, unsigned worker) {
    ScopedDenormalMode mode(callerMode);
    WorkerState& w = state[worker];
    const size_t l = task / channels.size(), c = task % channels.size();
    const auto& lv = levels[l];
    const size_t p = lv.partitionFrames, nfft = 2 * p, st = ir.mStride[l], parts = lv.partitionCount;
    const size_t first = ir.mFirstActive[l], active = ir.mActive[l];
    // This level-channel's spectra: the kept floats, or a worker's scratch
    // for the compact ones; partitions outside [first, active) are zero.
    float* v;
    if (compact) {
      w.spectra.resize(parts * 2 * st);
      v = w.spectra.data();
    } else {
      v = ir.mData + ir.mLevelOffset[l] + c * parts * 2 * st;
      std::memset(v, 0, parts * 2 * st * sizeof(float));
    }
    if (active > first) {
      if (!w.cfg[l]) w.cfg[l] = kiss_fftr_alloc(static_cast<int>(nfft), 0, nullptr, nullptr);
      if (!w.cfg[l]) {
        w.failed = true;
        return;
      }
      const float scale = 1.0f / static_cast<float>(nfft);
      w.time.resize(nfft);
      w.freq.resize(p + 1);
      for (size_t k = first; k < active; ++k) {
        std::fill(w.time.begin(), w.time.end(), 0.0f);
        const size_t start = lv.offsetFrames + k * p;
        const size_t n = std::min(p, frames - start);
        std::memcpy(w.time.data(), channels[c].data() + start, n * sizeof(float));
        kiss_fftr(w.cfg[l], w.time.data(), w.freq.data());
        float* re = v + k * 2 * st;
        float* im = re + st;
        for (size_t b = 0; b <= p; ++b) {
          re[b] = w.freq[b].r * scale;
          im[b] = w.freq[b].i * scale;
        }
        std::fill(re + p + 1, re + st, 0.0f);
        std::fill(im + p + 1, im + st, 0.0f);
      }
    }
    if (!compact) return;
    uint16_t* h = ir.mHalf + ir.mLevelOffset[l] + c * parts * 2 * st;
    std::memset(h, 0, parts * 2 * st * sizeof(uint16_t));
    if (active <= first) return;  // silent: zeros under scale 1
    const float peak = dsp_detail::peakMagnitude(v + first * 2 * st, (active - first) * 2 * st);
    // peak / scale < 2^14; never below the least normal float (a spectrum
    // of denormals made a zero scale, and 0 / 0 a NaN).
    const float scale =
        peak > 0.0f ? std::max(std::ldexp(1.0f, std::ilogb(peak) - 13), std::numeric_limits<float>::min()) : 1.0f;
    ir.mScale[l * channels.size() + c] = scale;
    for (size_t k = first; k < active; ++k)
      for (size_t i = 0; i < st; i += dsp_detail::compactTileWidth(i, st)) {
        const size_t tw = dsp_detail::compactTileWidth(i, st);
        uint16_t* t = h + dsp_detail::compactTileOffset(i, k, parts, st);
        const float* re = v + k * 2 * st + i;
        dsp_detail::floatsToHalves(re, scale, t, tw);
        dsp_detail::floatsToHalves(re + st, scale, t + tw, tw);
      }
  };
  if (pool && tasks > 1)
    pool->parallelFor(tasks, transform);
  else
    for (size_t t = 0; t < tasks; ++t) transform(t, 0);
  for (const auto& w : state)
    if (w.failed) return outOfRange("prepared IR: cannot create an FFT for a partition level");
  return std::shared_ptr<const PreparedIr>(std::move(out));
}

}  // namespace earshot
