// Streaming non-uniformly partitioned overlap-save convolution, many sources
// into one multichannel output.
//
// Method: uniformly partitioned overlap-save with a frequency-domain delay
// line per level (Soo & Pang 1990; Wefers, "Partitioned convolution
// algorithms for real-time auralization", 2015), levels of partition sizes
// growing by powers of two combined as in Gardner 1995 / Garcia 2002 (see partition_layout.cpp).
// Every latency step (N input frames) each level runs 1/M of its block's
// work. The block's tasks (per source: forward FFT of the newest 2P input
// frames, then the multiply-accumulate over its K partitions; then one
// inverse FFT per output channel) are laid out in order over the M steps at
// construction, each step filled to an equal share of the estimated cost
// (scheduleLevel), so no step carries a whole FFT block's work. Outputs are
// double-buffered: block j is computed while block j - 1 is played, and is
// played during the M steps that follow. Products of all sources sharing a
// level are summed before the inverse FFTs.
//
// IR changes: a level adopts a source's newest IR only when it starts a new
// block and is not fading. For the block(s) covering the fade it accumulates
// sum X * H_new into `main` and sum X * (H_old - H_new) of the fading sources
// into `diff`; the output is main + (1 - g) * diff with g a sin^2 ramp, i.e.
// g * y_new + (1 - g) * y_old per fading source (equal gain: g + (1-g) = 1).
// All sources fading in a level share the ramp, which is why a level starts
// fades only between fades.
#include "earshot/dsp/convolution_mixer.h"

#include <kiss_fftr.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "aligned_floats.h"
#include "earshot/core/denormals.h"
#include "mac_kernels.h"

namespace earshot {

using dsp_detail::AlignedFloats;
using dsp_detail::padBins;

namespace {

constexpr size_t kBatch = 64;  // partitions per register-tiled MAC pass

struct Holder {
  std::shared_ptr<const PreparedIr> ir;  // null = silence
  int refs = 0;                          // audio thread only
};

// One unit of a level block's work. A block runs its tasks in order, spread
// over its M steps so that each step costs about the same.
struct Task {
  enum Kind : uint8_t { kForward, kMac, kInverse } kind;
  uint32_t a = 0;  // kForward: source; kMac: first channel; kInverse: channel
  uint32_t k0 = 0, k1 = 0;  // kMac: partition range
  uint32_t a1 = 0;          // kMac: one past the last channel
  uint32_t source = 0;      // kMac
};

struct LevelState {
  PartitionLevel desc;
  size_t p = 0, k = 0, m = 0, stride = 0;
  size_t phaseOffset = 0;
  kiss_fftr_cfg fwd = nullptr, inv = nullptr;
  AlignedFloats accMain, accDiff;  // [channel][2 * stride]
  AlignedFloats out;               // [buffer 0/1][channel][p], double-buffered
  size_t readBuf = 0;              // buffer being played; the other is computed
  bool fading = false;
  size_t fadePos = 0;
  std::vector<char> mainTouched, diffTouched;  // per channel, this block
  std::vector<Task> tasks;                     // the block's work in order
  std::vector<size_t> phaseTask;               // tasks of phase p: [phaseTask[p], phaseTask[p + 1])
};

struct SourceLevel {
  AlignedFloats fdl;  // [slot][2 * stride], slot = block index mod K
  size_t head = 0;    // slot of the newest spectrum
  Holder* cur = nullptr;
  Holder* prev = nullptr;
  bool fading = false;
  // xs[j]: the input spectrum that partition k0 + j multiplies (the level
  // holds k partitions of `stride` bins), for j < count.
  void inputsOf(size_t k0, size_t count, size_t k, size_t stride, const float** xs) const {
    for (size_t j = 0; j < count; ++j) {
      const size_t kk = k0 + j;
      const size_t slot = head >= kk ? head - kk : head + k - kk;
      xs[j] = fdl.data() + slot * 2 * stride;
    }
  }
};

struct Source {
  AlignedFloats history;  // ring of historyFrames, indexed by absolute frame
  std::atomic<Holder*> pending{nullptr};
  Holder* latest = nullptr;
  std::vector<SourceLevel> levels;
};

}  // namespace

struct ConvolutionMixer::Impl {
  ConvolverSettings settings;
  PartitionLayout layout;
  size_t n = 0, channels = 0, fade = 0, histMask = 0;
  std::vector<LevelState> levels;
  // Per-source state is allocated on the control side the first time a
  // source is reserved or given an IR (reserveSource), then published to the
  // audio thread, which adopts it at its next step; a source without state
  // is silent and costs the audio thread nothing.
  size_t historyFrames = 0;
  std::vector<std::unique_ptr<Source>> owned;        // control side (controlMutex)
  std::unique_ptr<std::atomic<Source*>[]> published;  // control -> audio
  std::vector<Source*> sources;                       // audio thread: adopted state (null: none yet)
  AlignedFloats ramp;       // sin^2 fade-in gain, `fade` values
  AlignedFloats outBlock;   // [channel][n]: output for the current N frames
  AlignedFloats timeBuf;    // 2 * maxP
  AlignedFloats fadeCur, fadePrev;  // compact IRs while fading: a partition's spectrum in floats
  std::vector<kiss_fft_cpx> cpxBuf;
  size_t fill = 0;          // frames of the current step already taken
  uint64_t written = 0;     // input frames completed into steps
  uint64_t step = 0;

