// Binaural decoder for ambisonic signals: see ambisonic_decoder.h.
#include "earshot/ir/ambisonic_decoder.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <complex>
#include <string>
#include <thread>
#include <vector>

#include "earshot/core/math.h"
#include "earshot/core/thread_runs.h"
#include "earshot/hrtf/coordinates.h"
#include "earshot/ir/spherical_harmonics.h"
#include "spectral_synth.h"

namespace earshot {

namespace {

size_t nextPow2(size_t n) {
  size_t p = 1;
  while (p < n) p *= 2;
  return p;
}

using cd = std::complex<double>;

// Directions x frequency bins the design holds (as float pairs per ear:
// 128 MB at the limit; the shipped KU100 set needs 1.2 M).
constexpr size_t kMaxDecoderDesignValues = size_t(8) << 20;
// Rotating phasors (e^(i k w), one complex multiply per bin) are set exactly
// every this many bins: their rounding stays near 1e-14.
constexpr size_t kPhasorAnchor = 32;

// The design's threads: the machine's cores, at most 4.
size_t designThreads() { return std::clamp<size_t>(std::thread::hardware_concurrency(), 1, 4); }

// The 2x2 mixing M closest to the identity with M Cx M^H = Cy (Vilkamo et
// al. 2013, with the identity as prototype): M = Ky P Kx^-1, P = V U^H from
// the SVD of Kx^H Ky = U S V^H, K the Cholesky factors.
Eigen::Matrix2cd covarianceMixing(Eigen::Matrix2cd cx, Eigen::Matrix2cd cy) {
  const double ex = 1e-9 * std::max(1e-30, cx.trace().real()), ey = 1e-9 * std::max(1e-30, cy.trace().real());
  cx += ex * Eigen::Matrix2cd::Identity();
  cy += ey * Eigen::Matrix2cd::Identity();
  const Eigen::Matrix2cd kx = cx.llt().matrixL(), ky = cy.llt().matrixL();
  Eigen::JacobiSVD<Eigen::Matrix2cd> svd(kx.adjoint() * ky, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix2cd p = svd.matrixV() * svd.matrixU().adjoint();
  return ky * p * kx.inverse();
}

}  // namespace

Result<std::shared_ptr<const AmbisonicDecoder>> AmbisonicDecoder::create(const BinauralModel& model,
                                                                        const AmbisonicDecoderSettings& s) {
  if (s.order < 1 || s.order > kMaxAmbisonicOrder)
    return invalidArgument("ambisonic decoder: order " + std::to_string(s.order) + " is outside [1, 3]");
  if (!(s.alignedAboveHz > 0) || !std::isfinite(s.alignedAboveHz))
    return invalidArgument("ambisonic decoder: the time-alignment crossover must be a positive frequency");
  if (s.taps < 128 || s.taps > 8192 || (s.taps & (s.taps - 1)) != 0 || s.delayFrames >= s.taps / 2)
    return invalidArgument("ambisonic decoder: taps must be a power of two in [128, 8192] and the delay below half");
  const hrtf::HrtfSet& set = model.hrtf();
  const double fs = set.sampleRateHz();
  const size_t hrir = set.hrirLength();
  // Room for the HRIR, its onset (+-1 ms) and the bulk delay.
  const size_t n = std::max(s.taps, nextPow2(2 * (hrir + s.delayFrames + size_t(std::ceil(0.001 * fs)))));
  const size_t bins = n / 2 + 1;
  const int channels = ambisonicChannels(s.order);

  // Measurements that carry weight, their harmonics and HRTFs.
  const std::vector<double>& weight = model.measurementWeights();
  std::vector<size_t> used;
  for (size_t i = 0; i < set.measurementCount(); ++i)
    if (weight[i] > 0) used.push_back(i);
  const Eigen::Index m = Eigen::Index(used.size());
  if (m < channels) return invalidArgument(set.path() + ": too few HRTF directions for an order-" +
                                           std::to_string(s.order) + " decoder");
  Eigen::MatrixXd y(m, channels);
  Eigen::VectorXd w(m);
  for (Eigen::Index r = 0; r < m; ++r) {
    const Vec3d d(hrtf::headToSofa(Vec3d(set.measurement(used[size_t(r)]).headDirection)));
    double h[kMaxAmbisonicChannels];
    realSphericalHarmonics(normalize(d), s.order, h);
    for (int c = 0; c < channels; ++c) y(r, c) = h[c];
    w(r) = weight[used[size_t(r)]];
  }
  w /= w.sum();
  const Eigen::MatrixXd phi = y.transpose() * w.asDiagonal() * y;  // the SH channels' diffuse covariance
  Eigen::MatrixXd a = phi;
  a.diagonal().array() += 1e-6 * phi.trace() / channels;
  const Eigen::MatrixXd pinv = a.ldlt().solve(y.transpose() * w.asDiagonal());  // channels x m

  // HRTF spectra: minimum phase plus the onset and the bulk delay (the full
  // HRTF), and minimum phase plus the bulk delay alone (time-aligned).
  detail::FftrPtr ifft(kiss_fftr_alloc(int(n), 1, nullptr, nullptr));
  if (!ifft) return Status(StatusCode::kInternal, "FFT allocation failed");
  std::vector<kiss_fft_cpx> spec(bins);
  // Held in float, the full HRTFs only (the time-aligned ones differ by the
  // onset's phase, applied per bin below): 2 x directions x bins values.
  if (double(m) * double(bins) > double(kMaxDecoderDesignValues))
    return outOfRange(set.path() + ": " + std::to_string(m) + " HRTF directions x " + std::to_string(bins) +
                      " frequency bins is over the ambisonic decoder's design limit of " +
                      std::to_string(kMaxDecoderDesignValues) + " (HRIRs too long or too many directions)");
  Eigen::MatrixXcf full[2] = {Eigen::MatrixXcf(m, Eigen::Index(bins)), Eigen::MatrixXcf(m, Eigen::Index(bins))};
  Eigen::MatrixXd onsetFrames(m, 2);
  // Directions in runs on the design's threads (each its own FFT plan and
  // scratch; every direction's spectra are computed the same way whatever
  // the runs).
  const size_t threads = designThreads();
  const bool spectraOk = forRuns(size_t(m), 1, threads, [&](size_t r0, size_t r1) {
    detail::FftrPtr fft(kiss_fftr_alloc(int(n), 0, nullptr, nullptr));
    if (!fft) return false;
    std::vector<float> padded(n);
    std::vector<kiss_fft_cpx> runSpec(bins);
    for (Eigen::Index r = Eigen::Index(r0); r < Eigen::Index(r1); ++r) {
      const hrtf::HrtfMeasurement meas = set.measurement(used[size_t(r)]);
      for (int ear = 0; ear < 2; ++ear) {
        const float* taps = ear == 0 ? meas.left : meas.right;
        std::fill(padded.begin(), padded.end(), 0.0f);
        std::copy(taps, taps + hrir, padded.begin());
        kiss_fftr(fft.get(), padded.data(), runSpec.data());
        const double onset = (ear == 0 ? meas.leftDelaySeconds : meas.rightDelaySeconds) * fs;
        onsetFrames(r, ear) = onset;
        // e^(-2 pi i k (onset + delay) / n) by a rotating phasor, anchored
        // exactly every kPhasorAnchor bins (a sine and cosine per bin was
        // most of the design's time).
        const double w1 = -2.0 * kPi * (onset + double(s.delayFrames)) / double(n);
        const cd step = std::polar(1.0, w1);
        cd phase = 1.0;
        for (size_t k = 0; k < bins; ++k) {
          if (k % kPhasorAnchor == 0) phase = std::polar(1.0, w1 * double(k));
          full[ear](r, Eigen::Index(k)) = std::complex<float>(cd(runSpec[k].r, runSpec[k].i) * phase);
          phase *= step;
        }
      }
    }
    return true;
  });
  if (!spectraOk) return Status(StatusCode::kInternal, "ambisonic decoder: out of memory (FFT plans or scratch)");

  // Per bin: least squares on the full HRTFs below the crossover, on the
  // time-aligned ones above (raised-cosine crossfade over an octave around
  // it); then the covariance constraint against the full HRTFs' diffuse
  // field. Each fit is a fixed linear combination of compact HRIRs, so the
  // filters stay compact.
  std::vector<Eigen::MatrixXcd> decoders(bins);
  const double lo = s.alignedAboveHz / std::sqrt(2.0), hi = s.alignedAboveHz * std::sqrt(2.0);
  // The onsets' phases e^(2 pi i k onset / n), per direction and ear, as
  // rotating phasors (anchored as above).
  Eigen::MatrixXcd onsetStep(m, 2);
  for (Eigen::Index r = 0; r < m; ++r)
    for (int ear = 0; ear < 2; ++ear) onsetStep(r, ear) = std::polar(1.0, 2.0 * kPi * onsetFrames(r, ear) / double(n));
  // Bins in runs on the design's threads, each run starting at a phasor
  // anchor (so every bin's decoder is the same whatever the runs).
  const bool designOk = forRuns(bins, kPhasorAnchor, threads, [&](size_t k0, size_t k1) {
    Eigen::MatrixXcd d(channels, 2), hk(m, 2), onsetPhase(m, 2);
    Eigen::VectorXcd aligned(m);
    for (size_t k = k0; k < k1; ++k) {
      if (k % kPhasorAnchor == 0)
        for (Eigen::Index r = 0; r < m; ++r)
          for (int ear = 0; ear < 2; ++ear)
            onsetPhase(r, ear) = std::polar(1.0, 2.0 * kPi * double(k) * onsetFrames(r, ear) / double(n));
      const double f = double(k) * fs / double(n);
      const double t =
          f <= lo ? 0.0 : f >= hi ? 1.0 : 0.5 - 0.5 * std::cos(kPi * std::log(f / lo) / std::log(hi / lo));
      for (int ear = 0; ear < 2; ++ear) {
        hk.col(ear) = full[ear].col(Eigen::Index(k)).cast<cd>();
        if (t > 0) {  // the time-aligned HRTFs: the onset's phase taken out
          for (Eigen::Index r = 0; r < m; ++r) aligned(r) = hk(r, ear) * onsetPhase(r, ear);
          d.col(ear) = (1.0 - t) * (pinv * hk.col(ear)) + t * (pinv * aligned);
        } else {
          d.col(ear) = pinv * hk.col(ear);
        }
      }
      if (s.covarianceConstraint) {
        const Eigen::Matrix2cd target = hk.transpose() * w.asDiagonal() * hk.conjugate();
        const Eigen::Matrix2cd decoded = d.transpose() * phi * d.conjugate();
        decoders[k] = d * covarianceMixing(decoded, target).transpose();
      } else {
        decoders[k] = d;
      }
      onsetPhase = onsetPhase.cwiseProduct(onsetStep);
    }
    return true;
  });
  if (!designOk) return Status(StatusCode::kInternal, "ambisonic decoder: out of memory (design)");

  // FIRs: inverse transforms, the last eighth faded out.
  std::shared_ptr<AmbisonicDecoder> out(new AmbisonicDecoder());
  out->mSettings = s;
  out->mSettings.taps = n;
  out->mRate = fs;
  out->mFilters.assign(size_t(channels) * 2, std::vector<float>(n));
  const size_t fade = n / 8;
  for (int c = 0; c < channels; ++c)
    for (int ear = 0; ear < 2; ++ear) {
      for (size_t k = 0; k < bins; ++k) {
        const cd v = decoders[k](c, ear);
        spec[k] = {float(v.real()), (k == 0 || k == bins - 1) ? 0.0f : float(v.imag())};
      }
      std::vector<float>& fir = out->mFilters[size_t(c) * 2 + size_t(ear)];
      kiss_fftri(ifft.get(), spec.data(), fir.data());
      for (size_t i = 0; i < n; ++i) fir[i] /= float(n);
      for (size_t i = 0; i < fade; ++i)
        fir[n - 1 - i] *= float(0.5 - 0.5 * std::cos(kPi * (double(i) + 0.5) / double(fade)));
    }
  return std::shared_ptr<const AmbisonicDecoder>(std::move(out));
}

AudioBuffer AmbisonicDecoder::channelIr(int channel) const {
  AudioBuffer b(2, 0, mRate);
  b.channels[0] = filter(channel, 0);
  b.channels[1] = filter(channel, 1);
  return b;
}

Result<AudioBuffer> AmbisonicDecoder::decode(const AudioBuffer& in) const {
  if (in.channelCount() != size_t(channels()))
    return invalidArgument("ambisonic decoder: " + std::to_string(in.channelCount()) + " channels given, order " +
                           std::to_string(order()) + " takes " + std::to_string(channels()));
  const size_t len = in.frameCount() + taps() - 1;
  if (in.frameCount() > detail::kMaxIrSamples) return outOfRange("ambisonic decoder: input too long");
  const size_t n = detail::fastFftSize(len), bins = n / 2 + 1;
  detail::FftrPtr fft(kiss_fftr_alloc(int(n), 0, nullptr, nullptr));
  detail::FftrPtr ifft(kiss_fftr_alloc(int(n), 1, nullptr, nullptr));
  if (!fft || !ifft) return Status(StatusCode::kInternal, "FFT allocation failed");
  std::vector<float> padded(n);
  std::vector<kiss_fft_cpx> x(bins), h(bins), acc[2] = {std::vector<kiss_fft_cpx>(bins, {0, 0}),
                                                         std::vector<kiss_fft_cpx>(bins, {0, 0})};
  for (int c = 0; c < channels(); ++c) {
    std::fill(padded.begin(), padded.end(), 0.0f);
    std::copy(in.channels[size_t(c)].begin(), in.channels[size_t(c)].end(), padded.begin());
    kiss_fftr(fft.get(), padded.data(), x.data());
    for (int ear = 0; ear < 2; ++ear) {
      std::fill(padded.begin(), padded.end(), 0.0f);
      std::copy(filter(c, ear).begin(), filter(c, ear).end(), padded.begin());
      kiss_fftr(fft.get(), padded.data(), h.data());
      for (size_t k = 0; k < bins; ++k) {
        acc[ear][k].r += x[k].r * h[k].r - x[k].i * h[k].i;
        acc[ear][k].i += x[k].r * h[k].i + x[k].i * h[k].r;
      }
    }
  }
  AudioBuffer out(2, len, in.sampleRateHz);
  for (int ear = 0; ear < 2; ++ear) {
    kiss_fftri(ifft.get(), acc[ear].data(), padded.data());
    for (size_t i = 0; i < len; ++i) out.channels[size_t(ear)][i] = padded[i] / float(n);
  }
  return out;
}

}  // namespace earshot
