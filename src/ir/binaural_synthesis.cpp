// Binaural IR synthesis: see binaural_synthesis.h for the method.
#include "earshot/ir/binaural_synthesis.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <new>
#include <string>

#include <Eigen/Core>

#include "earshot/core/math.h"
#include "earshot/ir/band_filter_bank.h"
#include "spectral_synth.h"

namespace earshot {

namespace {

// Directions sampled uniformly (Fibonacci sphere) to weight the measurements
// in the diffuse-field average: each sample adds lookup()'s interpolation
// weights, so a measurement counts by the solid angle it serves.
constexpr int kSphereSamples = 16384;

size_t nextPow2(size_t n) {
  size_t p = 1;
  while (p < n) p *= 2;
  return p;
}

// Spectrum on the model grid of a minimum-phase HRIR (its delay, which only
// the interaural cross-spectrum sees, is applied there).
void gridSpectrum(detail::FftrPtr& fft, std::vector<float>& padded, const float* taps, size_t length,
                  std::vector<kiss_fft_cpx>& scratch, std::complex<double>* out) {
  std::fill(padded.begin(), padded.end(), 0.0f);
  std::copy(taps, taps + length, padded.begin());
  kiss_fftr(fft.get(), padded.data(), scratch.data());
  for (size_t k = 0; k < scratch.size(); ++k) out[k] = std::complex<double>(scratch[k].r, scratch[k].i);
}

// Scratch for minimum-phase reconstruction on the model grid.
struct MinPhaseWorkspace {
  explicit MinPhaseWorkspace(size_t grid)
      : forward(kiss_fftr_alloc(int(grid), 0, nullptr, nullptr)),
        inverse(kiss_fftr_alloc(int(grid), 1, nullptr, nullptr)),
        spectrum(grid / 2 + 1),
        cepstrum(grid),
        power(grid / 2 + 1),
        phase(grid / 2 + 1),
        trig(2 * (grid / 2 + 1)),
        local(3 * (grid / 2 + 1)) {}
  bool ok() const { return forward && inverse; }
  detail::FftrPtr forward, inverse;
  std::vector<kiss_fft_cpx> spectrum;
  std::vector<float> cepstrum;
  std::vector<float> power, phase;
  std::vector<float> trig;   // cosines, then sines
  std::vector<float> local;  // a neighbour's phase not yet in the model's table, per neighbour
};

// Below this power (-200 dB) the log magnitude is clamped.
constexpr double kPowerFloor = 1e-20;

}  // namespace

// The minimum phase of measurement i's ear: the folded real cepstrum of its
// log magnitude (Oppenheim & Schafer, sec. 13.8), transformed back; the
// imaginary part is the phase.
void BinauralModel::minimumPhaseOf(size_t i, int ear, void* workspace, float* out) const {
  auto& ws = *static_cast<MinPhaseWorkspace*>(workspace);
  const size_t grid = mGridSize, gridBins = grid / 2 + 1;
  const float* power = &mGridPower[(i * 2 + size_t(ear)) * gridBins];
  for (size_t k = 0; k < gridBins; ++k)
    ws.spectrum[k] = {0.5f * std::log(std::max(power[k], float(kPowerFloor))), 0.0f};
  kiss_fftri(ws.inverse.get(), ws.spectrum.data(), ws.cepstrum.data());
  const float scale = 1.0f / float(grid);
  ws.cepstrum[0] *= scale;
  for (size_t n = 1; n < grid / 2; ++n) ws.cepstrum[n] *= 2.0f * scale;
  ws.cepstrum[grid / 2] *= scale;
  std::fill(ws.cepstrum.begin() + std::ptrdiff_t(grid / 2 + 1), ws.cepstrum.end(), 0.0f);
  kiss_fftr(ws.forward.get(), ws.cepstrum.data(), ws.spectrum.data());
  for (size_t k = 0; k < gridBins; ++k) out[k] = ws.spectrum[k].i;
}

// Measurement i's minimum phase for `ear`: from the model's table, made on
// first use. The thread that claims an entry (0 -> 1) fills it and
// publishes it (-> 2, release); another thread that finds it unpublished
// computes its own copy into `scratch` (the same numbers) instead of waiting.
const float* BinauralModel::phaseOf(size_t i, int ear, void* workspace, float* scratch) const {
  const size_t gridBins = mGridSize / 2 + 1, slot = i * 2 + size_t(ear);
  std::atomic<uint8_t>& state = mPhaseState[slot];
  float* entry = &mGridPhase[slot * gridBins];
  if (state.load(std::memory_order_acquire) == 2) return entry;
  minimumPhaseOf(i, ear, workspace, scratch);
  uint8_t expected = 0;
  if (state.compare_exchange_strong(expected, 1, std::memory_order_acq_rel)) {
    std::copy(scratch, scratch + gridBins, entry);
    state.store(2, std::memory_order_release);
  }
  return scratch;
}

double BinauralModel::spectrumInto(const Vec3f& headDirection, int ear, void* workspace,
                                   std::complex<float>* out) const {
  auto& ws = *static_cast<MinPhaseWorkspace*>(workspace);
  const size_t grid = mGridSize, gridBins = grid / 2 + 1;
  const hrtf::InterpolationWeights w = mHrtf->weights(headDirection);
  double delay = 0.0;
  // Float throughout (the grid spectra are float; exact to ~1e-7 of the
  // magnitude). The magnitude is the neighbours' power averaged with the
  // weights; the phase their minimum phases averaged with the same weights,
  // which is exactly the minimum phase of their log magnitudes averaged (the
  // cepstral construction is linear in the log magnitude), and close to the
  // averaged power's where neighbours differ little. Each measurement's
  // phase is made once (phaseOf): no transforms per arrival.
  std::fill(ws.power.begin(), ws.power.end(), 0.0f);
  std::fill(ws.phase.begin(), ws.phase.end(), 0.0f);
  for (int j = 0; j < w.count; ++j) {
    const float wj = w.weight[j];
    const float* pj = &mGridPower[(w.index[j] * 2 + size_t(ear)) * gridBins];
    for (size_t k = 0; k < gridBins; ++k) ws.power[k] += wj * pj[k];
    const float* phj = phaseOf(w.index[j], ear, workspace, &ws.local[size_t(j) * gridBins]);
    for (size_t k = 0; k < gridBins; ++k) ws.phase[k] += wj * phj[k];
  }
  for (int j = 0; j < w.count; ++j) {
    const hrtf::HrtfMeasurement m = mHrtf->measurement(w.index[j]);
    delay += double(w.weight[j]) * (ear == 0 ? m.leftDelaySeconds : m.rightDelaySeconds);
  }
  // Vectorised square root, sine and cosine (Eigen's packet math).
  using Array = Eigen::Array<float, Eigen::Dynamic, 1>;
  const Eigen::Map<const Array> power(ws.power.data(), Eigen::Index(gridBins));
  const Eigen::Map<const Array> phase(ws.phase.data(), Eigen::Index(gridBins));
  Eigen::Map<Array> magnitude(ws.power.data(), Eigen::Index(gridBins));
  magnitude = power.max(float(kPowerFloor)).sqrt();
  Eigen::Map<Array> cosine(ws.trig.data(), Eigen::Index(gridBins));
  Eigen::Map<Array> sine(ws.trig.data() + gridBins, Eigen::Index(gridBins));
  cosine = phase.cos();
  sine = phase.sin();
  for (size_t k = 0; k < gridBins; ++k) out[k] = {ws.power[k] * cosine[Eigen::Index(k)], ws.power[k] * sine[Eigen::Index(k)]};
  return delay;
}

double BinauralModel::hrtfSpectrum(const Vec3f& headDirection, int ear, std::vector<std::complex<float>>& out) const {
  MinPhaseWorkspace ws(mGridSize);
  out.resize(mGridSize / 2 + 1);
  if (!ws.ok()) throw std::bad_alloc();
  return spectrumInto(headDirection, ear, &ws, out.data());
}

Status validate(const ListenerOrientation& o) {
  if (!isFinite(o.forward) || !isFinite(o.up)) return invalidArgument("listener forward/up is not finite");
  const double lf = length(o.forward), lu = length(o.up);
  if (!(lf > 1e-12) || !(lu > 1e-12)) return invalidArgument("listener forward/up is a zero vector");
  if (length(cross(o.forward / lf, o.up / lu)) < 1e-6)
    return invalidArgument("listener forward and up are parallel");
  return Status::ok();
}

Vec3d toHeadFrame(const Vec3d& d, const ListenerOrientation& o) {
  const Vec3d f = normalize(o.forward);
  const Vec3d r = normalize(cross(f, o.up));
  const Vec3d u = cross(r, f);
  return {dot(d, r), dot(d, u), -dot(d, f)};
}

Result<std::shared_ptr<const BinauralModel>> BinauralModel::create(std::shared_ptr<const hrtf::HrtfSet> set) {
  if (!set) return invalidArgument("no HRTF set");
  std::shared_ptr<BinauralModel> m(new BinauralModel());
  static std::atomic<uint64_t> nextId{1};
  m->mId = nextId.fetch_add(1);
  m->mHrtf = set;
  const size_t taps = set->hrirLength();
  const size_t count = set->measurementCount();
  if (taps == 0 || count == 0) return invalidArgument(set->path() + ": HRTF set has no HRIRs");
  // 8x oversampled: the grid resolves the HRIR's spectrum finely enough for
  // linear interpolation (tested against the exact DFT in ir_binaural_test).
  m->mGridSize = nextPow2(std::max<size_t>(512, 8 * taps));
  const size_t grid = m->mGridSize, gridBins = grid / 2 + 1;
  const double fs = set->sampleRateHz();

  // Solid-angle weight of each measurement.
  m->mMeasurementWeight.assign(count, 0.0);
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < kSphereSamples; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / kSphereSamples, r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const Vec3f dir(float(r * std::cos(golden * i)), float(r * std::sin(golden * i)), float(z));
    const hrtf::InterpolationWeights w = set->weights(dir);
    for (int k = 0; k < w.count; ++k) m->mMeasurementWeight[w.index[k]] += double(w.weight[k]) / kSphereSamples;
  }