  // Retired holders (audio -> control), single producer single consumer.
  std::vector<Holder*> retired;
  size_t retiredMask = 0;
  std::atomic<size_t> retiredHead{0}, retiredTail{0};
  size_t heldCount = 0;  // holders with refs > 0 (audio thread)
  mutable std::mutex controlMutex;

  ~Impl() {
    std::set<Holder*> held;
    for (auto& s : owned) {
      if (!s) continue;
      if (s->latest) held.insert(s->latest);
      for (auto& sl : s->levels) {
        if (sl.cur) held.insert(sl.cur);
        if (sl.prev) held.insert(sl.prev);
      }
      delete s->pending.exchange(nullptr);
    }
    for (Holder* h : held) delete h;
    collect();
    for (auto& lv : levels) {
      kiss_fftr_free(lv.fwd);
      kiss_fftr_free(lv.inv);
    }
  }

  // Control side: takes up to `n` retired holders off the queue (the one
  // consumer at a time: controlMutex held, or the destructor).
  size_t popRetired(Holder** out, size_t n) {
    size_t tail = retiredTail.load(std::memory_order_relaxed);
    const size_t head = retiredHead.load(std::memory_order_acquire);
    size_t k = 0;
    while (tail != head && k < n) out[k++] = retired[(tail++) & retiredMask];
    retiredTail.store(tail, std::memory_order_release);
    return k;
  }
  void collect() {
    Holder* batch[64];
    while (size_t k = popRetired(batch, 64))
      for (size_t i = 0; i < k; ++i) delete batch[i];
  }

  // What reserve() allocates for a source: its input history and each
  // level's spectra of past input blocks.
  size_t sourceStateBytes() const {
    size_t values = historyFrames;
    for (const LevelState& lv : levels) values += lv.k * 2 * lv.stride;
    return values * sizeof(float) + sizeof(Source) + levels.size() * sizeof(SourceLevel);
  }

  // Control side, controlMutex held: the source's state, allocated once.
  void reserve(size_t si) {
    if (owned[si]) return;
    auto src = std::make_unique<Source>();
    src->history.resize(historyFrames);
    for (const LevelState& lv : levels) {
      SourceLevel sl;
      sl.fdl.resize(lv.k * 2 * lv.stride);
      sl.head = lv.k - 1;
      src->levels.push_back(std::move(sl));
    }
    published[si].store(src.get(), std::memory_order_release);
    owned[si] = std::move(src);
  }

  // --- audio thread ---
  // Takes up state the control side has published since the last process()
  // call. The new state is all zeros and has no IR: it joins a level block in
  // progress as silence (its IR is adopted at the level's next block start).
  void adoptSources() {
    for (size_t si = 0; si < sources.size(); ++si)
      if (!sources[si]) sources[si] = published[si].load(std::memory_order_acquire);
  }

  void acquire(Holder* h) {
    if (h) ++h->refs;
  }
  void release(Holder* h) {
    if (!h || --h->refs > 0) return;
    size_t head = retiredHead.load(std::memory_order_relaxed);
    retired[head & retiredMask] = h;
    retiredHead.store(head + 1, std::memory_order_release);
    --heldCount;
  }
  size_t retiredFree() const {
    return retired.size() - (retiredHead.load(std::memory_order_relaxed) - retiredTail.load(std::memory_order_acquire));
  }

  void takePending() {
    for (Source* sp : sources) {
      if (!sp) continue;
      Source& s = *sp;
      if (s.pending.load(std::memory_order_relaxed) == nullptr) continue;
      // Every holder we hold may retire; keep room for all of them so that
      // release() never finds the queue full.
      if (retiredFree() < heldCount + 1) return;
      Holder* h = s.pending.exchange(nullptr, std::memory_order_acq_rel);
      if (!h) continue;
      ++heldCount;
      acquire(h);
      release(s.latest);
      s.latest = h;
    }
  }

