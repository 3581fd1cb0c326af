#pragma once
// A zero-initialised, 64-byte aligned float array (for the SIMD kernels).
// Internal to src/dsp.
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <new>

namespace earshot::dsp_detail {

class AlignedFloats {
 public:
  AlignedFloats() = default;
  explicit AlignedFloats(size_t count) { resize(count); }
  ~AlignedFloats() { std::free(mData); }
  AlignedFloats(AlignedFloats&& o) noexcept : mData(o.mData), mSize(o.mSize) {
    o.mData = nullptr;
    o.mSize = 0;
  }
  AlignedFloats& operator=(AlignedFloats&& o) noexcept {
    if (this != &o) {
      std::free(mData);
      mData = o.mData;
      mSize = o.mSize;
      o.mData = nullptr;
      o.mSize = 0;
    }
    return *this;
  }
  AlignedFloats(const AlignedFloats&) = delete;
  AlignedFloats& operator=(const AlignedFloats&) = delete;

  /** Reallocates to `count` zeros (not real-time safe). */
  void resize(size_t count) {
    std::free(mData);
    mData = nullptr;
    mSize = count;
    if (count == 0) return;
    size_t bytes = ((count * sizeof(float) + 63) / 64) * 64;
    mData = static_cast<float*>(std::aligned_alloc(64, bytes));
    if (!mData) throw std::bad_alloc();
    std::memset(mData, 0, bytes);
  }
  void zero() {
    if (mData) std::memset(mData, 0, mSize * sizeof(float));
  }
  float* data() { return mData; }
  const float* data() const { return mData; }
  size_t size() const { return mSize; }
  float& operator[](size_t i) { return mData[i]; }
  float operator[](size_t i) const { return mData[i]; }

 private:
  float* mData = nullptr;
  size_t mSize = 0;
};

/** Rounds up to a multiple of 8 floats (one AVX register; the MAC kernels
 *  work in tiles of 16 or 32 floats with an 8-float tail). */
inline size_t padBins(size_t bins) { return (bins + 7) / 8 * 8; }

}  // namespace earshot::dsp_detail