  detail::FftrPtr fft(kiss_fftr_alloc(int(grid), 0, nullptr, nullptr));
  if (!fft) return Status(StatusCode::kInternal, "FFT allocation failed");
  std::vector<float> padded(grid);
  std::vector<kiss_fft_cpx> scratch(gridBins);
  std::vector<std::complex<double>> h[2] = {std::vector<std::complex<double>>(gridBins),
                                            std::vector<std::complex<double>>(gridBins)};
  m->mPower[0].assign(gridBins, 0.0);
  m->mPower[1].assign(gridBins, 0.0);
  m->mCross.assign(gridBins, 0.0);
  m->mGridPower.resize(count * 2 * gridBins);
  // Each measurement's minimum phase, made on first use (phaseOf): not
  // zeroed here (untouched pages cost nothing), published per entry.
  m->mGridPhase.reset(new float[count * 2 * gridBins]);
  m->mPhaseState.reset(new std::atomic<uint8_t>[count * 2]);
  for (size_t i = 0; i < count * 2; ++i) m->mPhaseState[i].store(0, std::memory_order_relaxed);
  for (size_t i = 0; i < count; ++i) {
    const hrtf::HrtfMeasurement meas = set->measurement(i);
    gridSpectrum(fft, padded, meas.left, taps, scratch, h[0].data());
    gridSpectrum(fft, padded, meas.right, taps, scratch, h[1].data());
    const double w = m->mMeasurementWeight[i];
    for (int ear = 0; ear < 2; ++ear) {
      float* power = &m->mGridPower[(i * 2 + size_t(ear)) * gridBins];
      for (size_t k = 0; k < gridBins; ++k) {
        const double p = std::norm(h[ear][k]);
        power[k] = float(p);
        m->mPower[ear][k] += w * p;
      }
    }
    if (w > 0) {
      // The ears' delays as a phase on the cross-spectrum: e^(-2 pi i k d)
      // for the interaural delay d (grid samples), by a rotating phasor
      // anchored exactly every 32 bins (one sine and cosine per bin and ear
      // was most of this function's time).
      const double d = (meas.leftDelaySeconds - meas.rightDelaySeconds) * fs / double(grid);
      const std::complex<double> step = std::polar(1.0, -2.0 * kPi * d);
      std::complex<double> phase = 1.0;
      for (size_t k = 0; k < gridBins; ++k) {
        if (k % 32 == 0) phase = std::polar(1.0, -2.0 * kPi * double(k) * d);
        m->mCross[k] += w * h[0][k] * std::conj(h[1][k]) * phase;
        phase *= step;
      }
    }
  }
  m->mRelativeBandEnergy = m->relativeBandEnergyTable(0.0);

