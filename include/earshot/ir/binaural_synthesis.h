#pragma once
/** @file Binaural (2-channel: left, right) impulse responses.
 *
 *  Discrete arrivals (the direct sound, image sources): each is filtered by
 *  the HRTF of its own direction in the listener's head frame (interpolated
 *  minimum-phase HRIRs, hrtf_set.h) and placed at its own fractional delay
 *  plus that ear's onset delay, exactly, in the frequency domain (as the omni
 *  synthesis places the bare arrival; ir_synthesis.h).
 *
 *  Late reflections: the energy histogram drives band-shaped noise as in the
 *  omni IR, binauralised by a diffuse-field model of the same HRTF set:
 *  the ears' diffuse-field power spectra P_L(f), P_R(f) and cross-spectrum
 *  X(f) (averaged over the sphere with the weights lookup() gives to each
 *  measurement) set a 2x2 mixing of two independent noises U, V:
 *      L = sqrt(P_L) U,   R = (X* / sqrt(P_L)) U + sqrt(P_R - |X|^2 / P_L) V,
 *  so the two ears have the diffuse-field spectrum of the head and the
 *  diffuse-field interaural coherence, which falls with frequency (Jacobsen &
 *  Roisin, JASA 108(1), 2000; Borss & Martin, "An improved parametric model
 *  for perception-based design of virtual acoustics", AES 35th Conf., 2009)
 *  rather than two identical or two independent noises. The histogram's
 *  first-order direction of arrival then weights each ear per band and bin:
 *      g_ear^2 = (1 - a) + a * E_ear,band(d) / P_ear,band
 *  with a = |direction sum| / band-mean energy (0 diffuse, 1 one direction)
 *  and E the band energy of the HRTF toward d, so a lateral late field is
 *  louder in the near ear and a diffuse one is balanced.
 *
 *  With an identity HRTF (every HRIR a unit pulse, zero delays, e.g. the
 *  test set Pulse.sofa) both ears equal the omni IR of the same seed.
 *
 *  Conventions (docs/design.md): channel 0 left, channel 1 right; time 0 is the
 *  emission; amplitudes are the omni pressure filtered by the HRTF. */
#include <array>
#include <atomic>
#include <cstdint>
#include <complex>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "earshot/core/audio_buffer.h"
#include "earshot/core/bands.h"
#include "earshot/core/status.h"
#include "earshot/core/vec3.h"
#include "earshot/hrtf/hrtf_set.h"
#include "earshot/ir/ir_synthesis.h"

namespace earshot {

/** The listener's orientation in the world: forward and up (need not be unit
 *  or exactly orthogonal; up is made orthogonal to forward). Defaults are the
 *  glTF convention: forward -Z, up +Y. */
struct ListenerOrientation {
  Vec3d forward{0.0, 0.0, -1.0};
  Vec3d up{0.0, 1.0, 0.0};
};

/** Error unless forward and up are finite, non-zero and not parallel. */
Status validate(const ListenerOrientation& orientation);

/** A world direction in the head frame (+x right, +y up, -z forward) of a
 *  listener with this orientation (valid per validate()). Pure, any thread. */
Vec3d toHeadFrame(const Vec3d& worldDirection, const ListenerOrientation& orientation);

/** What binaural synthesis needs of an HRTF set, prepared once per set:
 *  the diffuse-field filters and the per-measurement band energies.
 *  Immutable; share it as std::shared_ptr<const BinauralModel> between
 *  threads (all members const; what it makes on first use, each
 *  measurement's minimum phase and shifted band energies, is published
 *  thread-safely and is the same whichever thread makes it). */
class BinauralModel {
 public:
  /** Prepares a model for `hrtf` (about 20-100 ms for a few thousand
   *  measurements). Any thread but the audio thread. */
  static Result<std::shared_ptr<const BinauralModel>> create(std::shared_ptr<const hrtf::HrtfSet> hrtf);

  /** Unique per model made in this process (never reused): a key for
   *  caches of what is derived from the model's filters. */
  uint64_t id() const { return mId; }
  const hrtf::HrtfSet& hrtf() const { return *mHrtf; }
  const std::shared_ptr<const hrtf::HrtfSet>& hrtfPtr() const { return mHrtf; }
  double sampleRateHz() const { return mHrtf->sampleRateHz(); }

