// HrtfSet::load's prepared-set cache: a second load comes from it bit for
// bit; another rate, mode or file content is another entry; a damaged entry
// is prepared again and rewritten; no cache, an unwritable folder or a FIFO
// in the entry's place only cost time; the folder keeps the newest entries;
// the default set's prepared form that the build makes (and installs) is
// read on a first run, bit for bit the set prepared from the SOFA file.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "earshot/core/random.h"
#include "earshot/hrtf/hrtf_set.h"
#include "earshot/io/disk_cache.h"

namespace earshot::hrtf {
namespace {

namespace fs = std::filesystem;

const std::string kDataDir = std::string(EARSHOT_TEST_DATA_DIR) + "/hrtf/";
const std::string kKemar = kDataDir + "MIT_KEMAR_normal_pinna.sofa";
const std::string kPulse = kDataDir + "Pulse.sofa";

// A fresh cache folder in EARSHOT_CACHE_DIR for the test, the previous
// value back afterwards.
class HrtfCache : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/earshot_hrtf_cache_XXXXXX";
    mRoot = ::mkdtemp(tmpl);
    mFolder = mRoot + "/cache";
    if (const char* c = std::getenv("EARSHOT_CACHE_DIR")) mPrevious = c, mHadPrevious = true;
    setenv("EARSHOT_CACHE_DIR", mFolder.c_str(), 1);
  }
  void TearDown() override {
    if (mHadPrevious) setenv("EARSHOT_CACHE_DIR", mPrevious.c_str(), 1);
    else unsetenv("EARSHOT_CACHE_DIR");
    std::error_code ec;
    fs::remove_all(mRoot, ec);
  }
  std::vector<fs::path> entries() const {
    std::vector<fs::path> out;
    std::error_code ec;
    for (fs::directory_iterator it(mFolder, ec), end; !ec && it != end; it.increment(ec))
      if (it->path().filename().string().rfind("hrtf-", 0) == 0) out.push_back(it->path());
    return out;
  }
  std::shared_ptr<const HrtfSet> load(const std::string& path, double rate = 48000.0,
                                      InterpolationMode mode = InterpolationMode::kBarycentric) {
    auto r = HrtfSet::load(path, rate, mode);
    EXPECT_TRUE(r.isOk()) << r.status().message();
    return r.isOk() ? r.value() : nullptr;
  }
  std::string mRoot, mFolder, mPrevious;
  bool mHadPrevious = false;
};

// Everything a caller can see of a set: every measurement, the metadata and
// lookups in 200 random directions.
void expectSameSet(const HrtfSet& a, const HrtfSet& b) {
  ASSERT_EQ(a.measurementCount(), b.measurementCount());
  ASSERT_EQ(a.hrirLength(), b.hrirLength());
  EXPECT_EQ(a.sampleRateHz(), b.sampleRateHz());
  EXPECT_EQ(a.fileSampleRateHz(), b.fileSampleRateHz());
  EXPECT_EQ(a.referenceOnsetSeconds(), b.referenceOnsetSeconds());
  EXPECT_EQ(a.triangleCount(), b.triangleCount());
  EXPECT_EQ(a.path(), b.path());
  for (std::size_t i = 0; i < a.measurementCount(); ++i) {
    const HrtfMeasurement x = a.measurement(i), y = b.measurement(i);
    ASSERT_EQ(std::memcmp(x.left, y.left, a.hrirLength() * sizeof(float)), 0) << i;
    ASSERT_EQ(std::memcmp(x.right, y.right, a.hrirLength() * sizeof(float)), 0) << i;
    ASSERT_EQ(x.leftDelaySeconds, y.leftDelaySeconds) << i;
    ASSERT_EQ(x.rightDelaySeconds, y.rightDelaySeconds) << i;
    ASSERT_EQ(x.headDirection.x, y.headDirection.x) << i;
    ASSERT_EQ(x.headDirection.y, y.headDirection.y) << i;
    ASSERT_EQ(x.headDirection.z, y.headDirection.z) << i;
    ASSERT_EQ(x.azimuthDegrees, y.azimuthDegrees) << i;
    ASSERT_EQ(x.elevationDegrees, y.elevationDegrees) << i;
    ASSERT_EQ(x.distanceMeters, y.distanceMeters) << i;
  }
  Pcg32 rng(7, 1);
  HrirPair p, q;
  for (int k = 0; k < 200; ++k) {
    const Vec3f d(float(rng.uniformDouble() - 0.5), float(rng.uniformDouble() - 0.5), float(rng.uniformDouble() - 0.5));
    a.lookup(d, p);
    b.lookup(d, q);
    ASSERT_EQ(p.length, q.length);
    ASSERT_EQ(std::memcmp(p.left.data(), q.left.data(), p.length * sizeof(float)), 0) << k;
    ASSERT_EQ(std::memcmp(p.right.data(), q.right.data(), p.length * sizeof(float)), 0) << k;
    ASSERT_EQ(p.leftDelaySeconds, q.leftDelaySeconds);
    ASSERT_EQ(p.rightDelaySeconds, q.rightDelaySeconds);
  }
}

