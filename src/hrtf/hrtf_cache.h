#pragma once
// The prepared-set cache's helpers (HrtfSet::load, hrtf_cache.cpp).
#include <cstddef>
#include <cstdint>
#include <string>

namespace earshot::hrtf::detail {

/** 128-bit hash of bytes: two lanes of MurmurHash3-style word mixing with
 *  different constants and a final avalanche each. Not cryptographic: it
 *  keys a cache in the user's own folder, and a changed file (any bit) gets
 *  another key. */
struct Hash128 {
  uint64_t a = 0, b = 0;
};
Hash128 hashBytes(const void* data, std::size_t size, uint64_t seed = 0);

/** The cache folder: $EARSHOT_CACHE_DIR ("" or "off": none, returns ""),
 *  else $XDG_CACHE_HOME/earshot, else $HOME/.cache/earshot (absolute paths
 *  only), else "". */
std::string preparedCacheFolder();

}  // namespace earshot::hrtf::detail