  void blockStart(LevelState& lv) {
    if (lv.fading) {
      lv.fadePos += lv.p;
      if (lv.fadePos >= fade) {
        lv.fading = false;
        for (Source* sp : sources) {
          if (!sp) continue;
          SourceLevel& sl = sp->levels[&lv - levels.data()];
          if (sl.fading) {
            release(sl.prev);
            sl.prev = nullptr;
            sl.fading = false;
          }
        }
      }
    }
    const size_t li = &lv - levels.data();
    if (!lv.fading) {
      bool any = false;
      for (Source* sp : sources) {
        if (!sp) continue;
        SourceLevel& sl = sp->levels[li];
        if (sl.cur == sp->latest) continue;
        if (sl.cur == nullptr && step < lv.m) {
          // The level's first block: its output so far was silence from an
          // all-zero history, so an IR posted before the first process()
          // call starts exactly, without a fade-in.
          sl.cur = sp->latest;
          acquire(sl.cur);
          continue;
        }
        {
          sl.prev = sl.cur;
          sl.cur = sp->latest;
          acquire(sl.cur);
          sl.fading = true;
          any = true;
        }
      }
      if (any) {
        lv.fading = true;
        lv.fadePos = 0;
      }
    }
    lv.accMain.zero();
    if (lv.fading) lv.accDiff.zero();
    std::fill(lv.mainTouched.begin(), lv.mainTouched.end(), 0);
    std::fill(lv.diffTouched.begin(), lv.diffTouched.end(), 0);
  }

  // Forward FFT of source `si`'s 2P input frames that end where the level's
  // block began (delayed by the level's input delay) into the next
  // delay-line slot. `phase` is the step of the block the task runs in: a
  // forward FFT scheduled after the block's first step must not see the
  // frames that arrived since (with several sources they are spread over
  // the block's steps; reading the newest frames instead shifted every
  // later source's input by phase * N frames in levels after the first).
  void forward(LevelState& lv, size_t si, size_t phase) {
    const size_t li = &lv - levels.data();
    const size_t nfft = 2 * lv.p;
    const int64_t end = static_cast<int64_t>(written) - static_cast<int64_t>(phase * n) -
                        static_cast<int64_t>(lv.desc.inputDelayFrames);
    const int64_t start = end - static_cast<int64_t>(nfft);
    if (!sources[si]) return;
    Source& s = *sources[si];
    SourceLevel& sl = s.levels[li];
    size_t first = static_cast<size_t>(start) & histMask;
    size_t n1 = std::min(nfft, histMask + 1 - first);
    std::memcpy(timeBuf.data(), s.history.data() + first, n1 * sizeof(float));
    if (n1 < nfft) std::memcpy(timeBuf.data() + n1, s.history.data(), (nfft - n1) * sizeof(float));
    kiss_fftr(lv.fwd, timeBuf.data(), cpxBuf.data());
    sl.head = sl.head + 1 == lv.k ? 0 : sl.head + 1;
    float* re = sl.fdl.data() + sl.head * 2 * lv.stride;
    float* im = re + lv.stride;
    for (size_t b = 0; b <= lv.p; ++b) {
      re[b] = cpxBuf[b].r;
      im[b] = cpxBuf[b].i;
    }
  }

  void accumulate(LevelState& lv, size_t si, size_t c0, size_t c1, size_t k0, size_t k1) {
    const size_t li = &lv - levels.data();
    const size_t st = lv.stride;
    if (!sources[si]) return;
    {
      SourceLevel& sl = sources[si]->levels[li];
      const PreparedIr* cur = sl.cur ? sl.cur->ir.get() : nullptr;
      if (sl.fading || !cur) {
        for (size_t c = c0; c < c1; ++c) accumulateFading(lv, sl, c, k0, k1);
        return;
      }
      // Steady state: the partitions of this range in register-tiled
      // passes over the accumulators (both ears at once when binaural).
      const size_t kEnd = std::min(k1, cur->activePartitions(li));
      for (size_t kb = std::max(k0, cur->firstActivePartition(li)); kb < kEnd; kb += kBatch) {
        const size_t cnt = std::min(kBatch, kEnd - kb);
        const float* xs[kBatch];
        sl.inputsOf(kb, cnt, lv.k, st, xs);
        if (cur->compact()) {
          for (size_t c = c0; c < c1; ++c) {
            float* mr = lv.accMain.data() + c * 2 * st;
            dsp_detail::complexMacBatchHalf(mr, mr + st, xs, cur->compactSpectra(li, c), kb, cnt, lv.k, st,
                                            cur->spectrumScale(li, c));
            lv.mainTouched[c] = 1;
          }
          continue;
        }
        const float* hs[kBatch];
        const float* hs1[kBatch];
        size_t c = c0;
        if (c1 - c0 == 2) {
          for (size_t j = 0; j < cnt; ++j) {
            hs[j] = cur->spectrum(li, c0, kb + j);
            hs1[j] = cur->spectrum(li, c0 + 1, kb + j);
          }
          float* a0 = lv.accMain.data() + c0 * 2 * st;
          float* a1 = a0 + 2 * st;
          dsp_detail::complexMacBatch2(a0, a0 + st, a1, a1 + st, xs, hs, hs1, cnt, st, st);
          lv.mainTouched[c0] = lv.mainTouched[c0 + 1] = 1;
          c = c1;
        }
        for (; c < c1; ++c) {
          for (size_t j = 0; j < cnt; ++j) hs[j] = cur->spectrum(li, c, kb + j);
          float* mr = lv.accMain.data() + c * 2 * st;
          dsp_detail::complexMacBatch(mr, mr + st, xs, hs, cnt, st, st);
          lv.mainTouched[c] = 1;
        }
      }
    }
  }

