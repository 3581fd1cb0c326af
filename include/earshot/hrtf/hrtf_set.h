#pragma once
/** @file HrtfSet: head-related impulse responses loaded from a SOFA
 *  SimpleFreeFieldHRIR file, resampled to the engine rate, split into
 *  minimum-phase HRIRs plus per-ear onset delays, and looked up for any
 *  direction with interpolation.
 *
 *  Why the split: interpolating HRIRs whose onsets differ (the interaural
 *  time difference and its change between neighbouring measurements) sums
 *  shifted copies and comb-filters. The set therefore stores every HRIR as
 *  its minimum-phase version (same magnitude response, onset at tap 0) and
 *  stores each ear's onset delay in seconds. lookup() interpolates the
 *  minimum-phase HRIRs and the delays separately; the caller re-applies each
 *  ear's delay as a fractional delay. Minimum phase plus a pure delay is
 *  perceptually equivalent to the measured HRIR when the delay is the
 *  excess-phase delay at low frequencies (Kulkarni, Isabelle & Colburn, JASA
 *  105(5), 1999), which is how the onset is estimated (see src/hrtf/hrir_dsp.cpp).
 *  The rendered pair keeps the measured low-frequency interaural
 *  cross-correlation ITD (tested to 20 us on the KU100 set at 90 degrees).
 *
 *  Delay convention: leftDelaySeconds / rightDelaySeconds are relative to the
 *  arrival of the sound at the head centre. To render a plane wave that
 *  reaches the head centre at time t0 (e.g. t0 = r / c for the direct sound),
 *  place tap 0 of the left HRIR at t0 + leftDelaySeconds (same for the right
 *  ear). Delays lie within about +-0.5 ms for a human-sized head and are
 *  negative for the ear facing the source; a caller whose t0 is smaller than
 *  -delay clamps to 0. The measurement's own propagation delay (loudspeaker
 *  distance) is removed: it is referenceOnsetSeconds().
 *
 *  Directions are unit vectors in the listener head frame (earshot/glTF
 *  convention, see earshot/hrtf/coordinates.h): +x right, +y up, -z forward.
 *
 *  Ears: receiver 0 of a SimpleFreeFieldHRIR file is the left ear, receiver 1
 *  the right ear (as the convention defines; ReceiverPosition is not used
 *  because some published files, e.g. the KU100 set, carry it mirrored).
 *
 *  Threading: an HrtfSet is immutable after load(); share it as
 *  std::shared_ptr<const HrtfSet>. Every const member may be called from any
 *  thread concurrently; lookup() and weights() neither allocate nor lock and
 *  may be called on the audio thread. */
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/core/vec3.h"