  // Cholesky factor of the diffuse-field cross-spectral matrix.
  m->mLeft.resize(gridBins);
  m->mRightU.resize(gridBins);
  m->mRightV.resize(gridBins);
  for (size_t k = 0; k < gridBins; ++k) {
    const double pl = m->mPower[0][k], pr = m->mPower[1][k];
    const std::complex<double> x = m->mCross[k];
    if (pl > 0) {
      const double a = std::sqrt(pl);
      m->mLeft[k] = std::complex<float>(float(a), 0.0f);
      m->mRightU[k] = std::complex<float>(std::conj(x) / a);
      m->mRightV[k] = std::complex<float>(float(std::sqrt(std::max(0.0, pr - std::norm(x) / pl))), 0.0f);
    } else {
      m->mRightV[k] = std::complex<float>(float(std::sqrt(std::max(0.0, pr))), 0.0f);
    }
  }
  return std::shared_ptr<const BinauralModel>(std::move(m));
}

Result<std::shared_ptr<const BinauralModel>> loadBinauralModel(const std::string& sofaPath, double sampleRateHz) {
  std::string path = sofaPath;
  if (path.empty()) {
    auto def = hrtf::defaultHrtfPath();
    if (!def.isOk()) return def.status();
    path = *def;
  }
  auto set = hrtf::HrtfSet::load(path, sampleRateHz);
  if (!set.isOk()) return set.status();
  return BinauralModel::create(*set);
}

