// Ambisonic IR synthesis: see ambisonic_synthesis.h for the method.
#include "earshot/ir/ambisonic_synthesis.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "spectral_synth.h"

namespace earshot {

namespace {

// Independent late noise of ambisonic channel c >= 1 (W uses kLateNoiseStream)
// for IRs too short for the channels to share W's (see below).
uint64_t channelNoiseStream(int c) { return 0xA3B1C2D3E4F50000ULL + uint64_t(c); }

// Per-bin values linear between bin centres (sample i at (i + 0.5) /
// binSamples - 0.5 bins, as SpectralSynth::bandEnvelope), held beyond the
// ends. The samples' positions are the same for every channel: found once
// (runs of samples between two bin centres, each sample's fraction), then
// each channel's values are a ramp per run (a floor, a division and two
// clamps per sample and channel were a sixth of the synthesis).
class BinsToSamples {
 public:
  BinsToSamples(size_t bins, double binSamples, size_t length) : mLast(long(bins) - 1), mFrac(length) {
    const double perSample = 1.0 / binSamples;
    long j = length > 0 ? long(std::floor(0.5 * perSample - 0.5)) : 0;
    for (size_t i = 0; i < length; ++i) {
      const double x = (double(i) + 0.5) * perSample - 0.5;  // increasing: j follows floor(x)
      while (double(j + 1) <= x) ++j;
      if (mRuns.empty() || mRuns.back().j != j) mRuns.push_back({j, i});
      mFrac[i] = float(x - double(j));
    }
  }
  void operator()(const std::vector<float>& perBin, std::vector<float>& out) const {
    for (size_t r = 0; r < mRuns.size(); ++r) {
      const long j = mRuns[r].j;
      const float lo = perBin[size_t(std::clamp(j, 0L, mLast))], hi = perBin[size_t(std::clamp(j + 1, 0L, mLast))];
      const float d = hi - lo;
      const size_t end = r + 1 < mRuns.size() ? mRuns[r + 1].begin : mFrac.size();
      for (size_t i = mRuns[r].begin; i < end; ++i) out[i] = lo + mFrac[i] * d;
    }
  }

