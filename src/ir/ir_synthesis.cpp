// IR synthesis: see ir_synthesis.h for the method and its references.
#include "earshot/ir/ir_synthesis.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstring>
#include <memory>
#include <string>

#include "earshot/core/math.h"
#include "earshot/core/random.h"
#include "spectral_synth.h"

namespace earshot {


uint64_t noiseKeyOf(const Vec3d& source, const Vec3d& listener) {
  auto bits = [](double v) {
    if (v == 0.0) v = 0.0;  // -0 and +0 are the same place
    uint64_t u = 0;
    std::memcpy(&u, &v, sizeof u);
    return u;
  };
  auto point = [&](const Vec3d& p) { return mix64(bits(p.x) ^ mix64(bits(p.y) ^ mix64(bits(p.z)))); };
  const uint64_t key = point(source) + point(listener);  // symmetric: swapping the two gives the same key
  return key == 0 ? 1 : key;
}

Status validate(const IrSynthesisSettings& s) {
  if (!(s.sampleRateHz >= 8000.0 && s.sampleRateHz <= 384000.0))
    return invalidArgument("sample rate " + std::to_string(s.sampleRateHz) + " Hz is outside [8000, 384000]");
  if (!(s.lengthSeconds >= 0.0 && s.lengthSeconds <= 600.0))
    return invalidArgument("IR length " + std::to_string(s.lengthSeconds) + " s is outside [0, 600]");
  if (!(s.bandShiftOctaves >= -1.0 && s.bandShiftOctaves <= 1.0))
    return invalidArgument("band shift " + std::to_string(s.bandShiftOctaves) + " octaves is outside [-1, 1]");
  return Status::ok();
}

Arrival toArrival(const DirectPath& direct) {
  Arrival a;
  a.delaySeconds = direct.delaySeconds;
  a.gain = direct.audible ? direct.spreadingGain : 0.0;
  a.bandGain = direct.bandGain;
  for (int b = 0; b < kNumBands; ++b) a.bandGain[size_t(b)] *= direct.directivityGain[size_t(b)];
  a.direction = direct.directionFromListener;
  return a;
}

size_t irLengthSamples(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                       const IrSynthesisSettings& s) {
  if (s.lengthSeconds > 0) return std::max<size_t>(1, size_t(std::llround(s.lengthSeconds * s.sampleRateHz)));
  double end = 0.0;
  for (const Arrival& a : arrivals)
    if (a.gain != 0) end = std::max(end, a.delaySeconds);
  if (reflections) {
    long last = reflections->lastNonEmptyBin();
    if (last >= 0) end = std::max(end, double(last + 1) * reflections->binSeconds());
  }
  return size_t(std::ceil((end + 0.05) * s.sampleRateHz));
}

Result<AudioBuffer> synthesizeOmniIr(const DirectPath* direct, const EnergyHistogram* reflections,
                                     const IrSynthesisSettings& settings) {
  std::vector<Arrival> arrivals;
  if (direct && direct->audible) arrivals.push_back(toArrival(*direct));
  return synthesizeOmniIr(arrivals, reflections, settings);
}

Result<AudioBuffer> synthesizeOmniIr(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                                     const IrSynthesisSettings& settings) {
  auto synth = detail::SpectralSynth::plan(arrivals, reflections, settings);
  if (!synth.isOk()) return synth.status();
  const double fs = settings.sampleRateHz;
  detail::SpectralSynth& plan = synth.value();
  EARSHOT_RETURN_IF_ERROR(plan.checkMemory(1, 2));  // the levelled and the finished noise
  auto spectrum = plan.emptySpectrum();
  for (const Arrival& a : arrivals) plan.addArrival(a, a.delaySeconds, {}, spectrum);
  AudioBuffer out(1, 0, fs);
  plan.inverse(spectrum, out.channels[0]);
  // Reflections: per band, the band's finished noise x sqrt(energy density).
  if (reflections && reflections->lastNonEmptyBin() >= 0) {
    const auto noise = plan.finishedBandNoise(settings.seed, detail::kLateNoiseStream, {}, 0);
    const size_t offset = detail::noiseOffset(settings.seed, settings.noiseKey, (*noise)[0].size());
    detail::ThreadScratch scratch(1);  // the band envelope in a buffer of this thread, kept for its next IR
    std::vector<float>& env = scratch[0];
    for (int b = 0; b < kNumBands; ++b)
      if (plan.bandEnvelope(*reflections, b, nullptr, env))
        plan.addEnvelopedNoise((*noise)[size_t(b)], offset, env, out.channels[0].data());
  }
  return out;
}

}  // namespace earshot