TEST_F(HrtfCache, SecondLoadComesFromTheCacheBitForBit) {
  auto fresh = load(kKemar);
  ASSERT_TRUE(fresh);
  EXPECT_FALSE(fresh->loadedFromCache());
  ASSERT_EQ(entries().size(), 1u);
  auto cached = load(kKemar);
  ASSERT_TRUE(cached);
  EXPECT_TRUE(cached->loadedFromCache());
  expectSameSet(*fresh, *cached);
  EXPECT_EQ(entries().size(), 1u);
}

TEST_F(HrtfCache, RateModeAndContentHaveEntriesOfTheirOwn) {
  const std::string user = mRoot + "/user.sofa";
  fs::copy_file(kKemar, user);
  load(user);
  auto at44 = load(user, 44100.0);
  EXPECT_FALSE(at44->loadedFromCache());
  auto nearest = load(user, 48000.0, InterpolationMode::kNearest);
  EXPECT_FALSE(nearest->loadedFromCache());
  EXPECT_EQ(entries().size(), 3u);
  EXPECT_TRUE(load(user, 44100.0)->loadedFromCache());
  EXPECT_TRUE(load(user, 48000.0, InterpolationMode::kNearest)->loadedFromCache());
  // Another file at the same path: its own set, not the cached one.
  fs::copy_file(kPulse, user, fs::copy_options::overwrite_existing);
  auto other = load(user);
  EXPECT_FALSE(other->loadedFromCache());
  auto pulse = load(kPulse);
  EXPECT_EQ(other->measurementCount(), pulse->measurementCount());
  EXPECT_NE(other->measurementCount(), at44->measurementCount());
}

TEST_F(HrtfCache, DamagedEntriesArePreparedAgainAndRewritten) {
  auto fresh = load(kPulse);
  ASSERT_EQ(entries().size(), 1u);
  const fs::path entry = entries().front();
  const auto size = fs::file_size(entry);
  auto damage = [&](const std::string& what, auto&& edit) {
    SCOPED_TRACE(what);
    {
      std::fstream f(entry, std::ios::in | std::ios::out | std::ios::binary);
      edit(f);
    }
    auto again = load(kPulse);
    ASSERT_TRUE(again);
    EXPECT_FALSE(again->loadedFromCache());
    expectSameSet(*fresh, *again);
    EXPECT_EQ(fs::file_size(entry), size);  // rewritten whole
    EXPECT_TRUE(load(kPulse)->loadedFromCache());
  };
  // One byte of the HRIRs, of the header's rate, of the checksum.
  for (std::streamoff at : {std::streamoff(size / 2), std::streamoff(64), std::streamoff(size - 3)})
    damage("byte " + std::to_string(at), [&](std::fstream& f) {
      f.seekg(at);
      char c = 0;
      f.read(&c, 1);
      c = char(c ^ 0x10);
      f.seekp(at);
      f.write(&c, 1);
    });
  damage("truncated", [&](std::fstream&) { fs::resize_file(entry, size / 3); });
  damage("empty", [&](std::fstream&) { fs::resize_file(entry, 0); });
  damage("longer", [&](std::fstream& f) {
    f.seekp(0, std::ios::end);
    f.write("xxxxxxxx", 8);
  });
}