// [measurement][ear][band]: each measurement's band energies (through the
// late noise's band weights at bands shifted by `shift`) over the ear's
// diffuse-field band energy, from the grid powers.
std::vector<float> BinauralModel::relativeBandEnergyTable(double shift) const {
  const size_t count = mHrtf->measurementCount(), grid = mGridSize, gridBins = grid / 2 + 1;
  const double bandFs = mHrtf->sampleRateHz() * std::exp2(-shift);  // as SpectralSynth: exactly fs for the octaves
  std::vector<BandArrayD> bandWeight2(gridBins);
  for (size_t k = 0; k < gridBins; ++k) {
    bandWeight2[k] = noiseBandWeights(double(k) * bandFs / double(grid));  // the late noise's bands
    for (double& w : bandWeight2[k]) w *= w;
  }
  std::vector<double> bandEnergy(count * 2 * kNumBands, 0.0);
  BandArrayD diffuseBand[2] = {filledBands(0.0), filledBands(0.0)};
  for (size_t i = 0; i < count; ++i) {
    const double w = mMeasurementWeight[i];
    for (int ear = 0; ear < 2; ++ear) {
      double* e = &bandEnergy[(i * 2 + size_t(ear)) * kNumBands];
      const float* power = &mGridPower[(i * 2 + size_t(ear)) * gridBins];
      for (size_t k = 0; k < gridBins; ++k) {
        const double p = double(power[k]);
        for (int b = 0; b < kNumBands; ++b) e[b] += bandWeight2[k][b] * p;
      }
      for (int b = 0; b < kNumBands; ++b) diffuseBand[ear][b] += w * e[b];
    }
  }
  std::vector<float> table(bandEnergy.size());
  for (size_t i = 0; i < count; ++i)
    for (int ear = 0; ear < 2; ++ear)
      for (int b = 0; b < kNumBands; ++b) {
        const size_t at = (i * 2 + size_t(ear)) * kNumBands + size_t(b);
        const double p = diffuseBand[ear][b];
        table[at] = p > 0 ? float(bandEnergy[at] / p) : 1.0f;
      }
  return table;
}

BandArrayD BinauralModel::relativeBandEnergy(const Vec3f& headDirection, int ear, double bandShiftOctaves) const {
  const std::vector<float>* table = &mRelativeBandEnergy;
  std::shared_ptr<const std::vector<float>> shifted;
  if (bandShiftOctaves != 0.0) {
    std::lock_guard<std::mutex> lock(mShiftedMutex);
    for (const auto& [shift, t] : mShiftedBandEnergy)
      if (shift == bandShiftOctaves) shifted = t;
    if (!shifted) {
      shifted = std::make_shared<const std::vector<float>>(relativeBandEnergyTable(bandShiftOctaves));
      // A third-octave IR uses two shifts; any other shift a caller asks
      // for is kept too, but only the newest few (each ~0.3 MB).
      if (mShiftedBandEnergy.size() >= 4) mShiftedBandEnergy.erase(mShiftedBandEnergy.begin());
      mShiftedBandEnergy.emplace_back(bandShiftOctaves, shifted);
    }
    table = shifted.get();
  }
  const hrtf::InterpolationWeights w = mHrtf->weights(headDirection);
  BandArrayD out = filledBands(0.0);
  for (int k = 0; k < w.count; ++k)
    for (int b = 0; b < kNumBands; ++b)
      out[b] += double(w.weight[k]) * (*table)[(w.index[k] * 2 + size_t(ear)) * kNumBands + size_t(b)];
  return out;
}