namespace earshot::hrtf {

/** How lookup() combines measurements. */
enum class InterpolationMode {
  /** Barycentric weights on the spherical Delaunay triangulation (convex hull)
   *  of the measured directions: the default. */
  kBarycentric,
  /** The single nearest measured direction (explicit option, no smoothing). */
  kNearest,
};

/** Result of a lookup: per-ear minimum-phase HRIR taps plus per-ear delays.
 *  Fixed capacity so lookup() never allocates; only the first `length` taps
 *  are meaningful (= HrtfSet::hrirLength()). About 32 KB: keep one per voice
 *  rather than on a small stack. */
struct HrirPair {
  static constexpr std::size_t kMaxTaps = 4096;
  std::array<float, kMaxTaps> left{};   ///< minimum-phase left-ear HRIR, onset at onsetTap()
  std::array<float, kMaxTaps> right{};  ///< minimum-phase right-ear HRIR, onset at onsetTap()
  std::size_t length = 0;               ///< valid taps in left/right
  double leftDelaySeconds = 0.0;        ///< where tap 0 goes, relative to head-centre arrival
  double rightDelaySeconds = 0.0;       ///< where tap 0 goes, relative to head-centre arrival
};

/** Up to three measurement indices and their weights (sum 1). */
struct InterpolationWeights {
  std::array<std::size_t, 3> index{};
  std::array<float, 3> weight{};
  int count = 0;  ///< 1 (nearest / clamped) to 3 (inside a triangle)
};

/** One measured direction of the set, after resampling and the
 *  minimum-phase / delay split.
 *  Pointers stay valid for the lifetime of the HrtfSet. */
struct HrtfMeasurement {
  Vec3f headDirection;          ///< unit vector, head frame
  double azimuthDegrees = 0.0;  ///< as in the file (SOFA convention)
  double elevationDegrees = 0.0;
  double distanceMeters = 0.0;
  const float* left = nullptr;   ///< hrirLength() minimum-phase taps
  const float* right = nullptr;  ///< hrirLength() minimum-phase taps
  double leftDelaySeconds = 0.0;   ///< same convention as HrirPair
  double rightDelaySeconds = 0.0;
};

class HrtfSet {
 public:
  /** Loads a SOFA SimpleFreeFieldHRIR file and prepares it for lookups.
   *  @param sofaPath file path (UTF-8 bytes as the OS takes them).
   *  @param sampleRateHz engine rate, 8000..192000 Hz; HRIRs are resampled to it
   *         with a Kaiser-windowed sinc (band-limited, keeps the filter's gain),
   *         then made minimum-phase; onsets are estimated at the file's rate.
   *  @param mode interpolation used by lookup().
   *  @return the set, or an error naming the file and what is wrong: missing or
   *          unreadable file, not SOFA, another SOFA convention, not 2 receivers,
   *          a bad sampling rate, no measurements, HRIRs longer than
   *          HrirPair::kMaxTaps at this rate. Never falls back to another set.
   *  Threading: any thread except the audio thread (reads a file, allocates,
   *  prepares the measurements on up to 4 threads of its own; about 0.7 s of
   *  CPU for the 2354-direction KU100 set, a quarter of it in libmysofa's
   *  reading). The result does not depend on the thread count.
   *
   *  Prepared-set cache: a set once prepared is kept in a cache folder
   *  ($EARSHOT_CACHE_DIR; unset: $XDG_CACHE_HOME/earshot or
   *  $HOME/.cache/earshot; "" or "off": no cache) and loaded from there,
   *  bit for bit the same, when the file's bytes, the rate, the mode and
   *  the preparation's numerics (a fingerprint of it on test data) are the
   *  same: ~20 ms instead of ~0.5 s. A cache entry that is missing,
   *  unreadable, truncated or altered, or that holds what no SOFA file
   *  could give (a rate or a delay out of range, even under a valid
   *  checksum), is prepared again and rewritten; a
   *  folder that cannot be written only costs the time. At most
   *  kMaxCachedSets entries are kept (the oldest go). */
  static Result<std::shared_ptr<const HrtfSet>> load(const std::string& sofaPath, double sampleRateHz,
                                                      InterpolationMode mode = InterpolationMode::kBarycentric);

  /** HRIR for a direction in the head frame (need not be unit length; a zero or
   *  non-finite vector is treated as forward (0, 0, -1)). Writes out.length =
   *  hrirLength() taps per ear and the two delays. No allocation, no lock. */
  void lookup(const Vec3f& headDirection, HrirPair& out) const;

  /** The measurements and weights lookup() would combine for a direction.
   *  No allocation, no lock. */
  InterpolationWeights weights(const Vec3f& headDirection) const;

  /** Taps per HRIR at sampleRateHz() (<= HrirPair::kMaxTaps): the file's
   *  length scaled by the rate ratio. */
  std::size_t hrirLength() const { return mLength; }
  /** Tap index of the onset in every stored HRIR (0: minimum phase). */
  std::size_t onsetTap() const { return mOnsetTap; }
  /** Engine sampling rate the HRIRs were resampled to, Hz. */
  double sampleRateHz() const { return mSampleRateHz; }
  /** Sampling rate stored in the file, Hz. */
  double fileSampleRateHz() const { return mFileSampleRateHz; }
  /** Mean onset (both ears, all directions) in the file's time axis, seconds:
   *  the head-centre arrival time the delays are relative to. The file's HRIR
   *  for measurement i, ear e, corresponds to the stored HRIR with its tap 0
   *  placed at referenceOnsetSeconds() + delay(i, e). */
  double referenceOnsetSeconds() const { return mReferenceOnsetSeconds; }
  InterpolationMode mode() const { return mMode; }
  const std::string& path() const { return mPath; }
  /** The set came out of the prepared-set cache (see load). */
  bool loadedFromCache() const { return mFromCache; }
  /** Entries the prepared-set cache keeps (about 2.5 MB each for the
   *  shipped set at 48 kHz). */
  static constexpr std::size_t kMaxCachedSets = 16;
  /** The range of a SOFA file's Data.SamplingRate, Hz, that load() takes. */
  static constexpr double kMinFileRateHz = 1000.0;
  static constexpr double kMaxFileRateHz = 1000000.0;

