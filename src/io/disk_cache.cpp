#include "earshot/io/disk_cache.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <utility>
#include <vector>

#include "earshot/io/atomic_file.h"

namespace earshot {

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
  auto mix = [&](uint64_t w) {
    h1 ^= rotl(w * c1, 31) * c2;
    h1 = rotl(h1, 27) * 5 + 0x52dce729;
    h2 ^= rotl(w * c2, 33) * c1;
    h2 = rotl(h2, 31) * 5 + 0x38495ab5;
  };
  std::size_t i = 0;
  for (; i + 8 <= size; i += 8) {
    uint64_t w;
    std::memcpy(&w, p + i, 8);
    mix(w);
  }
  uint64_t last = 0;
  if (size > i) std::memcpy(&last, p + i, size - i);
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

std::string cacheFolder() {
  if (const char* e = std::getenv("EARSHOT_CACHE_DIR")) {
    const std::string v = e;
    if (v.empty() || v == "off") return "";
    return v;
  }
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && x[0] == '/') return std::string(x) + "/earshot";
  if (const char* h = std::getenv("HOME"); h && h[0] == '/') return std::string(h) + "/.cache/earshot";
  return "";
}

std::string cacheEntryName(const std::string& prefix, const void* key, std::size_t keyBytes) {
  const Hash128 h = hashBytes(key, keyBytes);
  char hex[40];
  std::snprintf(hex, sizeof hex, "%016llx%016llx", (unsigned long long)h.a, (unsigned long long)h.b);
  return prefix + hex + ".bin";
}

namespace {

bool isHex32(const std::string& s, std::size_t at) {
  if (s.size() < at + 32) return false;
  for (std::size_t i = at; i < at + 32; ++i)
    if (!std::isxdigit(static_cast<unsigned char>(s[i])) || std::isupper(static_cast<unsigned char>(s[i])))
      return false;
  return true;
}

// The kind of a file earshot wrote: "<kind>-<32 lowercase hex digits>.bin"
// (kind: lowercase letters, the prefix of cacheEntryName) gives its kind,
// that name + ".tmp-..." (a write's leftover) "partial", anything else "".
std::string kindOf(const std::string& name) {
  const std::size_t dash = name.find('-');
  if (dash == 0 || dash == std::string::npos) return "";
  for (std::size_t i = 0; i < dash; ++i)
    if (!std::islower(static_cast<unsigned char>(name[i]))) return "";
  if (!isHex32(name, dash + 1)) return "";
  const std::string rest = name.substr(dash + 33);
  if (rest == ".bin") return name.substr(0, dash);
  if (rest.rfind(".bin.tmp-", 0) == 0 && rest.size() > 9) return "partial";
  return "";
}

}  // namespace

std::optional<std::string> readCacheEntry(const std::string& path, uint64_t maxBytes) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec) || ec) return std::nullopt;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec || size < 16 || size > maxBytes) return std::nullopt;
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::string bytes(size, '\0');
  if (!in.read(bytes.data(), std::streamsize(size))) return std::nullopt;
  const Hash128 sum = hashBytes(bytes.data(), size - 16);
  uint64_t stored[2];
  std::memcpy(stored, bytes.data() + size - 16, 16);
  if (stored[0] != sum.a || stored[1] != sum.b) return std::nullopt;
  bytes.resize(size - 16);
  return bytes;
}

bool writeCacheEntry(const std::string& folder, const std::string& name, const std::string& bytes,
                     const std::string& prefix, std::size_t keep) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec) return false;
  const Hash128 sum = hashBytes(bytes.data(), bytes.size());
  const uint64_t stored[2] = {sum.a, sum.b};
  const Status written = writeFileAtomically(folder + "/" + name, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), std::streamsize(bytes.size()));
    out.write(reinterpret_cast<const char*>(stored), sizeof stored);
    out.close();
    return out ? Status::ok() : ioError(tmp + ": cannot write");
  });
  if (!written.isOk()) return false;
  // Keep the newest `keep` entries of this kind.
  std::vector<std::pair<fs::file_time_type, fs::path>> entries;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    if (kindOf(it->path().filename().string()) + "-" != prefix) continue;
    std::error_code e;
    const auto t = fs::last_write_time(it->path(), e);
    if (!e) entries.emplace_back(t, it->path());
  }
  if (entries.size() > keep) {
    std::sort(entries.begin(), entries.end());
    for (std::size_t i = 0; i + keep < entries.size(); ++i) fs::remove(entries[i].second, ec);
  }
  return true;
}

std::vector<CacheFile> listCacheFiles(const std::string& folder) {
  namespace fs = std::filesystem;
  std::vector<CacheFile> out;
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code e;
    if (!it->is_regular_file(e) || e) continue;
    const std::string kind = kindOf(it->path().filename().string());
    if (kind.empty()) continue;
    const uint64_t bytes = it->file_size(e);
    out.push_back({it->path().string(), kind, e ? 0 : bytes});
  }
  std::sort(out.begin(), out.end(), [](const CacheFile& a, const CacheFile& b) { return a.path < b.path; });
  return out;
}

std::size_t clearCacheFiles(const std::string& folder) {
  std::size_t removed = 0;
  for (const CacheFile& f : listCacheFiles(folder)) {
    std::error_code ec;
    if (std::filesystem::remove(f.path, ec) && !ec) ++removed;
  }
  return removed;
}

}  // namespace earshot