 private:
  struct Run {
    long j;        // the bin centre at or before the run's samples
    size_t begin;  // its first sample
  };
  long mLast;
  std::vector<float> mFrac;
  std::vector<Run> mRuns;
};

}  // namespace

AmbisonicFrame worldAmbisonicFrame() { return AmbisonicFrame{}; }

Result<AudioBuffer> synthesizeAmbisonicIr(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                                          const IrSynthesisSettings& settings, int order,
                                          const AmbisonicFrame& frame) {
  if (order < 1 || order > kMaxAmbisonicOrder)
    return invalidArgument("ambisonic order " + std::to_string(order) + " is outside [1, " +
                           std::to_string(kMaxAmbisonicOrder) + "]");
  for (double v : frame.worldToFrame)
    if (!std::isfinite(v)) return invalidArgument("ambisonic frame is not finite");
  auto synth = detail::SpectralSynth::plan(arrivals, reflections, settings);
  if (!synth.isOk()) return synth.status();
  detail::SpectralSynth& plan = synth.value();
  const int channels = ambisonicChannels(order);
  const double fs = settings.sampleRateHz;
  // Whether the channels share W's late noise (sharedNoise, see below).
  const size_t period = plan.noisePeriod();
  size_t spread = 1;
  while (spread < size_t(channels)) spread *= 2;
  const size_t spacing = period / spread;
  const bool sharedNoise = double(spacing) >= detail::kMinNoiseSpacingSeconds * fs;
  // The levelled and W's finished noise, and one per channel unless shared.
  EARSHOT_RETURN_IF_ERROR(plan.checkMemory(size_t(channels), sharedNoise ? 2 : 2 + size_t(channels)));

  // Arrivals: the omni arrival's spectrum times the harmonics of its direction.
  std::vector<detail::Spectrum> spectra(size_t(channels), plan.emptySpectrum());
  if (plan.arrivalSamples() > 0) {
    std::vector<float> weights(arrivals.size() * size_t(channels), 0.0f);
    double y[kMaxAmbisonicChannels];
    for (size_t i = 0; i < arrivals.size(); ++i) {
      const Arrival& a = arrivals[i];
      const double len = length(a.direction);
      const Vec3d d = len > 0 ? rotate(frame.worldToFrame, a.direction / len) : Vec3d(1, 0, 0);
      realSphericalHarmonics(d, order, y);
      for (int c = 0; c < channels; ++c) weights[i * size_t(channels) + size_t(c)] = float(y[c]);
    }
    plan.addWeightedArrivals(arrivals, weights.data(), size_t(channels), spectra.data());
  }
  AudioBuffer out(size_t(channels), 0, fs);
  for (int c = 0; c < channels; ++c) plan.inverse(spectra[size_t(c)], out.channels[size_t(c)]);
  const size_t length = plan.length();
  // settings.partialFrames: the channels after W are made up to here.
  const size_t partial = settings.partialFrames > 0 ? std::min(length, settings.partialFrames) : length;
  auto cut = [&](AudioBuffer& ir) {
    for (int c = 1; c < channels; ++c) {
      std::vector<float>& ch = ir.channels[size_t(c)];
      std::fill(ch.begin() + long(std::min(partial, ch.size())), ch.end(), 0.0f);
    }
    return std::move(ir);
  };

  if (!reflections || reflections->lastNonEmptyBin() < 0) return cut(out);
  // Band envelopes (shared by every channel) and W's late field, in this
  // thread's buffers reused by its next IR (ThreadScratch): 11 per IR, each
  // the IR's length.
  detail::ThreadScratch scratch(kNumBands + 4);
  std::vector<std::vector<float>*> env(kNumBands);
  for (int b = 0; b < kNumBands; ++b) env[size_t(b)] = &scratch[size_t(b)];
  bool anyBand = false;
  for (int b = 0; b < kNumBands; ++b) {
    if (!plan.bandEnvelope(*reflections, b, nullptr, *env[size_t(b)])) env[size_t(b)]->clear();
    anyBand = anyBand || !env[size_t(b)]->empty();
  }
  if (!anyBand) return cut(out);
  // Every channel's late noise. W's, then: when the period allows, every
  // channel reads that same noise, channel c shifted by c period / C (C the
  // channel count rounded up to a power of two), which keeps channels at
  // least detail::kMinNoiseSpacingSeconds apart, so the channels are as
  // independent as separately made noises, and a first run makes one
  // noise instead of (order + 1)^2 (each 22 FFTs of the period). Shorter
  // IRs make a noise per channel, fetched from channel `first` on: the
  // sources of one simulation, synthesised side by side, start at different
  // channels and so make different noises at the same time
  // (finishedBandNoise waits for one that another thread is making).
  std::vector<std::shared_ptr<const std::vector<std::vector<float>>>> noises{size_t(channels)};
  noises[0] = plan.finishedBandNoise(settings.seed, detail::kLateNoiseStream, {}, 0);
  const size_t offset = detail::noiseOffset(settings.seed, settings.noiseKey, period);
  const int first = int(settings.noiseKey % uint64_t(channels));
  for (int i = 0; i < channels; ++i) {
    const int c = (first + i) % channels;
    if (c == 0) continue;
    noises[size_t(c)] = sharedNoise ? noises[0] : plan.finishedBandNoise(settings.seed, channelNoiseStream(c), {}, 0);
  }
  auto lateOf = [&](int c, std::vector<float>& late, size_t count) {
    const auto& noise = noises[size_t(c)];
    const size_t at = sharedNoise ? (offset + size_t(c) * spacing) % period : offset;
    late.assign(count, 0.0f);
    for (int b = 0; b < kNumBands; ++b)
      if (!env[size_t(b)]->empty())
        plan.addEnvelopedNoise((*noise)[size_t(b)], at, *env[size_t(b)], late.data(), count);
  };
  std::vector<float>& lateW = scratch[kNumBands];
  lateOf(0, lateW, length);
  for (size_t i = 0; i < length; ++i) out.channels[0][i] += lateW[i];

  // Per histogram bin: direction and directional fraction -> each channel's
  // coherent and independent gains, then per sample.
  const size_t histBins = reflections->binCount();
  std::vector<double> frac(histBins, 0.0), harmonicsOf(histBins * kMaxAmbisonicChannels, 0.0);
  for (size_t bin = 0; bin < histBins; ++bin) {
    double mean = 0;
    for (int b = 0; b < kNumBands; ++b) mean += reflections->energy(bin, b) / kNumBands;
    const Vec3d sum = reflections->directionSum(bin);
    const double len = earshot::length(sum);
    if (!(mean > 0) || !(len > 1e-9 * mean) || !std::isfinite(len)) continue;
    frac[bin] = std::min(1.0, len / mean);
    realSphericalHarmonics(rotate(frame.worldToFrame, sum / len), order, &harmonicsOf[bin * kMaxAmbisonicChannels]);
  }
  const double binSamples = reflections->binSeconds() * fs;
  std::vector<float> coherentBins(histBins), independentBins(histBins);
  std::vector<float>& coherent = scratch[kNumBands + 1];
  std::vector<float>& independent = scratch[kNumBands + 2];
  std::vector<float>& lateC = scratch[kNumBands + 3];
  coherent.resize(partial);
  independent.resize(partial);
  const BinsToSamples toSamples(histBins, binSamples, partial);
  for (int c = 1; c < channels; ++c) {
    const double diffuse = 1.0 / double(2 * ambisonicOrderOf(c) + 1);
    for (size_t bin = 0; bin < histBins; ++bin) {
      const double a = frac[bin], yc = harmonicsOf[bin * kMaxAmbisonicChannels + size_t(c)];
      coherentBins[bin] = float(a * yc);
      independentBins[bin] = float(std::sqrt(std::max(0.0, a * yc * yc + (1.0 - a) * diffuse - a * a * yc * yc)));
    }
    toSamples(coherentBins, coherent);
    toSamples(independentBins, independent);
    lateOf(c, lateC, partial);
    float* o = out.channels[size_t(c)].data();
    for (size_t i = 0; i < partial; ++i) o[i] += coherent[i] * lateW[i] + independent[i] * lateC[i];
  }
  return cut(out);
}

}  // namespace earshot