// The checksum is no seal (anyone can compute it): an entry whose values a
// SOFA file could not give is a miss, whatever its checksum says. Each is
// prepared again and rewritten as it was.
TEST_F(HrtfCache, AnEntryWithAValidChecksumIsStillChecked) {
  auto fresh = load(kPulse);
  ASSERT_TRUE(fresh);
  ASSERT_EQ(entries().size(), 1u);
  const fs::path entry = entries().front();
  auto fromFile = [&] {
    std::ifstream in(entry, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string original = fromFile();
  const auto payload = readCacheEntry(entry.string(), original.size());
  ASSERT_TRUE(payload);
  ASSERT_GT(payload->size(), 96u);
  // Header: ... file rate at byte 64, reference onset at 72 (doubles); the
  // delays (doubles) end the payload. Written back with a valid checksum.
  const std::size_t lastDelay = payload->size() - sizeof(double);
  auto craft = [&](std::size_t at, double value) {
    std::string bytes = *payload;
    std::memcpy(&bytes[at], &value, sizeof value);
    ASSERT_TRUE(writeCacheEntry(mFolder, entry.filename().string(), bytes, "hrtf-", HrtfSet::kMaxCachedSets));
  };
  // A plausible value under a valid checksum is read (the crafting works).
  double delay = 0;
  std::memcpy(&delay, &(*payload)[lastDelay], sizeof delay);
  craft(lastDelay, delay + 1e-6);
  auto plausible = load(kPulse);
  ASSERT_TRUE(plausible);
  EXPECT_TRUE(plausible->loadedFromCache());
  const HrtfMeasurement last = plausible->measurement(plausible->measurementCount() - 1);
  EXPECT_EQ(last.rightDelaySeconds, delay + 1e-6);
  struct Case {
    const char* what;
    std::size_t at;
    double value;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const Case& c : {Case{"file rate 1e-30 Hz", 64, 1e-30}, Case{"file rate 3e38 Hz", 64, 3e38},
                        Case{"reference onset 1e300 s", 72, 1e300}, Case{"delay 1e300 s", lastDelay, 1e300},
                        Case{"delay -1e6 s", lastDelay, -1e6}, Case{"delay NaN", lastDelay, nan}}) {
    SCOPED_TRACE(c.what);
    craft(c.at, c.value);
    auto again = load(kPulse);
    ASSERT_TRUE(again);
    EXPECT_FALSE(again->loadedFromCache());
    expectSameSet(*fresh, *again);
    EXPECT_TRUE(fromFile() == original) << "rewritten as prepared";
  }
}

TEST_F(HrtfCache, NoCacheAnUnwritableFolderOrAFifoOnlyCostTime) {
  setenv("EARSHOT_CACHE_DIR", "off", 1);
  auto a = load(kPulse);
  EXPECT_FALSE(a->loadedFromCache());
  EXPECT_FALSE(load(kPulse)->loadedFromCache());
  EXPECT_FALSE(fs::exists(mFolder));
  // A folder under a regular file cannot be made.
  std::ofstream(mRoot + "/file") << "x";
  setenv("EARSHOT_CACHE_DIR", (mRoot + "/file/cache").c_str(), 1);
  auto b = load(kPulse);
  ASSERT_TRUE(b);
  EXPECT_FALSE(b->loadedFromCache());
  expectSameSet(*a, *b);
  // A FIFO where the entry would be: neither read (it would block) nor
  // replaced.
  setenv("EARSHOT_CACHE_DIR", mFolder.c_str(), 1);
  load(kPulse);
  ASSERT_EQ(entries().size(), 1u);
  const fs::path entry = entries().front();
  fs::remove(entry);
  ASSERT_EQ(::mkfifo(entry.c_str(), 0600), 0);
  auto c = load(kPulse);
  ASSERT_TRUE(c);
  EXPECT_FALSE(c->loadedFromCache());
  expectSameSet(*a, *c);
  EXPECT_TRUE(fs::is_fifo(entry));
}

// An empty cache folder (a first run on a machine): the shipped set comes
// prepared, from share/earshot/prepared (here the build tree's, made by
// `earshot cache --prepare` at build time), at both rates it is made for,
// bit for bit the set prepared from the SOFA file; nothing is written to the
// user's folder for it. The same bytes at another path are prepared (the
// prepared form is the shipped file's), and `off` reads nothing prepared.
TEST_F(HrtfCache, TheShippedSetIsReadPreparedOnAFirstRun) {
  auto shippedPath = defaultHrtfPath();
  ASSERT_TRUE(shippedPath.isOk()) << shippedPath.status().message();
  for (double rate : {48000.0, 44100.0}) {
    auto first = load(*shippedPath, rate);
    ASSERT_TRUE(first);
    EXPECT_TRUE(first->loadedFromCache()) << rate;
    EXPECT_TRUE(entries().empty());
    setenv("EARSHOT_CACHE_DIR", "off", 1);
    auto prepared = load(*shippedPath, rate);
    setenv("EARSHOT_CACHE_DIR", mFolder.c_str(), 1);
    ASSERT_TRUE(prepared);
    EXPECT_FALSE(prepared->loadedFromCache());
    expectSameSet(*first, *prepared);
  }
  const std::string copy = mRoot + "/copy.sofa";
  fs::copy_file(*shippedPath, copy);
  auto atOtherPath = load(copy);
  ASSERT_TRUE(atOtherPath);
  EXPECT_FALSE(atOtherPath->loadedFromCache());
}

TEST_F(HrtfCache, KeepsTheNewestEntries) {
  fs::create_directories(mFolder);
  const auto old = fs::file_time_type::clock::now() - std::chrono::hours(24);
  for (std::size_t i = 0; i < HrtfSet::kMaxCachedSets + 3; ++i) {
    char name[64];
    std::snprintf(name, sizeof name, "hrtf-%032zx.bin", i);
    const fs::path p = fs::path(mFolder) / name;
    std::ofstream(p) << "stale";
    fs::last_write_time(p, old + std::chrono::minutes(i));
  }
  std::ofstream(fs::path(mFolder) / "notes.txt") << "not an entry";
  auto set = load(kPulse);
  ASSERT_TRUE(set);
  const auto left = entries();
  EXPECT_EQ(left.size(), HrtfSet::kMaxCachedSets);
  EXPECT_TRUE(load(kPulse)->loadedFromCache());  // the new entry stayed
  EXPECT_FALSE(fs::exists(fs::path(mFolder) / "hrtf-00000000000000000000000000000000.bin"));  // the oldest went
  EXPECT_TRUE(fs::exists(fs::path(mFolder) / "notes.txt"));
}

}  // namespace
}  // namespace earshot::hrtf