  // Partition k's spectrum in floats: the IR's own, or (compact IRs) its
  // halves converted into `scratch` (2 * stride floats).
  static const float* spectrumOf(const PreparedIr& ir, size_t li, size_t c, size_t k, float* scratch) {
    if (!ir.compact()) return ir.spectrum(li, c, k);
    dsp_detail::compactPartitionToFloats(ir.compactSpectra(li, c), k, ir.layout().levels()[li].partitionCount,
                                         ir.binStride(li), ir.spectrumScale(li, c), scratch);
    return scratch;
  }

  // One source and channel while the level fades (or has no current IR):
  // main += X * H_cur, diff += X * (H_prev - H_cur).
  void accumulateFading(LevelState& lv, SourceLevel& sl, size_t c, size_t k0, size_t k1) {
    const size_t li = &lv - levels.data();
    const size_t st = lv.stride;
    float* mr = lv.accMain.data() + c * 2 * st;
    float* dr = lv.accDiff.data() + c * 2 * st;
    const PreparedIr* cur = sl.cur ? sl.cur->ir.get() : nullptr;
    const PreparedIr* prev = sl.fading && sl.prev ? sl.prev->ir.get() : nullptr;
    const size_t curActive = cur ? cur->activePartitions(li) : 0;
    const size_t prevActive = prev ? prev->activePartitions(li) : 0;
    if ((cur || prev) && (!cur || cur->compact()) && (!prev || prev->compact())) {
      // Compact IRs: in register-tiled passes as the steady state, the
      // difference's halves read directly (converting each partition to
      // floats first made a fading block ~1.7x a steady one: every source
      // of a simulation fades at once).
      const float* xs[kBatch];
      auto passes = [&](size_t from, size_t to, auto&& pass) {
        for (size_t kb = from; kb < to; kb += kBatch) {
          const size_t cnt = std::min(kBatch, to - kb);
          sl.inputsOf(kb, cnt, lv.k, st, xs);
          pass(kb, cnt);
        }
      };
      const size_t curEnd = std::max(k0, std::min(k1, curActive));
      const size_t prevEnd = std::max(k0, std::min(k1, prevActive));
      const uint16_t* hc = cur ? cur->compactSpectra(li, c) : nullptr;
      const uint16_t* hp = prev ? prev->compactSpectra(li, c) : nullptr;
      const float sc = cur ? cur->spectrumScale(li, c) : 0.0f, sp = prev ? prev->spectrumScale(li, c) : 0.0f;
      passes(k0, curEnd, [&](size_t kb, size_t cnt) {
        dsp_detail::complexMacBatchHalf(mr, mr + st, xs, hc, kb, cnt, lv.k, st, sc);
      });
      if (curEnd > k0) lv.mainTouched[c] = 1;
      if (!sl.fading) return;
      // diff += X * (H_prev - H_cur): where both have the partition, the
      // difference; beyond, the one that has it (with its sign).
      const size_t both = std::min(curEnd, prevEnd);
      passes(k0, both, [&](size_t kb, size_t cnt) {
        dsp_detail::complexMacDiffBatchHalf(dr, dr + st, xs, hp, sp, hc, sc, kb, cnt, lv.k, st);
      });
      passes(both, prevEnd, [&](size_t kb, size_t cnt) {
        dsp_detail::complexMacBatchHalf(dr, dr + st, xs, hp, kb, cnt, lv.k, st, sp);
      });
      passes(both, curEnd, [&](size_t kb, size_t cnt) {
        dsp_detail::complexMacBatchHalf(dr, dr + st, xs, hc, kb, cnt, lv.k, st, -sc);
      });
      if (std::max(curEnd, prevEnd) > k0) lv.diffTouched[c] = 1;
      return;
    }
    for (size_t kk = k0; kk < k1; ++kk) {
      const bool hasCur = kk < curActive;
      const bool hasPrev = kk < prevActive;
      if (!hasCur && !hasPrev) continue;
      const size_t slot = sl.head >= kk ? sl.head - kk : sl.head + lv.k - kk;
      const float* xr = sl.fdl.data() + slot * 2 * st;
      const float* hc = hasCur ? spectrumOf(*cur, li, c, kk, fadeCur.data()) : nullptr;
      if (hasCur) {
        dsp_detail::complexMac(mr, mr + st, xr, xr + st, hc, hc + st, st);
        lv.mainTouched[c] = 1;
      }
      if (!sl.fading) continue;
      const float* hp = hasPrev ? spectrumOf(*prev, li, c, kk, fadePrev.data()) : nullptr;
      if (hasPrev && hasCur) {
        dsp_detail::complexMacDiff(dr, dr + st, xr, xr + st, hp, hp + st, hc, hc + st, st);
      } else if (hasPrev) {
        dsp_detail::complexMac(dr, dr + st, xr, xr + st, hp, hp + st, st);
      } else {
        dsp_detail::complexMacNeg(dr, dr + st, xr, xr + st, hc, hc + st, st);
      }
      lv.diffTouched[c] = 1;
    }
  }

