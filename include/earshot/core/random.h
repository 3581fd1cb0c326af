#pragma once
/** @file PCG32 (O'Neill 2014, pcg-random.org, XSH-RR variant): a small, fast
 *  generator with independent streams. earshot seeds one stream per ray index
 *  from (seed, ray index) so that results do not depend on which thread traced
 *  which ray. std::mt19937 per path is ~5x slower (docs/design.md). */
#include <cstdint>

namespace earshot {

class Pcg32 {
 public:
  /** @param seed run seed; @param stream independent stream id (e.g. ray index). */
  Pcg32(uint64_t seed, uint64_t stream) {
    mInc = (stream << 1u) | 1u;
    mState = 0;
    next();
    mState += seed;
    next();
  }
  uint32_t next() {
    uint64_t old = mState;
    mState = old * 6364136223846793005ULL + mInc;
    auto xorshifted = static_cast<uint32_t>(((old >> 18u) ^ old) >> 27u);
    auto rot = static_cast<uint32_t>(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((-rot) & 31));
  }
  /** Uniform in [0, 1) with 24 bits (exactly representable as float). */
  float uniform() { return float(next() >> 8) * (1.0f / 16777216.0f); }
  /** Uniform in [0, 1) with 53 bits. */
  double uniformDouble() {
    uint64_t hi = next(), lo = next();
    return double(((hi << 32) | lo) >> 11) * (1.0 / 9007199254740992.0);
  }

 private:
  uint64_t mState;
  uint64_t mInc;
};

/** Mixes a 64-bit value (SplitMix64 finaliser): derives sub-seeds. */
constexpr uint64_t mix64(uint64_t z) {
  z += 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

}  // namespace earshot