  /** Frequency grid of the filters: values at k * fs / gridSize(), k = 0 .. gridSize() / 2. */
  size_t gridSize() const { return mGridSize; }
  /** Diffuse-field filters on the grid: L = left() U, R = rightCoherent() U + rightIndependent() V. */
  const std::vector<std::complex<float>>& left() const { return mLeft; }
  const std::vector<std::complex<float>>& rightCoherent() const { return mRightU; }
  const std::vector<std::complex<float>>& rightIndependent() const { return mRightV; }
  /** Diffuse-field power of each ear on the grid, and the cross-spectrum L R*. */
  const std::vector<double>& diffusePower(int ear) const { return mPower[ear]; }
  const std::vector<std::complex<double>>& diffuseCrossSpectrum() const { return mCross; }
  /** Weight of each measurement in the sphere average (sum 1). */
  const std::vector<double>& measurementWeights() const { return mMeasurementWeight; }
  /** The HRTF toward `headDirection` for one ear (0 left, 1 right) on the
   *  grid (gridSize() / 2 + 1 values), and that ear's onset delay (seconds,
   *  hrtf_set.h convention). Interpolated in the frequency domain: the
   *  power spectra of the measurements lookup() would combine are averaged
   *  with its weights, and so are their minimum phases (folded real
   *  cepstrum; Oppenheim & Schafer, Discrete-Time Signal Processing, 3rd ed.,
   *  sec. 13.8; each measurement's made once, on first use): the minimum
   *  phase of their averaged log magnitude. The delays are interpolated with
   *  the same weights. Unlike
   *  averaging HRIRs in the time domain, this keeps each band's energy the
   *  average of the neighbours' even where their responses differ in phase
   *  (the shadowed ear). Allocates; not for the audio thread. */
  double hrtfSpectrum(const Vec3f& headDirection, int ear, std::vector<std::complex<float>>& out) const;

  /** Band energy of the HRTF toward `headDirection` over the diffuse-field band
   *  energy of that ear (1 on average over the sphere). ear 0 left, 1 right.
   *  bandShiftOctaves: of the bands shifted so (a third-octave pass,
   *  third_octave.h), from the same grid powers; each shift's table is made
   *  on its first use (~4 ms for the shipped set) and kept (the newest 4). */
  BandArrayD relativeBandEnergy(const Vec3f& headDirection, int ear, double bandShiftOctaves = 0.0) const;

 private:
  BinauralModel() = default;
  friend Result<AudioBuffer> synthesizeBinauralIr(const std::vector<Arrival>&, const EnergyHistogram*,
                                                  const IrSynthesisSettings&, const BinauralModel&,
                                                  const ListenerOrientation&);
  // hrtfSpectrum with caller-owned scratch (an internal workspace type).
  double spectrumInto(const Vec3f& headDirection, int ear, void* workspace, std::complex<float>* out) const;
  std::shared_ptr<const hrtf::HrtfSet> mHrtf;
  uint64_t mId = 0;
  size_t mGridSize = 0;
  std::vector<std::complex<float>> mLeft, mRightU, mRightV;
  std::array<std::vector<double>, 2> mPower;
  std::vector<std::complex<double>> mCross;
  std::vector<double> mMeasurementWeight;
  std::vector<float> mRelativeBandEnergy;  // [measurement][ear][band]
  // mRelativeBandEnergy of shifted bands, by shift (made on first use).
  mutable std::mutex mShiftedMutex;
  mutable std::vector<std::pair<double, std::shared_ptr<const std::vector<float>>>> mShiftedBandEnergy;
  std::vector<float> relativeBandEnergyTable(double bandShiftOctaves) const;
  std::vector<float> mGridPower;           // [measurement][ear][grid bin]: |H|^2 with the onset removed
  // [measurement][ear][grid bin]: the minimum phase of mGridPower's
  // magnitude, each entry made on its first use and published by
  // mPhaseState (0 not made, 1 being made, 2 ready): a cache, hence mutable.
  mutable std::unique_ptr<float[]> mGridPhase;
  mutable std::unique_ptr<std::atomic<uint8_t>[]> mPhaseState;
  void minimumPhaseOf(size_t measurement, int ear, void* workspace, float* out) const;
  const float* phaseOf(size_t measurement, int ear, void* workspace, float* scratch) const;
};

/** Loads a SOFA HRTF set at `sampleRateHz` (an empty path: the shipped
 *  default, hrtf::defaultHrtfPath()) and prepares its model. A named file that
 *  cannot be used is an error naming it, never a fallback to the default.
 *  Any thread but the audio thread. */
Result<std::shared_ptr<const BinauralModel>> loadBinauralModel(const std::string& sofaPath, double sampleRateHz);

/** A 2-channel IR (left, right) from discrete arrivals (world-frame
 *  directions) and a late energy histogram (may be null), for a listener with
 *  `orientation`. settings.sampleRateHz must equal the model's rate. */
Result<AudioBuffer> synthesizeBinauralIr(const std::vector<Arrival>& arrivals, const EnergyHistogram* reflections,
                                         const IrSynthesisSettings& settings, const BinauralModel& model,
                                         const ListenerOrientation& orientation);

}  // namespace earshot