  void inverse(const float* acc, size_t p, kiss_fftr_cfg cfg) {
    const size_t st = padBins(p + 1);
    for (size_t b = 0; b <= p; ++b) {
      cpxBuf[b].r = acc[b];
      cpxBuf[b].i = acc[st + b];
    }
    kiss_fftri(cfg, cpxBuf.data(), timeBuf.data());
  }

  // Inverse FFT of channel c's accumulators into the buffer being computed.
  void finishChannel(LevelState& lv, size_t c) {
    const size_t p = lv.p;
    const size_t st = lv.stride;
    float* o = lv.out.data() + ((1 - lv.readBuf) * channels + c) * p;
    if (lv.mainTouched[c]) {
      inverse(lv.accMain.data() + c * 2 * st, p, lv.inv);
      std::memcpy(o, timeBuf.data() + p, p * sizeof(float));
    } else {
      std::memset(o, 0, p * sizeof(float));
    }
    if (lv.fading && lv.diffTouched[c]) {
      inverse(lv.accDiff.data() + c * 2 * st, p, lv.inv);
      const float* d = timeBuf.data() + p;
      const size_t ramped = lv.fadePos < fade ? std::min(p, fade - lv.fadePos) : 0;
      const float* g = ramp.data() + lv.fadePos;
      for (size_t i = 0; i < ramped; ++i) o[i] += (1.0f - g[i]) * d[i];
    }
  }

  void runStep() {
    takePending();
    outBlock.zero();
    for (LevelState& lv : levels) {
      const size_t phase = static_cast<size_t>((step + lv.phaseOffset) % lv.m);
      if (phase == 0) blockStart(lv);
      for (size_t t = lv.phaseTask[phase]; t < lv.phaseTask[phase + 1]; ++t) {
        const Task& task = lv.tasks[t];
        switch (task.kind) {
          case Task::kForward: forward(lv, task.a, phase); break;
          case Task::kMac: accumulate(lv, task.source, task.a, task.a1, task.k0, task.k1); break;
          case Task::kInverse: finishChannel(lv, task.a); break;
        }
      }
      if (phase == lv.m - 1) lv.readBuf = 1 - lv.readBuf;
      const size_t slice = (phase + 1 == lv.m ? 0 : phase + 1) * n;
      for (size_t c = 0; c < channels; ++c) {
        float* dst = outBlock.data() + c * n;
        const float* src = lv.out.data() + (lv.readBuf * channels + c) * lv.p + slice;
        for (size_t i = 0; i < n; ++i) dst[i] += src[i];
      }
    }
    ++step;
  }

