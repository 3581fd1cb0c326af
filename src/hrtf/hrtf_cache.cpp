// The prepared-set cache of HrtfSet::load: a set's prepared arrays (the
// minimum-phase HRIRs at the engine's rate, delays, directions) in one file
// per (SOFA bytes, rate, mode, preparation fingerprint), so that the next
// process loads in milliseconds what took ~0.5 s to prepare.
//
// File layout (native byte order; the endianness word rejects a file from
// another machine): magic "EARSHRTF", format version, endianness word, the
// key, the rate and mode, the file's rate and reference onset, M and the
// HRIR length, then directions (3M float), file angles (3M float), taps
// (2 M length float), delays (2M double), and a 128-bit hash of all the
// bytes before it (earshot/io/disk_cache.h). A reader checks every size
// against the file's before allocating, every value for finiteness, every
// direction for unit length, and the rate and delays for the ranges a SOFA
// file can give (the checksum is no seal: anyone can compute it); anything
// else is a miss.
#include <cmath>
#include <cstring>
#include <vector>

#include "earshot/hrtf/hrtf_set.h"
#include "earshot/io/disk_cache.h"

namespace earshot::hrtf {

namespace {

constexpr char kMagic[8] = {'E', 'A', 'R', 'S', 'H', 'R', 'T', 'F'};
constexpr uint32_t kFormatVersion = 1;
constexpr uint32_t kEndianWord = 0x01020304;
constexpr uint64_t kMaxMeasurements = uint64_t(1) << 20;
// HrtfSet::load's ranges: a file's rate in [1 kHz, 1 MHz]; an ear's delay
// is (onset + Data.Delay) / file rate less the mean of those, with the
// onset within a file sample (<= 1 ms) of the HRIR (length / rate s,
// resampled) and |Data.Delay| at most a second, so every one and their
// mean lie within 1.01 s + length / rate of 0, and a delay within twice
// that.
bool plausibleOnset(double seconds, double bound) { return std::fabs(seconds) <= bound; }

struct Header {
  char magic[8];
  uint32_t version, endian;
  uint64_t key[4];
  double rate;
  uint32_t mode, reserved;
  double fileRate, referenceOnset;
  uint64_t measurements, length;
};
static_assert(sizeof(Header) == 8 + 8 + 32 + 8 + 8 + 16 + 16, "no padding in the cache header");

uint64_t payloadBytes(uint64_t m, uint64_t length) {
  return m * 3 * sizeof(float) * 2 + m * 2 * length * sizeof(float) + m * 2 * sizeof(double);
}

template <class T>
void append(std::string& out, const T* p, std::size_t count) {
  out.append(reinterpret_cast<const char*>(p), count * sizeof(T));
}

template <class T>
const char* take(const char* p, T* out, std::size_t count) {
  std::memcpy(out, p, count * sizeof(T));
  return p + count * sizeof(T);
}

}  // namespace

std::string HrtfSet::cacheFileName(const CacheKey& key, double sampleRateHz, InterpolationMode mode) {
  struct {
    CacheKey key;
    double rate;
    uint64_t mode;
  } what{key, sampleRateHz, uint64_t(mode)};
  return cacheEntryName("hrtf-", &what, sizeof what);
}

std::shared_ptr<HrtfSet> HrtfSet::readPrepared(const std::string& file, const CacheKey& key, double sampleRateHz,
                                               InterpolationMode mode, uint64_t maxBytes) {
  const std::optional<std::string> entry = readCacheEntry(file, maxBytes);
  if (!entry || entry->size() < sizeof(Header)) return nullptr;
  const std::string& bytes = *entry;
  const uint64_t size = bytes.size();
  Header h;
  std::memcpy(&h, bytes.data(), sizeof h);
  if (std::memcmp(h.magic, kMagic, 8) != 0 || h.version != kFormatVersion || h.endian != kEndianWord) return nullptr;
  for (int i = 0; i < 4; ++i)
    if (h.key[i] != key[size_t(i)]) return nullptr;
  if (h.rate != sampleRateHz || h.mode != uint32_t(mode)) return nullptr;
  if (h.measurements < 1 || h.measurements > kMaxMeasurements || h.length < 1 || h.length > HrirPair::kMaxTaps)
    return nullptr;
  if (size != sizeof(Header) + payloadBytes(h.measurements, h.length)) return nullptr;
  if (!(h.fileRate >= HrtfSet::kMinFileRateHz && h.fileRate <= HrtfSet::kMaxFileRateHz)) return nullptr;
  const double onsetBound = 1.01 + double(h.length) / sampleRateHz;
  if (!plausibleOnset(h.referenceOnset, onsetBound)) return nullptr;

  auto set = std::shared_ptr<HrtfSet>(new HrtfSet());
  const std::size_t m = h.measurements, taps = h.length;
  set->mMode = mode;
  set->mSampleRateHz = sampleRateHz;
  set->mFileSampleRateHz = h.fileRate;
  set->mReferenceOnsetSeconds = h.referenceOnset;
  set->mLength = taps;
  set->mOnsetTap = 0;
  set->mDirections.resize(m);
  set->mFileAngles.resize(m);
  set->mTaps.resize(m * 2 * taps);
  set->mDelays.resize(m * 2);
  const char* p = bytes.data() + sizeof(Header);
  std::vector<float> xyz(3 * m);
  p = take(p, xyz.data(), xyz.size());
  for (std::size_t i = 0; i < m; ++i) {
    const Vec3f d(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    if (!isFinite(Vec3d(d)) || !(std::fabs(length(Vec3d(d)) - 1.0) < 1e-4)) return nullptr;
    set->mDirections[i] = d;
  }
  p = take(p, xyz.data(), xyz.size());
  for (std::size_t i = 0; i < m; ++i) {
    set->mFileAngles[i] = Vec3f(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    if (!isFinite(Vec3d(set->mFileAngles[i]))) return nullptr;
  }
  p = take(p, set->mTaps.data(), set->mTaps.size());
  p = take(p, set->mDelays.data(), set->mDelays.size());
  for (float v : set->mTaps)
    if (!std::isfinite(v)) return nullptr;
  for (double v : set->mDelays)
    if (!plausibleOnset(v, 2 * onsetBound)) return nullptr;  // NaN too
  set->mFromCache = true;
  return set;
}

void HrtfSet::writePrepared(const std::string& folder, const std::string& name, const CacheKey& key) const {
  Header h{};
  std::memcpy(h.magic, kMagic, 8);
  h.version = kFormatVersion;
  h.endian = kEndianWord;
  for (int i = 0; i < 4; ++i) h.key[i] = key[size_t(i)];
  h.rate = mSampleRateHz;
  h.mode = uint32_t(mMode);
  h.fileRate = mFileSampleRateHz;
  h.referenceOnset = mReferenceOnsetSeconds;
  h.measurements = mDirections.size();
  h.length = mLength;
  std::string bytes;
  bytes.reserve(sizeof h + payloadBytes(h.measurements, h.length));
  append(bytes, &h, 1);
  std::vector<float> xyz;
  xyz.reserve(3 * mDirections.size());
  for (const Vec3f& d : mDirections) xyz.insert(xyz.end(), {d.x, d.y, d.z});
  append(bytes, xyz.data(), xyz.size());
  xyz.clear();
  for (const Vec3f& a : mFileAngles) xyz.insert(xyz.end(), {a.x, a.y, a.z});
  append(bytes, xyz.data(), xyz.size());
  append(bytes, mTaps.data(), mTaps.size());
  append(bytes, mDelays.data(), mDelays.size());
  writeCacheEntry(folder, name, bytes, "hrtf-", kMaxCachedSets);
}

}  // namespace earshot::hrtf
