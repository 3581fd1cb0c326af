// Non-uniform partition layout for streaming FFT convolution.
//
// Method: W. G. Gardner, "Efficient convolution without input-output delay",
// JAES 43(3), 1995, and G. Garcia, "Optimal filter partition for efficient
// convolution with short input/output delay", AES 113th Convention, 2002.
// Level l has partitions of P_l = N * 2^e_l frames (e_0 = 0, increasing).
// A level processes the input in P_l-frame blocks with overlap-save FFTs of
// size 2 P_l; a block's forward FFT, multiply-accumulate and inverse FFTs are
// spread over M_l = P_l / N latency steps, so the level's first tap must be
// at least 2 P_l - 2 N (the "offset" constraint). Any level that starts later
// than that reads the input delayed by the difference (inputDelayFrames),
// which keeps every block's results arriving exactly at their deadline.
// Given the set of sizes, each level gets the fewest partitions that satisfy
// the next level's constraint (covering taps with larger partitions is
// always cheaper) and the last covers the rest; we search all sets of sizes
// up to the largest partition and keep the cheapest by an operation count:
// per output frame and source a level costs 1 + C / S FFTs of size 2P
// (alpha * 2P log2(2P) / P, plus copies: each source's forward FFT, and the
// C inverse FFTs that a mixer's S sources share because their products are
// summed before them) and C * K complex multiply-accumulates (beta each), C
// being the channel count. Counting the inverse FFTs once per source (as
// this model did at first) chose one uniform level for 32 sources' short
// ambisonic IRs, 3.4x slower than the layout chosen now
// (`earshot bench convolve --ir-seconds 0.16 --channels 4 --sources 32`).
#include "earshot/dsp/partition_layout.h"

#include <cmath>
#include <limits>
#include <string>