  void process(const float* const* inputs, float* const* outputs, size_t frames) {
    ScopedFlushDenormals ftz;
    adoptSources();
    size_t done = 0;
    while (done < frames) {
      const size_t chunk = std::min(frames - done, n - fill);
      const size_t pos = static_cast<size_t>(written + fill) & histMask;
      for (size_t s = 0; s < sources.size(); ++s) {
        if (!sources[s]) continue;  // no state yet: its input is not heard
        float* h = sources[s]->history.data();
        const float* in = inputs ? inputs[s] : nullptr;
        size_t n1 = std::min(chunk, histMask + 1 - pos);
        if (in) {
          std::memcpy(h + pos, in + done, n1 * sizeof(float));
          if (n1 < chunk) std::memcpy(h, in + done + n1, (chunk - n1) * sizeof(float));
        } else {
          std::memset(h + pos, 0, n1 * sizeof(float));
          if (n1 < chunk) std::memset(h, 0, (chunk - n1) * sizeof(float));
        }
      }
      for (size_t c = 0; c < channels; ++c)
        std::memcpy(outputs[c] + done, outBlock.data() + c * n + fill, chunk * sizeof(float));
      fill += chunk;
      done += chunk;
      if (fill == n) {
        written += n;
        fill = 0;
        runStep();
      }
    }
  }
};

namespace {

// Lays a level block's tasks (forward FFT per source, then per channel the
// multiply-accumulate of all partitions and the inverse FFT) out over its M
// steps in order, filling each step up to an equal share of the estimated
// cost; an FFT is indivisible, a multiply-accumulate splits at partitions.
void scheduleLevel(LevelState& lv, size_t sources, size_t channels) {
  const double nfft = 2.0 * static_cast<double>(lv.p);
  const double fft = nfft * std::log2(nfft) * 0.55 + nfft * 0.3;
  const double mac = static_cast<double>(sources) * static_cast<double>(lv.p + 1) * 0.3;
  const double total = fft * static_cast<double>(sources + channels) +
                       mac * static_cast<double>(channels * lv.k);
  const double share = total / static_cast<double>(lv.m);
  lv.tasks.clear();
  lv.phaseTask.assign(lv.m + 1, 0);
  size_t phase = 0;
  double load = 0;
  auto place = [&](double cost) {
    // Move to the next step when this one is full (never past the last).
    while (phase + 1 < lv.m && load > 0 && load + 0.5 * cost > share * 1.0001) {
      ++phase;
      lv.phaseTask[phase] = lv.tasks.size();
      load = 0;
    }
    load += cost;
  };
  // Per source: its forward FFT, then its multiply-accumulates (both ears
  // together when binaural: the kernel reads each input spectrum once for
  // both), so that every step mixes FFTs and MACs and an error in the
  // estimated FFT/MAC cost ratio does not pile one kind onto a few steps.
  const size_t group = channels == 2 ? 2 : 1;
  const double perSourceMac = mac / static_cast<double>(sources);
  for (size_t s = 0; s < sources; ++s) {
    place(fft);
    lv.tasks.push_back({Task::kForward, static_cast<uint32_t>(s), 0, 0, 0, 0});
    for (size_t c = 0; c < channels; c += group) {
      const double cost = perSourceMac * static_cast<double>(group);
      size_t k = 0;
      while (k < lv.k) {
        place(cost);  // as many partitions as fit in this step (at least one)
        size_t k1 = k + 1;
        while (k1 < lv.k && load + cost <= share * 1.0001) {
          load += cost;
          ++k1;
        }
        lv.tasks.push_back({Task::kMac, static_cast<uint32_t>(c), static_cast<uint32_t>(k),
                            static_cast<uint32_t>(k1), static_cast<uint32_t>(c + group), static_cast<uint32_t>(s)});
        k = k1;
      }
    }
  }
  for (size_t c = 0; c < channels; ++c) {
    place(fft);
    lv.tasks.push_back({Task::kInverse, static_cast<uint32_t>(c), 0, 0, 0, 0});
  }
  for (size_t p = phase + 1; p <= lv.m; ++p) lv.phaseTask[p] = lv.tasks.size();
}

}  // namespace

ConvolutionMixer::ConvolutionMixer(std::unique_ptr<Impl> impl) : mImpl(std::move(impl)) {}
ConvolutionMixer::~ConvolutionMixer() = default;

Result<std::unique_ptr<ConvolutionMixer>> ConvolutionMixer::create(const ConvolverSettings& settings,
                                                                   size_t sourceCount) {
  if (sourceCount < 1 || sourceCount > 4096)
    return invalidArgument("convolution mixer: sourceCount=" + std::to_string(sourceCount) + " must be in [1, 4096]");
  auto layout = PartitionLayout::create(settings, sourceCount);
  if (!layout) return layout.status();
  if (settings.fadeFrames > (size_t{1} << 20))
    return invalidArgument("convolver fadeFrames=" + std::to_string(settings.fadeFrames) + " must be <= 2^20");
  try {
    auto impl = std::make_unique<Impl>();
    impl->settings = settings;
    impl->layout = *layout;
    impl->n = settings.latencyFrames;
    impl->channels = settings.channels;
    impl->fade = settings.fadeFrames ? settings.fadeFrames : settings.latencyFrames;
    impl->histMask = layout->historyFrames() - 1;
    impl->ramp.resize(impl->fade);
    for (size_t i = 0; i < impl->fade; ++i) {
      double s = std::sin(0.5 * M_PI * (static_cast<double>(i) + 0.5) / static_cast<double>(impl->fade));
      impl->ramp[i] = static_cast<float>(s * s);
    }
    impl->outBlock.resize(settings.channels * impl->n);
    size_t maxP = 0;
    for (size_t li = 0; li < layout->levels().size(); ++li) {
      const PartitionLevel& d = layout->levels()[li];
      LevelState lv;
      lv.desc = d;
      lv.p = d.partitionFrames;
      lv.k = d.partitionCount;
      lv.m = d.stepsPerBlock;
      lv.stride = padBins(lv.p + 1);
      lv.phaseOffset = static_cast<size_t>(settings.phase) % lv.m;
      lv.fwd = kiss_fftr_alloc(static_cast<int>(2 * lv.p), 0, nullptr, nullptr);
      lv.inv = kiss_fftr_alloc(static_cast<int>(2 * lv.p), 1, nullptr, nullptr);
      if (!lv.fwd || !lv.inv) {
        kiss_fftr_free(lv.fwd);
        kiss_fftr_free(lv.inv);
        return invalidArgument("convolver: cannot create an FFT of size " + std::to_string(2 * lv.p));
      }
      lv.accMain.resize(settings.channels * 2 * lv.stride);
      lv.accDiff.resize(settings.channels * 2 * lv.stride);
      lv.out.resize(2 * settings.channels * lv.p);
      lv.mainTouched.assign(settings.channels, 0);
      lv.diffTouched.assign(settings.channels, 0);
      scheduleLevel(lv, sourceCount, settings.channels);
      maxP = std::max(maxP, lv.p);
      impl->levels.push_back(std::move(lv));
    }
    impl->timeBuf.resize(2 * maxP);
    if (layout->compactSpectra()) {
      impl->fadeCur.resize(2 * padBins(maxP + 1));
      impl->fadePrev.resize(2 * padBins(maxP + 1));
    }
    impl->cpxBuf.resize(maxP + 1);
    impl->historyFrames = layout->historyFrames();
    impl->owned.resize(sourceCount);
    impl->published.reset(new std::atomic<Source*>[sourceCount]);
    for (size_t s = 0; s < sourceCount; ++s) impl->published[s].store(nullptr);
    impl->sources.assign(sourceCount, nullptr);
    size_t cap = 1;
    while (cap < sourceCount * (2 * impl->levels.size() + 2) + 8) cap <<= 1;
    impl->retired.assign(cap, nullptr);
    impl->retiredMask = cap - 1;
    return std::unique_ptr<ConvolutionMixer>(new ConvolutionMixer(std::move(impl)));
  } catch (const std::bad_alloc&) {
    return outOfRange("convolver: out of memory for maxIrFrames=" + std::to_string(settings.maxIrFrames) +
                      " and " + std::to_string(sourceCount) + " sources");
  }
}

const PartitionLayout& ConvolutionMixer::layout() const { return mImpl->layout; }
const ConvolverSettings& ConvolutionMixer::settings() const { return mImpl->settings; }
size_t ConvolutionMixer::sourceCount() const { return mImpl->owned.size(); }
size_t ConvolutionMixer::latencyFrames() const { return mImpl->n; }

Status ConvolutionMixer::setIr(size_t source, std::shared_ptr<const PreparedIr> ir) {
  std::shared_ptr<const PreparedIr> replaced;
  EARSHOT_RETURN_IF_ERROR(postIr(source, std::move(ir), &replaced));
  replaced.reset();
  collectGarbage();
  return Status::ok();
}

Status ConvolutionMixer::postIr(size_t source, std::shared_ptr<const PreparedIr> ir,
                                std::shared_ptr<const PreparedIr>* replaced) {
  if (source >= mImpl->owned.size())
    return invalidArgument("convolver setIr: source " + std::to_string(source) + " out of range (have " +
                           std::to_string(mImpl->owned.size()) + ")");
  if (ir && ir->layout() != mImpl->layout)
    return invalidArgument("convolver setIr: the IR was prepared for a different partition layout");
  if (ir && ir->channelCount() != mImpl->channels)
    return invalidArgument("convolver setIr: IR has " + std::to_string(ir->channelCount()) +
                           " channels, the convolver " + std::to_string(mImpl->channels));
  EARSHOT_RETURN_IF_ERROR(reserveSource(source));
  auto* h = new Holder{std::move(ir), 0};
  Holder* old = mImpl->owned[source]->pending.exchange(h, std::memory_order_acq_rel);
  if (old && replaced) *replaced = std::move(old->ir);
  delete old;  // never seen by the audio thread
  return Status::ok();
}

Status ConvolutionMixer::reserveSource(size_t source) {
  if (source >= mImpl->owned.size())
    return invalidArgument("convolver reserveSource: source " + std::to_string(source) + " out of range (have " +
                           std::to_string(mImpl->owned.size()) + ")");
  std::lock_guard<std::mutex> lock(mImpl->controlMutex);
  try {
    mImpl->reserve(source);
  } catch (const std::bad_alloc&) {
    return outOfRange("convolver: out of memory for source " + std::to_string(source) + "'s state");
  }
  return Status::ok();
}

size_t ConvolutionMixer::sourceStateBytes() const { return mImpl->sourceStateBytes(); }

size_t ConvolutionMixer::reservedSources() const {
  std::lock_guard<std::mutex> lock(mImpl->controlMutex);
  size_t n = 0;
  for (const auto& s : mImpl->owned) n += s != nullptr;
  return n;
}

void ConvolutionMixer::collectGarbage() {
  // Taken off the queue under the lock, freed outside it: another control
  // thread (setIr, reserveSource) never waits for the frees.
  Holder* batch[64];
  for (;;) {
    size_t k;
    {
      std::lock_guard<std::mutex> lock(mImpl->controlMutex);
      k = mImpl->popRetired(batch, 64);
    }
    for (size_t i = 0; i < k; ++i) delete batch[i];
    if (k < 64) return;
  }
}

void ConvolutionMixer::process(const float* const* inputs, float* const* outputs, size_t frames) {
  mImpl->process(inputs, outputs, frames);
}

void ConvolutionMixer::clearState() {
  auto zero = [](AlignedFloats& a) { std::fill(a.data(), a.data() + a.size(), 0.0f); };
  Impl& m = *mImpl;
  zero(m.outBlock);
  zero(m.timeBuf);
  for (auto& lv : m.levels) {
    zero(lv.accMain);
    zero(lv.accDiff);
    zero(lv.out);
  }
  for (Source* s : m.sources) {
    if (!s) continue;
    zero(s->history);
    for (auto& sl : s->levels) zero(sl.fdl);
  }
}

bool ConvolutionMixer::holdsIr(size_t source) const {
  const Impl& m = *mImpl;
  if (source >= m.sources.size() || !m.sources[source]) return false;
  const Source& s = *m.sources[source];
  auto has = [](const Holder* h) { return h && h->ir; };
  if (has(s.latest)) return true;
  for (const SourceLevel& sl : s.levels)
    if (has(sl.cur) || (sl.fading && has(sl.prev))) return true;
  return false;
}

void ConvolutionMixer::resetSource(size_t source) {
  Impl& m = *mImpl;
  if (source >= m.sources.size() || !m.sources[source]) return;
  Source& s = *m.sources[source];
  // Released to the control side's queue, which always has room for every
  // holder the audio thread holds (takePending).
  m.release(s.latest);
  s.latest = nullptr;
  for (SourceLevel& sl : s.levels) {
    m.release(sl.cur);
    if (sl.prev) m.release(sl.prev);
    sl.cur = sl.prev = nullptr;
    sl.fading = false;
    std::fill(sl.fdl.data(), sl.fdl.data() + sl.fdl.size(), 0.0f);
  }
  std::fill(s.history.data(), s.history.data() + s.history.size(), 0.0f);
}

size_t ConvolutionMixer::countSubnormalsInState() const {
  size_t count = 0;
  auto scan = [&](const AlignedFloats& a) {
    for (size_t i = 0; i < a.size(); ++i)
      if (std::fpclassify(a[i]) == FP_SUBNORMAL) ++count;
  };
  const Impl& m = *mImpl;
  scan(m.outBlock);
  for (const auto& lv : m.levels) {
    scan(lv.accMain);
    scan(lv.accDiff);
    scan(lv.out);
  }
  for (const Source* s : m.sources) {
    if (!s) continue;
    scan(s->history);
    for (const auto& sl : s->levels) scan(sl.fdl);
  }
  return count;
}

}  // namespace earshot