Result<AudioBuffer> synthesizeBinauralIr(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                                         const IrSynthesisSettings& settings, const BinauralModel& model,
                                         const ListenerOrientation& orientation) {
  EARSHOT_RETURN_IF_ERROR(validate(orientation));
  if (std::abs(settings.sampleRateHz - model.sampleRateHz()) > 1e-9 * settings.sampleRateHz)
    return invalidArgument("IR rate " + std::to_string(settings.sampleRateHz) + " Hz differs from the HRTF set's " +
                           std::to_string(model.sampleRateHz()) + " Hz");
  auto synth = detail::SpectralSynth::plan(arrivals, reflections, settings);
  if (!synth.isOk()) return synth.status();
  detail::SpectralSynth& plan = synth.value();
  EARSHOT_RETURN_IF_ERROR(plan.checkMemory(2, 4));  // the levelled noise, finished for the left and two right filters
  const double fs = settings.sampleRateHz;
  const size_t grid = model.gridSize(), gridBins = grid / 2 + 1;
  detail::Spectrum spectrum[2] = {plan.emptySpectrum(), plan.emptySpectrum()};

  // Discrete arrivals through the HRTF of their own direction.
  if (!arrivals.empty()) {
    MinPhaseWorkspace ws(grid);
    if (!ws.ok()) return Status(StatusCode::kInternal, "FFT allocation failed");
    std::vector<std::complex<float>> h(gridBins);
    for (const Arrival& a : arrivals) {
      if (a.gain == 0) continue;
      const Vec3f head(toHeadFrame(a.direction, orientation));
      for (int ear = 0; ear < 2; ++ear) {
        const double delay = model.spectrumInto(head, ear, &ws, h.data());
        plan.addArrival(a, std::max(0.0, a.delaySeconds + delay), {h.data(), grid}, spectrum[ear]);
      }
    }
  }

  AudioBuffer out(2, 0, fs);
  plan.inverse(spectrum[0], out.channels[0]);
  plan.inverse(spectrum[1], out.channels[1]);

  // Late reflections: diffuse-field mixing of two noises, weighted per ear by
  // the first-order direction of arrival.
  if (reflections && reflections->lastNonEmptyBin() >= 0) {
    const size_t histBins = reflections->binCount();
    std::vector<float> gain[2][kNumBands];
    bool directional = false;
    for (size_t bin = 0; bin < histBins; ++bin) {
      double mean = 0;
      for (int b = 0; b < kNumBands; ++b) mean += reflections->energy(bin, b) / kNumBands;
      const Vec3d sum = reflections->directionSum(bin);
      const double len = length(sum);
      if (!(mean > 0) || !(len > 1e-9 * mean)) continue;
      if (!directional) {
        for (auto& ear : gain)
          for (auto& g : ear) g.assign(histBins, 1.0f);
        directional = true;
      }
      const double a = std::min(1.0, len / mean);
      const Vec3f head(toHeadFrame(sum / len, orientation));
      for (int ear = 0; ear < 2; ++ear) {
        const BandArrayD rel = model.relativeBandEnergy(head, ear, settings.bandShiftOctaves);
        for (int b = 0; b < kNumBands; ++b) gain[ear][b][bin] = float((1.0 - a) + a * rel[b]);
      }
    }
    bool independent = false;
    for (const auto& c : model.rightIndependent()) independent = independent || c != std::complex<float>(0.0f);
    // Finished band noises (levelled, through the second sqrt(W_band) and
    // the ear's diffuse-field filter), cached per model.
    const detail::GridFilter left{model.left().data(), grid}, rightU{model.rightCoherent().data(), grid},
        rightV{model.rightIndependent().data(), grid};
    const uint64_t key = model.id() * 4;
    const auto lr = plan.finishedBandNoises(settings.seed, detail::kLateNoiseStream, {{left, key + 1}, {rightU, key + 2}});
    const auto& l = lr[0];
    const auto& ru = lr[1];
    const auto rv = independent
                        ? plan.finishedBandNoise(settings.seed, detail::kLateNoiseStreamIndependent, rightV, key + 3)
                        : nullptr;
    const size_t offset = detail::noiseOffset(settings.seed, settings.noiseKey, (*l)[0].size());
    detail::ThreadScratch scratch(1);  // the band envelope in a buffer of this thread, kept for its next IR
    std::vector<float>& env = scratch[0];
    for (int b = 0; b < kNumBands; ++b) {
      const float* gl = directional ? gain[0][b].data() : nullptr;
      const float* gr = directional ? gain[1][b].data() : nullptr;
      if (!plan.bandEnvelope(*reflections, b, gl, env)) continue;
      plan.addEnvelopedNoise((*l)[size_t(b)], offset, env, out.channels[0].data());
      if (directional) plan.bandEnvelope(*reflections, b, gr, env);
      if (independent)
        plan.addEnvelopedNoises((*ru)[size_t(b)], (*rv)[size_t(b)], offset, env, out.channels[1].data());
      else
        plan.addEnvelopedNoise((*ru)[size_t(b)], offset, env, out.channels[1].data());
    }
  }
  return out;
}

}  // namespace earshot