  /** Number of measured directions (duplicates included, as in the file). */
  std::size_t measurementCount() const { return mDirections.size(); }
  /** Measurement i, 0 <= i < measurementCount(). */
  HrtfMeasurement measurement(std::size_t i) const;
  /** Triangles of the direction triangulation (0 if it could not be built and
   *  lookups use the nearest measurement). */
  std::size_t triangleCount() const { return mTriangles.size(); }

 private:
  struct Triangle {
    std::array<uint32_t, 3> v;
    // Edge-plane normals scaled by 1/det so that dot(d, n[k]) is the
    // (unnormalised) barycentric weight of vertex k for direction d.
    std::array<Vec3f, 3> n;
  };
  HrtfSet() = default;
  // Prepared-set cache (hrtf_cache.cpp). key: the SOFA bytes' 128-bit hash,
  // their count, the preparation's fingerprint.
  using CacheKey = std::array<uint64_t, 4>;
  static std::string cacheFileName(const CacheKey& key, double sampleRateHz, InterpolationMode mode);
  /** nullptr unless `file` holds exactly this key's set, whole and sound. */
  static std::shared_ptr<HrtfSet> readPrepared(const std::string& file, const CacheKey& key, double sampleRateHz,
                                               InterpolationMode mode, uint64_t maxBytes);
  /** Best effort: errors are ignored (the cache only saves time). */
  void writePrepared(const std::string& folder, const std::string& name, const CacheKey& key) const;
  void buildTriangulation();
  void buildNearestGrid();

  int nearestMeasurement(const Vec3f& sofaDir) const;
  int cellOf(const Vec3f& sofaDir) const;

  std::string mPath;
  InterpolationMode mMode = InterpolationMode::kBarycentric;
  double mSampleRateHz = 0.0;
  double mFileSampleRateHz = 0.0;
  double mReferenceOnsetSeconds = 0.0;
  std::size_t mLength = 0;
  std::size_t mOnsetTap = 0;
  bool mFromCache = false;

  std::vector<Vec3f> mDirections;       // unit, SOFA frame, per measurement
  std::vector<Vec3f> mFileAngles;       // azimuth deg, elevation deg, distance m
  std::vector<float> mTaps;             // [measurement][ear][mLength]
  std::vector<double> mDelays;          // [measurement][ear], seconds
  std::vector<Triangle> mTriangles;
  int mGridN = 0;                       // cube-map cells per face edge
  std::vector<uint32_t> mCellStart;     // 6 * mGridN^2 + 1 offsets into mCellTriangles
  std::vector<uint32_t> mCellTriangles;
  std::vector<uint32_t> mNearStart;     // per cell: measurements that can be nearest
  std::vector<uint32_t> mNearSites;
};

/** File name of the default HRTF set shipped in earshot's hrtf/ folder
 *  (Neumann KU100, TH Koeln, CC BY-SA 3.0; see hrtf/README.md). */
constexpr const char* kDefaultHrtfFileName = "FHK_HRIR_L2354.sofa";

/** Path of the default HRTF set: $EARSHOT_HRTF_DIR/FHK_HRIR_L2354.sofa when the
 *  environment variable is set and non-empty, else the hrtf/ folder of the
 *  source tree this library was built from. Error (naming the path tried) if
 *  the file does not exist. Any thread but the audio thread. */
Result<std::string> defaultHrtfPath();

}  // namespace earshot::hrtf
