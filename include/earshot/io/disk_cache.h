#pragma once
/** @file earshot's cache folder: prepared data (HRTF sets, late noises) that
 *  a later process loads instead of computing again. Entries are whole
 *  files, checked on every read (size, a trailing 128-bit checksum) and
 *  written through writeFileAtomically; anything wrong is a miss. */
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace earshot {

/** 128-bit hash of bytes: two lanes of MurmurHash3-style word mixing with
 *  different constants and a final avalanche each. Not cryptographic: it
 *  keys and checks entries of a cache in the user's own folder. */
struct Hash128 {
  uint64_t a = 0, b = 0;
};
Hash128 hashBytes(const void* data, std::size_t size, uint64_t seed = 0);

/** The cache folder: $EARSHOT_CACHE_DIR ("" or "off": none, returns ""),
 *  else $XDG_CACHE_HOME/earshot, else $HOME/.cache/earshot (absolute paths
 *  only), else "". */
std::string cacheFolder();

/** `prefix` (lowercase letters and a '-', e.g. "hrtf-") + 32 hex digits of
 *  the hash of `key` + ".bin". */
std::string cacheEntryName(const std::string& prefix, const void* key, std::size_t keyBytes);

/** The entry's bytes without its checksum, if `path` is a regular file (a
 *  FIFO would block) of at most maxBytes whose last 16 bytes are the hash
 *  of the rest; else nothing. */
std::optional<std::string> readCacheEntry(const std::string& path, uint64_t maxBytes);

/** Writes `bytes` and their checksum to folder/name (the folder made if
 *  needed; atomically), then keeps the newest `keep` entries named
 *  `prefix`*.bin of the folder. Best effort: false if anything failed. */
bool writeCacheEntry(const std::string& folder, const std::string& name, const std::string& bytes,
                     const std::string& prefix, std::size_t keep);

/** One file of the cache folder that earshot wrote: an entry
 *  (`kind`-<32 hex digits>.bin: "hrtf", "noise") or a temporary file an
 *  interrupted write left (kind "partial"). */
struct CacheFile {
  std::string path, kind;
  uint64_t bytes = 0;
};
/** earshot's files in `folder` (nothing else in it), sorted by name. */
std::vector<CacheFile> listCacheFiles(const std::string& folder);
/** Removes earshot's files from `folder` (not the folder nor any other
 *  file); returns how many went. */
std::size_t clearCacheFiles(const std::string& folder);

}  // namespace earshot
