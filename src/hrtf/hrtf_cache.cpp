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
// bytes before it. A reader checks every size against the file's before
// allocating, every value for finiteness and every direction for unit
// length; anything else is a miss.
#include "hrtf_cache.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include "earshot/hrtf/hrtf_set.h"
#include "earshot/io/atomic_file.h"

namespace earshot::hrtf {

namespace detail {

namespace {

inline uint64_t rotl(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }

inline uint64_t fmix(uint64_t k) {
  k ^= k >> 33;
  k *= 0xff51afd7ed558ccdULL;
  k ^= k >> 33;
  k *= 0xc4ceb9fe1a85ec53ULL;
  k ^= k >> 33;
  return k;
}

}  // namespace

Hash128 hashBytes(const void* data, std::size_t size, uint64_t seed) {
  constexpr uint64_t c1 = 0x87c37b91114253d5ULL, c2 = 0x4cf5ad432745937fULL;
  const auto* p = static_cast<const unsigned char*>(data);
  uint64_t h1 = seed ^ 0x9e3779b97f4a7c15ULL, h2 = seed ^ 0x6a09e667f3bcc909ULL;
  std::size_t i = 0;
  auto mix = [&](uint64_t w) {
    h1 ^= rotl(w * c1, 31) * c2;
    h1 = rotl(h1, 27) * 5 + 0x52dce729;
    h2 ^= rotl(w * c2, 33) * c1;
    h2 = rotl(h2, 31) * 5 + 0x38495ab5;
  };
  for (; i + 8 <= size; i += 8) {
    uint64_t w;
    std::memcpy(&w, p + i, 8);
    mix(w);
  }
  uint64_t last = 0;
  std::memcpy(&last, p + i, size - i);
  mix(last ^ (uint64_t(size - i) << 56));
  h1 ^= size;
  h2 ^= size;
  h1 += h2;
  h2 += h1;
  h1 = fmix(h1);
  h2 = fmix(h2);
  h1 += h2;
  h2 += h1;
  return {h1, h2};
}

std::string preparedCacheFolder() {
  if (const char* e = std::getenv("EARSHOT_CACHE_DIR")) {
    const std::string v = e;
    if (v.empty() || v == "off") return "";
    return v;
  }
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && x[0] == '/') return std::string(x) + "/earshot";
  if (const char* h = std::getenv("HOME"); h && h[0] == '/') return std::string(h) + "/.cache/earshot";
  return "";
}

}  // namespace detail

namespace {

constexpr char kMagic[8] = {'E', 'A', 'R', 'S', 'H', 'R', 'T', 'F'};
constexpr uint32_t kFormatVersion = 1;
constexpr uint32_t kEndianWord = 0x01020304;
constexpr uint64_t kMaxMeasurements = uint64_t(1) << 20;

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
  const detail::Hash128 h = detail::hashBytes(&what, sizeof what);
  char name[64];
  std::snprintf(name, sizeof name, "hrtf-%016llx%016llx.bin", (unsigned long long)h.a, (unsigned long long)h.b);
  return name;
}

std::shared_ptr<HrtfSet> HrtfSet::readPrepared(const std::string& file, const CacheKey& key, double sampleRateHz,
                                               InterpolationMode mode, uint64_t maxBytes) {
  std::error_code ec;
  // A regular file only (a FIFO would block the read), no larger than a
  // set may be.
  if (!std::filesystem::is_regular_file(file, ec) || ec) return nullptr;
  const uint64_t size = std::filesystem::file_size(file, ec);
  if (ec || size < sizeof(Header) + 16 || size > maxBytes) return nullptr;
  std::ifstream in(file, std::ios::binary);
  if (!in) return nullptr;
  std::string bytes(size, '\0');
  if (!in.read(bytes.data(), std::streamsize(size))) return nullptr;
  Header h;
  std::memcpy(&h, bytes.data(), sizeof h);
  if (std::memcmp(h.magic, kMagic, 8) != 0 || h.version != kFormatVersion || h.endian != kEndianWord) return nullptr;
  for (int i = 0; i < 4; ++i)
    if (h.key[i] != key[size_t(i)]) return nullptr;
  if (h.rate != sampleRateHz || h.mode != uint32_t(mode)) return nullptr;
  if (h.measurements < 1 || h.measurements > kMaxMeasurements || h.length < 1 || h.length > HrirPair::kMaxTaps)
    return nullptr;
  if (size != sizeof(Header) + payloadBytes(h.measurements, h.length) + 16) return nullptr;
  const detail::Hash128 sum = detail::hashBytes(bytes.data(), size - 16);
  uint64_t stored[2];
  std::memcpy(stored, bytes.data() + size - 16, 16);
  if (stored[0] != sum.a || stored[1] != sum.b) return nullptr;
  if (!(std::isfinite(h.fileRate) && h.fileRate > 0) || !std::isfinite(h.referenceOnset)) return nullptr;

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
    if (!std::isfinite(v)) return nullptr;
  set->mFromCache = true;
  return set;
}

void HrtfSet::writePrepared(const std::string& folder, const std::string& file, const CacheKey& key) const {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec) return;
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
  bytes.reserve(sizeof h + payloadBytes(h.measurements, h.length) + 16);
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
  const detail::Hash128 sum = detail::hashBytes(bytes.data(), bytes.size());
  const uint64_t stored[2] = {sum.a, sum.b};
  append(bytes, stored, 2);
  const Status written = writeFileAtomically(file, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), std::streamsize(bytes.size()));
    out.close();
    return out ? Status::ok() : ioError(tmp + ": cannot write");
  });
  if (!written.isOk()) return;
  // Keep the newest kMaxCachedSets entries.
  std::vector<std::pair<fs::file_time_type, fs::path>> entries;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind("hrtf-", 0) != 0 || name.size() != 41 || name.substr(37) != ".bin") continue;
    std::error_code e;
    const auto t = fs::last_write_time(it->path(), e);
    if (!e) entries.emplace_back(t, it->path());
  }
  if (entries.size() <= kMaxCachedSets) return;
  std::sort(entries.begin(), entries.end());
  for (std::size_t i = 0; i + kMaxCachedSets < entries.size(); ++i) fs::remove(entries[i].second, ec);
}

}  // namespace earshot::hrtf