namespace earshot {
namespace {

constexpr size_t kMinLatency = 8;
constexpr size_t kMaxLatency = 65536;
// Default cap on partition size (frames): the largest FFT (2x this) stays
// well under 2 % of a 256-frame block period at 48 kHz with KissFFT.
constexpr size_t kAutoMaxPartition = 8192;
// ... and at most 64 latency blocks, so that one FFT is at most a few times
// the cost of an average block at small latencies (measured at N = 64).
constexpr size_t kAutoMaxSteps = 64;
// Cost model constants (relative): KissFFT real FFT cost per n*log2(n), and
// one vectorised complex multiply-accumulate.
// Measured on x86-64 (Debian KissFFT, AVX2 kernel): ~0.55 ns per n log2 n
// for a real FFT, ~0.3 ns per complex multiply-accumulate (from L2), and
// ~0.3 ns per frame for the copies around each FFT.
constexpr double kFftCost = 0.55;
constexpr double kMacCost = 0.3;
constexpr double kCopyCost = 0.3;

bool isPow2(size_t v) { return v && !(v & (v - 1)); }

size_t nextPow2(size_t v) {
  size_t p = 1;
  while (p < v) p <<= 1;
  return p;
}

double cost(const std::vector<PartitionLevel>& levels, size_t channels, size_t sources) {
  double c = 0;
  const double ffts = 1.0 + double(channels) / double(sources);
  for (const auto& lv : levels) {
    double nfft = 2.0 * lv.partitionFrames;
    c += ffts * (kFftCost * nfft * std::log2(nfft) + kCopyCost * nfft) / lv.partitionFrames;
    c += channels * kMacCost * lv.partitionCount;
  }
  return c;
}

// Levels for the partition sizes n * 2^e for e in `exps` (increasing, first
// 0): each level but the last gets the fewest partitions that let the next
// level start late enough (offset >= 2P' - 2n); the last covers the rest.
std::vector<PartitionLevel> levelsFor(size_t n, size_t maxIr, const std::vector<int>& exps) {
  std::vector<PartitionLevel> levels;
  size_t offset = 0;
  for (size_t i = 0; i < exps.size() && offset < maxIr; ++i) {
    PartitionLevel lv;
    lv.partitionFrames = n << exps[i];
    lv.offsetFrames = offset;
    lv.stepsPerBlock = size_t{1} << exps[i];
    lv.inputDelayFrames = i == 0 ? 0 : offset - (2 * lv.partitionFrames - 2 * n);
    size_t target = maxIr;
    if (i + 1 < exps.size()) target = std::min(maxIr, 2 * (n << exps[i + 1]) - 2 * n);
    size_t need = target > offset ? target - offset : 0;
    lv.partitionCount = std::max<size_t>(1, (need + lv.partitionFrames - 1) / lv.partitionFrames);
    offset += lv.partitionCount * lv.partitionFrames;
    levels.push_back(lv);
  }
  return levels;
}

Status checkCommon(size_t latency, size_t maxIr, size_t maxPart) {
  if (latency < kMinLatency || latency > kMaxLatency || latency % 2 != 0)
    return invalidArgument("convolver latencyFrames=" + std::to_string(latency) + " must be even and in [8, 65536]");
  // KissFFT allocates inside the transform for prime factors above 5, which
  // the audio thread must not do: accept only 2^a 3^b 5^c sizes.
  size_t rest = latency;
  for (size_t f : {2, 3, 5})
    while (rest % f == 0) rest /= f;
  if (rest != 1)
    return invalidArgument("convolver latencyFrames=" + std::to_string(latency) +
                           " must have no prime factor above 5 (e.g. 64, 480, 1000)");
  if (maxIr < 1 || maxIr > (size_t{1} << 28))
    return invalidArgument("convolver maxIrFrames=" + std::to_string(maxIr) + " must be in [1, 2^28]");
  if (maxPart != 0 && (maxPart < latency || maxPart % latency != 0 || !isPow2(maxPart / latency)))
    return invalidArgument("convolver maxPartitionFrames=" + std::to_string(maxPart) +
                           " must be latencyFrames times a power of two");
  return Status::ok();
}

size_t effectiveMaxPart(size_t latency, size_t maxPart) {
  if (maxPart != 0) return maxPart;
  size_t p = latency;
  while (p * 2 <= kAutoMaxPartition && p * 2 <= kAutoMaxSteps * latency) p *= 2;
  return p;
}

}  // namespace

Result<PartitionLayout> PartitionLayout::create(const ConvolverSettings& s, size_t sources) {
  EARSHOT_RETURN_IF_ERROR(checkCommon(s.latencyFrames, s.maxIrFrames, s.maxPartitionFrames));
  if (s.channels < 1 || s.channels > 64)
    return invalidArgument("convolver channels=" + std::to_string(s.channels) + " must be in [1, 64]");
  if (sources < 1 || sources > 4096)
    return invalidArgument("convolver sources=" + std::to_string(sources) + " must be in [1, 4096]");
  const size_t maxPart = effectiveMaxPart(s.latencyFrames, s.maxPartitionFrames);
  int maxExp = 0;
  while (maxExp < 13 && (s.latencyFrames << (maxExp + 1)) <= maxPart) ++maxExp;
  // Exhaustive search over the sets of partition sizes n * 2^e, e in
  // [1, maxExp] (at most 2^maxExp candidates; maxExp <= 13).
  std::vector<PartitionLevel> best;
  double bestCost = std::numeric_limits<double>::infinity();
  for (uint32_t mask = 0; mask < (1u << maxExp); ++mask) {
    std::vector<int> exps = {0};
    for (int e = 1; e <= maxExp; ++e)
      if (mask & (1u << (e - 1))) exps.push_back(e);
    auto levels = levelsFor(s.latencyFrames, s.maxIrFrames, exps);
    if (levels.size() != exps.size()) continue;  // a larger level would be unused
    double c = cost(levels, s.channels, sources);
    if (c < bestCost - 1e-9) {
      bestCost = c;
      best = levels;
    }
  }
  PartitionLayout out;
  out.mLatency = s.latencyFrames;
  out.mLevels = best;
  out.mCompact = s.compactSpectra;
  out.mCapacity = 0;
  out.mHistory = 0;
  for (const auto& lv : best) {
    out.mCapacity = lv.offsetFrames + lv.partitionCount * lv.partitionFrames;
    // A block's forward FFTs may run in its last step, (M - 1) N = P - N
    // frames after the block's end, and read 2P frames (plus the delay)
    // before that end, while the step being filled adds up to N more.
    out.mHistory = std::max(out.mHistory, 3 * lv.partitionFrames + lv.inputDelayFrames + s.latencyFrames);
  }
  out.mHistory = nextPow2(out.mHistory);
  return out;
}

bool PartitionLayout::operator==(const PartitionLayout& o) const {
  if (mLatency != o.mLatency || mCapacity != o.mCapacity || mLevels.size() != o.mLevels.size() ||
      mCompact != o.mCompact)
    return false;
  for (size_t i = 0; i < mLevels.size(); ++i) {
    const auto& a = mLevels[i];
    const auto& b = o.mLevels[i];
    if (a.partitionFrames != b.partitionFrames || a.partitionCount != b.partitionCount ||
        a.offsetFrames != b.offsetFrames || a.inputDelayFrames != b.inputDelayFrames)
      return false;
  }
  return true;
}

}  // namespace earshot
