// Stochastic ray tracing with next-event estimation and a receiver sphere.
// Method: see reflection_tracer.h. References: M. R. Schroeder, "Digital
// simulation of sound transmission in reverberant spaces", JASA 47 (1970);
// R. Heinz, "Binaural room simulation based on an image source model with
// addition of statistical methods...", Appl. Acoust. 38 (1993) ("diffuse
// rain"); M. Vorlaender, Auralization (2008), ch. 11 (receiver volumes).
#include "earshot/propagation/reflection_tracer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <array>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define EARSHOT_LANES8 1
#define EARSHOT_AVX __attribute__((target("avx")))
#endif

#include "earshot/core/math.h"
#include "earshot/core/random.h"
#include "earshot/core/thread_pool.h"
#include "earshot/io/input_file.h"
#include "earshot/scene/ray_tracer.h"
#include "fixed_point.h"

namespace earshot {

namespace {

using detail::addSat;
using detail::kFixedBatch;
using detail::kFixedScale;
using detail::toFixed;
using detail::toFixedBatch;

// A hit this close to an edge (smallest barycentric coordinate) has the
// offset of its next ray checked against the neighbouring triangles
// (clearOffset): ~0.5 % of hits in rooms of half-metre triangles.
constexpr float kNearEdgeBarycentric = 1e-3f;

/** n * eps from the surface point p, unless that crosses another triangle
 *  (a neighbour meeting p's triangle at an acute angle, p within eps of
 *  their edge): then half the way to it. The check starts at eps / 20,
 *  beyond the float error of p on its own triangle. Measured in a closed
 *  box of 1728 triangles with leaning walls: 5 of 65,536 rays (60 bounces)
 *  left it through such corners with the plain offset, none with this. */
Vec3d clearOffset(const RayTracer& tracer, const Vec3d& p, const Vec3f& n, float eps) {
  Ray probe{p, 0.05f * eps, n, eps};
  Hit h;
  if (tracer.intersect(probe, h) && h.t < eps) return Vec3d(n) * (0.5 * double(h.t));
  return Vec3d(n * eps);
}

// exp(-m L) per band from two tables, L = whole metres + centimetres:
// exact at 1 cm resolution (relative error < m * 0.005, ~1e-4 at 8 kHz),
// instead of seven libm exp calls per detection.
class AirTable {
 public:
  AirTable(const BandArrayD& m, double maxLength) : mMetres(size_t(std::max(1.0, maxLength)) + 2) {
    for (size_t i = 0; i < mMetres.size(); ++i)
      for (int b = 0; b < kNumBands; ++b) mMetres[i][b] = float(std::exp(-m[b] * double(i)));
    for (size_t i = 0; i < 100; ++i)
      for (int b = 0; b < kNumBands; ++b) mCentis[i][b] = float(std::exp(-m[b] * double(i) * 0.01));
  }
  /** Fills f[b] = exp(-m_b L); lengths beyond the table give 0. */
  void factors(float length, float* f) const {
    const size_t whole = size_t(length);
    if (whole >= mMetres.size()) {
      for (int b = 0; b < kNumBands; ++b) f[b] = 0.0f;
      return;
    }
    const size_t centi = std::min<size_t>(99, size_t((length - float(whole)) * 100.0f + 0.5f));
    for (int b = 0; b < kNumBands; ++b) f[b] = mMetres[whole][b] * mCentis[centi][b];
  }

 private:
  std::vector<std::array<float, kNumBands>> mMetres;
  std::array<std::array<float, kNumBands>, 100> mCentis;
};

constexpr uint32_t kRaysPerTask = 256;

// Branchless orthonormal basis around unit n (Duff et al., JCGT 2017).
inline void basis(const Vec3f& n, Vec3f& t, Vec3f& b) {
  float sign = std::copysign(1.0f, n.z);
  const float a = -1.0f / (sign + n.z);
  const float c = n.x * n.y * a;
  t = {1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x};
  b = {c, sign + n.y * n.y * a, -n.y};
}

// Cosine-weighted direction around n: uniform point on the unit disk by
// rejection (no sin/cos), lifted to the hemisphere (Malley's method).
inline Vec3f cosineDirection(const Vec3f& n, Pcg32& rng) {
  float u, v, r2;
  do {
    u = 2.0f * rng.uniform() - 1.0f;
    v = 2.0f * rng.uniform() - 1.0f;
    r2 = u * u + v * v;
  } while (r2 >= 1.0f);
  Vec3f t, b;
  basis(n, t, b);
  float w = std::sqrt(std::max(0.0f, 1.0f - r2));
  return normalize(t * u + b * v + n * w);
}

// Where detections happen: the listener (a trace from the source), or each
// source (a shared trace, which runs from the listener: reciprocity).
struct Detector {
  Vec3d position;
  double radius = 0;
  bool probesDetected = false;  // a sphere of at least kMinProbeSphere
  float sphereR2 = 0, invSphereVolume = 0;
  float neeRouletteR2 = 0;      // shared trace needing shadow rays: sharedShadowRoulette x R^2 (0: no roulette)
  bool shadowsNeeded = true;    // not a convex room around it
  const PlaneSequenceSet* excluded = nullptr;
  uint32_t excludedMaxOrder = 0;
  // A shared trace: the source's directivity, applied to what it detects
  // (at the direction the sound left it in). Unused in a forward trace.
  Directivity directivity;
  bool directional = false;
  BandArrayD meanSquares{};
};

// counts[k] += bit k of mask, for k < width (4 or 8).
inline void addLaneCounts(uint32_t* counts, uint32_t mask, size_t width) {
#if defined(__SSE2__)
  alignas(16) static const uint32_t kNibbles[16][4] = {
      {0, 0, 0, 0}, {1, 0, 0, 0}, {0, 1, 0, 0}, {1, 1, 0, 0}, {0, 0, 1, 0}, {1, 0, 1, 0}, {0, 1, 1, 0}, {1, 1, 1, 0},
      {0, 0, 0, 1}, {1, 0, 0, 1}, {0, 1, 0, 1}, {1, 1, 0, 1}, {0, 0, 1, 1}, {1, 0, 1, 1}, {0, 1, 1, 1}, {1, 1, 1, 1}};
  for (size_t k = 0; k < width; k += 4) {
    __m128i* c = reinterpret_cast<__m128i*>(counts + k);
    const __m128i add = _mm_load_si128(reinterpret_cast<const __m128i*>(kNibbles[(mask >> k) & 0xFu]));
    _mm_storeu_si128(c, _mm_add_epi32(_mm_loadu_si128(c), add));
  }
#else
  for (size_t k = 0; k < width; ++k) counts[k] += (mask >> k) & 1u;
#endif
}

// The detectors in lanes of four, or eight where the CPU has AVX and there
// are more than four (structure of arrays), for the two loops
// a shared trace runs over all its detectors: on every segment, which
// spheres it crosses; at every reflection, which detectors get a shadow
// ray. The lanes only select: each selected detector then goes through the
// scalar code as before, so results are the same bits. The selection is
// the scalar code's predicate in the same IEEE operations in the same
// order (SSE2 has no fused multiply-add; max/min with the scalar's operand
// order), so it selects exactly the detectors the scalar code accepts.
// Measured (32 sources, furnished room): the two loops were ~40 % of the
// shared trace's own work, one scalar test per detector and segment.
class DetectorLanes {
 public:
  explicit DetectorLanes(const std::vector<Detector>& d) : mCount(d.size()), mGroups((d.size() + 7) / 8 * 2) {
    const size_t n = mGroups * 4;  // whole groups of eight
    mX.assign(n, 0.0);
    mY.assign(n, 0.0);
    mZ.assign(n, 0.0);
    mR2.assign(n, 0.0f);
    mRoulette.assign(n, 0.0f);
    mProbeBits.assign(mGroups, 0u);
    for (size_t i = 0; i < d.size(); ++i) {
      mX[i] = d[i].position.x;
      mY[i] = d[i].position.y;
      mZ[i] = d[i].position.z;
      mR2[i] = d[i].sphereR2;
      mRoulette[i] = d[i].neeRouletteR2;
      if (d[i].probesDetected) mProbeBits[i / 4] |= 1u << (i % 4);
    }
#if defined(EARSHOT_LANES8)
    // Eight at a time (AVX: the same operations, twice as wide) where the
    // CPU has it and there are more than four.
    mWide = d.size() > 4 && __builtin_cpu_supports("avx");
#endif
  }
  /** Detectors per group: 8 (AVX) or 4. */
  size_t width() const { return mWide ? 8 : 4; }
  size_t groups() const { return mWide ? (mCount + 7) / 8 : (mCount + 3) / 4; }
  /** crossed() or crossed8(), by width(). */
  uint32_t crossedAny(size_t g, const Vec3d& origin, const Vec3f& dir, float segment, bool probing) const {
#if defined(EARSHOT_LANES8)
    if (mWide) return crossed8(g, origin, dir, segment, probing);
#endif
    return crossed(g, origin, dir, segment, probing);
  }
  /** facing() or facing8(), by width(). */
  void facingAny(size_t g, const Vec3d& p, const Vec3f& n, float u, float minD2, uint32_t& send,
                 uint32_t& rouletted) const {
#if defined(EARSHOT_LANES8)
    if (mWide) return facing8(g, p, n, u, minD2, send, rouletted);
#endif
    facing(g, p, n, u, minD2, send, rouletted);
  }
  /** Bit k: detector 4g + k's sphere holds a part of the segment (origin,
   *  dir, length `segment`) longer than zero; when `probing`, only
   *  detectors that detect probes. */
  uint32_t crossed(size_t g, const Vec3d& origin, const Vec3f& dir, float segment, bool probing) const {
    const size_t i = g * 4;
    uint32_t bits = 0;
#if defined(__SSE2__)
    const __m128 ox = lanesOf(&mX[i], origin.x, false), oy = lanesOf(&mY[i], origin.y, false),
                 oz = lanesOf(&mZ[i], origin.z, false);
    const __m128 dx = _mm_set1_ps(dir.x), dy = _mm_set1_ps(dir.y), dz = _mm_set1_ps(dir.z);
    const __m128 bq = _mm_add_ps(_mm_add_ps(_mm_mul_ps(ox, dx), _mm_mul_ps(oy, dy)), _mm_mul_ps(oz, dz));
    const __m128 oo = _mm_add_ps(_mm_add_ps(_mm_mul_ps(ox, ox), _mm_mul_ps(oy, oy)), _mm_mul_ps(oz, oz));
    const __m128 disc = _mm_sub_ps(_mm_mul_ps(bq, bq), _mm_sub_ps(oo, _mm_loadu_ps(&mR2[i])));
    const __m128 root = _mm_sqrt_ps(disc);
    const __m128 nbq = _mm_xor_ps(bq, _mm_set1_ps(-0.0f));
    const __m128 t0 = _mm_max_ps(_mm_sub_ps(nbq, root), _mm_setzero_ps());   // std::max(0, x)
    const __m128 t1 = _mm_min_ps(_mm_add_ps(nbq, root), _mm_set1_ps(segment));  // std::min(segment, x)
    bits = uint32_t(_mm_movemask_ps(_mm_and_ps(_mm_cmpgt_ps(disc, _mm_setzero_ps()), _mm_cmpgt_ps(t1, t0))));
#else
    for (size_t k = 0; k < 4; ++k) {
      const Vec3f oc(origin - Vec3d{mX[i + k], mY[i + k], mZ[i + k]});
      const float bq = dot(oc, dir);
      const float disc = bq * bq - (dot(oc, oc) - mR2[i + k]);
      if (!(disc > 0)) continue;
      const float root = std::sqrt(disc);
      if (std::min(segment, -bq + root) > std::max(0.0f, -bq - root)) bits |= 1u << k;
    }
#endif
    if (probing) bits &= mProbeBits[g];
    return bits & valid(g);
  }
  /** For a reflection at p (normal n, the roulette's number u): bit k of
   *  `send`: detector 4g + k faces p and gets its shadow ray (the roulette
   *  passed, or not played); of `rouletted`: it faces p and lost. */
  void facing(size_t g, const Vec3d& p, const Vec3f& n, float u, float minD2, uint32_t& send,
              uint32_t& rouletted) const {
    const size_t i = g * 4;
#if defined(__SSE2__)
    const __m128 lx = lanesOf(&mX[i], p.x, true), ly = lanesOf(&mY[i], p.y, true), lz = lanesOf(&mZ[i], p.z, true);
    const __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(lx, lx), _mm_mul_ps(ly, ly)), _mm_mul_ps(lz, lz));
    const __m128 cosL = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(n.x), lx), _mm_mul_ps(_mm_set1_ps(n.y), ly)),
                                   _mm_mul_ps(_mm_set1_ps(n.z), lz));
    const __m128 k = _mm_loadu_ps(&mRoulette[i]);
    const __m128 d = _mm_sqrt_ps(d2);
    const __m128 pSend = _mm_div_ps(_mm_mul_ps(k, _mm_div_ps(cosL, d)), _mm_max_ps(_mm_set1_ps(minD2), d2));
    const uint32_t faces = uint32_t(_mm_movemask_ps(_mm_cmpgt_ps(cosL, _mm_setzero_ps())));
    const uint32_t played = uint32_t(_mm_movemask_ps(_mm_and_ps(_mm_cmpgt_ps(k, _mm_setzero_ps()),
                                                                _mm_cmplt_ps(pSend, _mm_set1_ps(1.0f)))));
    const uint32_t passed = uint32_t(_mm_movemask_ps(_mm_cmplt_ps(_mm_set1_ps(u), pSend)));
#else
    uint32_t faces = 0, played = 0, passed = 0;
    for (size_t j = 0; j < 4; ++j) {
      const Vec3f toL(Vec3d{mX[i + j], mY[i + j], mZ[i + j]} - p);
      const float d2 = dot(toL, toL), cosL = dot(n, toL), d = std::sqrt(d2);
      const float pSend = mRoulette[i + j] * (cosL / d) / std::max(d2, minD2);
      faces |= uint32_t(cosL > 0) << j;
      played |= uint32_t(mRoulette[i + j] > 0 && pSend < 1.0f) << j;
      passed |= uint32_t(u < pSend) << j;
    }
#endif
    send = faces & (~played | passed) & valid(g);
    rouletted = faces & played & ~passed & valid(g);
  }

#if defined(EARSHOT_LANES8)
  /** crossed() for detectors 8g .. 8g + 7. */
  EARSHOT_AVX uint32_t crossed8(size_t g, const Vec3d& origin, const Vec3f& dir, float segment, bool probing) const {
    const size_t i = g * 8;
    const __m256 ox = lanes8Of(&mX[i], origin.x, false), oy = lanes8Of(&mY[i], origin.y, false),
                 oz = lanes8Of(&mZ[i], origin.z, false);
    const __m256 dx = _mm256_set1_ps(dir.x), dy = _mm256_set1_ps(dir.y), dz = _mm256_set1_ps(dir.z);
    const __m256 bq =
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ox, dx), _mm256_mul_ps(oy, dy)), _mm256_mul_ps(oz, dz));
    const __m256 oo =
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ox, ox), _mm256_mul_ps(oy, oy)), _mm256_mul_ps(oz, oz));
    const __m256 disc = _mm256_sub_ps(_mm256_mul_ps(bq, bq), _mm256_sub_ps(oo, _mm256_loadu_ps(&mR2[i])));
    const __m256 root = _mm256_sqrt_ps(disc);
    const __m256 nbq = _mm256_xor_ps(bq, _mm256_set1_ps(-0.0f));
    const __m256 t0 = _mm256_max_ps(_mm256_sub_ps(nbq, root), _mm256_setzero_ps());
    const __m256 t1 = _mm256_min_ps(_mm256_add_ps(nbq, root), _mm256_set1_ps(segment));
    uint32_t bits = uint32_t(_mm256_movemask_ps(_mm256_and_ps(_mm256_cmp_ps(disc, _mm256_setzero_ps(), _CMP_GT_OS),
                                                              _mm256_cmp_ps(t1, t0, _CMP_GT_OS))));
    if (probing) bits &= mProbeBits[2 * g] | mProbeBits[2 * g + 1] << 4;
    return bits & valid8(g);
  }
  /** facing() for detectors 8g .. 8g + 7. */
  EARSHOT_AVX void facing8(size_t g, const Vec3d& p, const Vec3f& n, float u, float minD2, uint32_t& send,
                           uint32_t& rouletted) const {
    const size_t i = g * 8;
    const __m256 lx = lanes8Of(&mX[i], p.x, true), ly = lanes8Of(&mY[i], p.y, true), lz = lanes8Of(&mZ[i], p.z, true);
    const __m256 d2 =
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(lx, lx), _mm256_mul_ps(ly, ly)), _mm256_mul_ps(lz, lz));
    const __m256 cosL = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(n.x), lx), _mm256_mul_ps(_mm256_set1_ps(n.y), ly)),
        _mm256_mul_ps(_mm256_set1_ps(n.z), lz));
    const __m256 k = _mm256_loadu_ps(&mRoulette[i]);
    const __m256 d = _mm256_sqrt_ps(d2);
    const __m256 pSend =
        _mm256_div_ps(_mm256_mul_ps(k, _mm256_div_ps(cosL, d)), _mm256_max_ps(_mm256_set1_ps(minD2), d2));
    const uint32_t faces = uint32_t(_mm256_movemask_ps(_mm256_cmp_ps(cosL, _mm256_setzero_ps(), _CMP_GT_OS)));
    const uint32_t played = uint32_t(_mm256_movemask_ps(_mm256_and_ps(
        _mm256_cmp_ps(k, _mm256_setzero_ps(), _CMP_GT_OS), _mm256_cmp_ps(pSend, _mm256_set1_ps(1.0f), _CMP_LT_OS))));
    const uint32_t passed = uint32_t(_mm256_movemask_ps(_mm256_cmp_ps(_mm256_set1_ps(u), pSend, _CMP_LT_OS)));
    send = faces & (~played | passed) & valid8(g);
    rouletted = faces & played & ~passed & valid8(g);
  }
#endif

 private:
  uint32_t valid(size_t g) const {
    const size_t left = mCount - std::min(mCount, g * 4);
    return left >= 4 ? 0xFu : (1u << left) - 1u;
  }
  uint32_t valid8(size_t g) const {
    const size_t left = mCount - std::min(mCount, g * 8);
    return left >= 8 ? 0xFFu : (1u << left) - 1u;
  }
#if defined(EARSHOT_LANES8)
  // lanesOf() for eight detectors.
  EARSHOT_AVX static __m256 lanes8Of(const double* x, double o, bool fromO) {
    const __m256d v = _mm256_set1_pd(o), a = _mm256_loadu_pd(x), b = _mm256_loadu_pd(x + 4);
    const __m256d lo = fromO ? _mm256_sub_pd(a, v) : _mm256_sub_pd(v, a);
    const __m256d hi = fromO ? _mm256_sub_pd(b, v) : _mm256_sub_pd(v, b);
    return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm256_cvtpd_ps(lo)), _mm256_cvtpd_ps(hi), 1);
  }
#endif
#if defined(__SSE2__)
  // Four lanes of float(o - x[k]) (or float(x[k] - o) when `fromO`), the
  // difference in double as the scalar code's Vec3d subtraction.
  static __m128 lanesOf(const double* x, double o, bool fromO) {
    const __m128d v = _mm_set1_pd(o), a = _mm_loadu_pd(x), b = _mm_loadu_pd(x + 2);
    const __m128d lo = fromO ? _mm_sub_pd(a, v) : _mm_sub_pd(v, a), hi = fromO ? _mm_sub_pd(b, v) : _mm_sub_pd(v, b);
    return _mm_movelh_ps(_mm_cvtpd_ps(lo), _mm_cvtpd_ps(hi));
  }
#endif
  size_t mCount, mGroups;  // mGroups: groups of four, padded to whole groups of eight
  bool mWide = false;
  std::vector<double> mX, mY, mZ;
  std::vector<float> mR2, mRoulette;
  std::vector<uint32_t> mProbeBits;
};

// Histogram adds held back and applied in batches. A shared trace's
// sources' histograms (32 sources: ~9 MB) are beyond the cache, and a
// detection's first add waited for its line: perf put ~30 % of the trace's
// own work (beside Embree's) on those loads. Held, their lines are
// prefetched, and applied together the misses overlap. Fixed-point sums:
// the same bits in any order.
class PendingAdds {
 public:
  static constexpr size_t kMaxRun = kNumBands + 3;  // a deposit's bands and direction sums
  /** `direct`: every add made at once (one detector's histograms stay in
   *  the cache: holding its adds back only costs time). */
  explicit PendingAdds(bool direct) : mDirect(direct) {
    if (!direct) mRuns.reset(new Run[kRuns]);
  }
  /** Adds v[0, n) to target[0, n) (n <= kMaxRun; v holds kMaxRun values,
   *  copied whole), later: held, and the target's lines fetched meanwhile.
   *  Each run is one record (a deposit's adds together: one pointer, not
   *  one per value). */
  void addRun(int64_t* target, const int64_t* v, size_t n) {
    if (mDirect) {
      for (size_t k = 0; k < n; ++k) addSat(target[k], v[k]);
      return;
    }
    if (mCount == kRuns) flush();
    __builtin_prefetch(target, 1, 3);
    __builtin_prefetch(target + n - 1, 1, 3);
    Run& r = mRuns[mCount++];
    r.target = target;
    r.n = uint32_t(n);
    std::memcpy(r.v, v, kMaxRun * sizeof(int64_t));  // a fixed size: plain vector moves
  }
  void flush() {
    for (size_t i = 0; i < mCount; ++i) {
      const Run& r = mRuns[i];
      for (uint32_t k = 0; k < r.n; ++k) addSat(r.target[k], r.v[k]);
    }
    mCount = 0;
  }

 private:
  struct Run {
    int64_t* target;
    uint32_t n;
    int64_t v[kMaxRun];
  };
  static constexpr size_t kRuns = 48;  // ~500 adds held, as many as the per-value version held
  bool mDirect;
  std::unique_ptr<Run[]> mRuns;
  size_t mCount = 0;
};

// What the detectors need of a ray's path, recorded as it is traced: the
// segments a sphere may detect (after a specular reflection or a
// transmission, and a tail probe's past its cut) and the reflections whose
// diffuse part next-event estimation sends to each detector. They depend on
// the emitter, the scene and the settings alone (not on the detectors), so
// a shared trace can keep them for its next trace from the same place
// (SharedTracePaths), and detect other sources in them without tracing.
struct SegmentEvent {
  Vec3d origin;
  Vec3f direction, first;  // first: the ray's first direction (a shared trace's arrival direction)
  float length = 0;        // to the hit (1e30 when it escaped)
  float pathLength = 0;    // at its origin
  float energy[kNumBands];
  uint32_t order = 0;
  uint32_t planes = ~0u;   // PathEvents::planes index: the specular planes so far (a purely specular path), else ~0u
  bool probing = false;
};
struct ReflectionEvent {
  Vec3d p, shadowOrigin;   // the hit, and the shadow rays' origin (off the surface)
  Vec3f n, first;          // the normal facing the incoming ray; the ray's first direction
  float pathLength = 0;    // to the hit
  float scattered[kNumBands];
  float u = 0;             // the shadow-ray roulette's number
  uint32_t order = 0;      // of the reflection's incoming segment
};
struct PathEvents {
  std::vector<SegmentEvent> segments;
  std::vector<ReflectionEvent> reflections;
  std::vector<PlaneSequence> planes;
  size_t bytes() const {
    return segments.capacity() * sizeof(SegmentEvent) + reflections.capacity() * sizeof(ReflectionEvent) +
           planes.capacity() * sizeof(PlaneSequence);
  }
  void clear() {
    segments.clear();
    reflections.clear();
    planes.clear();
  }
};

// One detector's sums, per worker thread.
struct alignas(64) DetectorSums {
  std::vector<int64_t> hist;                 // [bin][kStride]
  std::vector<int64_t> perOrder;             // [order][band]
  std::vector<int64_t> probeHist;            // [bin][band]: what tail probes past their cut deposit
  int64_t late[kNumBands] = {};
  uint64_t shadows = 0, shadowsSkipped = 0, shadowsRouletted = 0, excluded = 0;
  uint64_t detections = 0, probeDetections = 0;
};

// One per worker thread. NOTE: cache-line aligned: side by side in a vector,
// one thread's counters (written every segment) shared a line with the other
// thread's buffer pointers (read every detection), and the line bounced
// between cores (perf: 64 % of the detection code's time on that load).
struct alignas(64) Accumulator {
  std::vector<DetectorSums> det;             // per detector
  std::vector<int64_t> aliveDiff;            // [bin + 1][band]: difference array of energy in flight
  int64_t escaped[kNumBands] = {};
  std::vector<int64_t> pathEnergy, pathRetained;  // [free-path bin][band]
  std::vector<int64_t> probeAliveDiff;       // as aliveDiff, tail probes past their cut
  int64_t probeCut[kNumBands] = {};
  uint64_t raysEscaped = 0, segments = 0, raysCut = 0, rouletted = 0, probeSegments = 0;
};

// A rotation matrix from a random unit quaternion (Shoemake 1992).
struct Rotation {
  double m[3][3];
  Vec3d apply(const Vec3d& v) const {
    return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z, m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
  }
};

Rotation randomRotation(uint64_t seed) {
  Pcg32 rng(seed, 0xF1B0'5EEDULL);
  double u1 = rng.uniformDouble(), u2 = rng.uniformDouble(), u3 = rng.uniformDouble();
  double a = std::sqrt(1 - u1), b = std::sqrt(u1);
  double w = a * std::sin(2 * kPi * u2), x = a * std::cos(2 * kPi * u2);
  double y = b * std::sin(2 * kPi * u3), z = b * std::cos(2 * kPi * u3);
  Rotation r;
  r.m[0][0] = 1 - 2 * (y * y + z * z); r.m[0][1] = 2 * (x * y - w * z);     r.m[0][2] = 2 * (x * z + w * y);
  r.m[1][0] = 2 * (x * y + w * z);     r.m[1][1] = 1 - 2 * (x * x + z * z); r.m[1][2] = 2 * (y * z - w * x);
  r.m[2][0] = 2 * (x * z - w * y);     r.m[2][1] = 2 * (y * z + w * x);     r.m[2][2] = 1 - 2 * (x * x + y * y);
  return r;
}

constexpr uint32_t kConvergenceRounds = 16;

// r's bits reversed within log2(n) bits (n a power of two).
uint32_t bitReverse(uint32_t r, uint32_t n) {
  uint32_t out = 0;
  for (uint32_t bit = 1; bit < n; bit <<= 1) out = (out << 1) | ((r & bit) ? 1u : 0u);
  return out;
}

// The late histogram's error, estimated from the spread of the rounds: each
// round is an independent estimate of the same histogram (its rays spread
// over the whole sphere), so over m rounds the relative standard error of
// their mean in a window is sd / (mean sqrt(m)). Windows of 10 ms, within
// 20 dB of the band's strongest window; the error is the worst window's, in
// dB (10 log10(1 + relative error)). Fixed-point sums: exact, so the
// estimate does not depend on the thread count.
class ConvergenceMonitor {
 public:
  ConvergenceMonitor(size_t bins, double binSeconds, uint32_t rounds)
      : mBins(bins), mPerWindow(std::max<size_t>(1, size_t(std::lround(0.01 / binSeconds)))),
        mPrevious(bins * kNumBands, 0) {
    mRounds.reserve(rounds);
  }
  void addRound(const std::vector<const std::vector<int64_t>*>& hists) {
    const size_t windows = (mBins + mPerWindow - 1) / mPerWindow;
    std::vector<double> round(windows * kNumBands, 0.0);
    for (size_t i = 0; i < mBins; ++i)
      for (int b = 0; b < kNumBands; ++b) {
        int64_t now = 0;
        for (const auto* h : hists) addSat(now, (*h)[i * EnergyHistogram::kStride + b]);
        round[(i / mPerWindow) * kNumBands + b] += double(now - mPrevious[i * kNumBands + b]);
        mPrevious[i * kNumBands + b] = now;
      }
    mRounds.push_back(std::move(round));
  }
  double errorDb() const {
    const size_t m = mRounds.size();
    if (m < 4) return 1e9;  // too few rounds to estimate a spread
    const size_t cells = mRounds[0].size();
    double worst = 0;
    for (int b = 0; b < kNumBands; ++b) {
      double peak = 0;
      std::vector<double> mean(cells / kNumBands, 0.0);
      for (size_t w = 0; w < mean.size(); ++w) {
        for (const auto& r : mRounds) mean[w] += r[w * kNumBands + size_t(b)] / double(m);
        peak = std::max(peak, mean[w]);
      }
      for (size_t w = 0; w < mean.size(); ++w) {
        if (!(mean[w] > 1e-2 * peak)) continue;
        double var = 0;
        for (const auto& r : mRounds) var += std::pow(r[w * kNumBands + size_t(b)] - mean[w], 2);
        var /= double(m - 1);
        worst = std::max(worst, std::sqrt(var / double(m)) / mean[w]);
      }
    }
    return 10.0 * std::log10(1.0 + worst);
  }

 private:
  size_t mBins, mPerWindow;
  std::vector<int64_t> mPrevious;           // [bin][band]: the totals after the last round
  std::vector<std::vector<double>> mRounds;  // per round: [window][band] energy (fixed-point units)
};

// Automatic receiver radius, sized from the ray density. An image source at
// distance d sends N r^2 / (4 d^2) of N rays through a sphere of radius r;
// the sparsest specular detections the trace makes are those of its highest
// order, d ~ bounces x the free path seen from the listener (the mean
// distance to the surfaces over 64 directions). The radius gives them
// kHitsPerImage expected rays: r = 2 d sqrt(kHitsPerImage / N). Too small a
// sphere makes the specular detections shot noise (at 16384 rays a fixed
// 0.5 m gave T30 -1.4 .. -0.2 JND over seeds in a specular box at alpha
// 0.6; sized, within 0.15), too large smears arrival times (by r / c).
// Sized so, the hits per image stay the same whatever the ray count: it
// never shrinks below 0.5 m, so that more rays do lower the noise. At most
// 2 m, and under 90 % of the distance to the nearest surface (a sphere cut
// by a wall would under-count), at least 1 cm.
constexpr double kHitsPerImage = 3.0;
// Tail probes are detected by the sphere only when it is at least this big
// (the automatic radius's floor); otherwise tail completion falls back to
// kappa x their energy in flight.
constexpr double kMinProbeSphere = 0.5;
constexpr uint32_t kUndetectedProbes = 4096;
// Probe thinning (with roulette only): from kProbeThinFrom of its start
// energy on, and again every kProbeThinStep further, a probe goes on with
// probability 1/2 and twice the energy (unbiased). Where a probe's share of
// the tail is small, fewer of them: the multiband box's 16-seed errors are
// unchanged to 0.01 JND and its trace 83 -> 43 ms; from 10 dB down the
// converged T20s' RMS error grew from 0.30 to 0.48 JND.
constexpr float kProbeThinFrom = 1e-2f;  // 20 dB down
constexpr float kProbeThinStep = 0.1f;   // then every 10 dB
double autoReceiverRadius(const RayTracer& tracer, const Vec3d& listener, uint32_t rays, uint32_t bounces) {
  double nearest = 1e30, sum = 0;
  uint32_t hits = 0;
  const uint32_t probes = 64;
  for (uint32_t i = 0; i < probes; ++i) {
    Ray ray{listener, 0.0f, Vec3f(fibonacciDirection(i, probes)), 1e30f};
    Hit hit;
    if (tracer.intersect(ray, hit)) {
      nearest = std::min(nearest, double(hit.t));
      sum += hit.t;
      ++hits;
    }
  }
  const double freePath = hits > 0 ? sum / hits : 1.0;
  const double sized = 2.0 * std::max(1u, bounces) * freePath * std::sqrt(kHitsPerImage / double(std::max(1u, rays)));
  return std::max(0.01, std::min(std::clamp(sized, 0.5, 2.0), 0.9 * nearest));
}

// Flutter axes: normals of pairs of parallel planes that both reflect
// specularly, between which a flutter echo lives. A specular room's late
// decay rides on the few rays that leave the source close to the slowest
// such axis, and uniform directions sample them by luck (tests/regression:
// the multiband box). A pair counts when each plane has at least
// kFlutterMinAreaShare of the scene's area, they are at least
// kFlutterMinSeparation apart, and a round trip keeps at least
// kFlutterMinRetained specularly in some band ((1 - alpha)(1 - s) of one
// times the other's, area-weighted over each plane's triangles). Its decay
// per metre is the least over bands of -ln(kept) / (2 x separation); the
// slowest axis is taken, and another only if within kFlutterRateSpread of
// it (at most kMaxFlutterAxes).
constexpr double kFlutterMinAreaShare = 0.02;
constexpr double kFlutterMinSeparation = 0.5;  // metres
constexpr double kFlutterMinRetained = 0.25;
constexpr double kFlutterRateSpread = 1.25;
constexpr size_t kMaxFlutterAxes = 2;

std::vector<Vec3d> findFlutterAxes(const RayTracer& tracer, const MaterialTable& materials) {
  const PlaneSet& ps = tracer.planes();
  const TriangleMesh& mesh = tracer.mesh();
  std::vector<double> area(ps.planes.size(), 0.0);
  std::vector<BandArrayD> specular(ps.planes.size(), BandArrayD{});
  double totalArea = 0;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    const uint32_t plane = ps.triangleToPlane[t];
    if (plane == PlaneSet::kNoPlane) continue;
    const Vec3d a(mesh.positions[mesh.triangles[t][0]]), b(mesh.positions[mesh.triangles[t][1]]),
        c(mesh.positions[mesh.triangles[t][2]]);
    const double ta = 0.5 * length(cross(b - a, c - a));
    const Material& m = materials[mesh.materialIds[t]];
    for (int band = 0; band < kNumBands; ++band)
      specular[plane][band] += ta * std::clamp(1.0 - double(m.absorption[band]), 0.0, 1.0) *
                               std::clamp(1.0 - double(m.scattering[band]), 0.0, 1.0);
    area[plane] += ta;
    totalArea += ta;
  }
  std::vector<uint32_t> large;
  for (uint32_t p = 0; p < ps.planes.size(); ++p)
    if (area[p] >= kFlutterMinAreaShare * totalArea && area[p] > 0) {
      for (double& r : specular[p]) r /= area[p];
      large.push_back(p);
    }
  std::vector<std::pair<double, Vec3d>> axes;  // (decay per metre, normal)
  for (size_t i = 0; i < large.size(); ++i)
    for (size_t j = i + 1; j < large.size(); ++j) {
      const Plane& a = ps.planes[large[i]];
      const Plane& b = ps.planes[large[j]];
      const double d = dot(a.normal, b.normal);
      if (std::fabs(d) < 1.0 - 1e-6) continue;
      const double separation = std::fabs(a.offset - (d > 0 ? b.offset : -b.offset));
      if (separation < kFlutterMinSeparation) continue;
      double kept = 0;
      for (int band = 0; band < kNumBands; ++band)
        kept = std::max(kept, specular[large[i]][band] * specular[large[j]][band]);
      if (kept < kFlutterMinRetained) continue;
      const double rate = -std::log(std::min(kept, 1.0 - 1e-12)) / (2.0 * separation);
      bool merged = false;
      for (auto& [r, n] : axes)
        if (std::fabs(dot(n, a.normal)) > 1.0 - 1e-6) {
          r = std::min(r, rate);
          merged = true;
        }
      if (!merged) axes.emplace_back(rate, a.normal);
    }
  std::stable_sort(axes.begin(), axes.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<Vec3d> out;
  for (size_t i = 0; i < axes.size() && i < kMaxFlutterAxes; ++i)
    if (axes[i].first <= kFlutterRateSpread * axes[0].first) out.push_back(axes[i].second);
  return out;
}

// Initial directions: a Fibonacci sphere (rotated per seed) for most rays,
// and, with flutter axes, kFlutterConeShare of the rays on Fibonacci caps
// around +n and -n of each axis, two nested ones per direction (half-angles
// kFlutterConeHalfAngles: the wide cap holds paths that stay within a room's
// width over ~50 m, the narrow one those of the late flutter, ~0.5 - 2 s
// out), each cap rotated per seed about its axis. Every ray carries
// 1 / (the density of all the sets at its direction, rays per steradian):
// the balance heuristic of multiple importance sampling (Veach & Guibas
// 1995), so every integral over directions stays unbiased and the energies
// still sum to 4 pi. Without axes every ray carries 4 pi / N, as before.
// Measured on the multiband box, 16 seeds at the default budget, against
// the exact energies: RMS error of T30 at 4 kHz 3.3 -> 0.9 JND, of the
// converged T20s 2.2 -> 1.1, of EDT over 250 Hz - 4 kHz 0.81 -> 0.56.
constexpr double kFlutterConeShare = 0.125;
constexpr double kFlutterConeHalfAngles[] = {0.15, 0.03};  // radians
constexpr uint32_t kMinRaysForFlutterCones = 1024;

class DirectionSampler {
 public:
  DirectionSampler(uint32_t rays, const Rotation& rot, const std::vector<Vec3d>& axes, uint64_t seed) : mRot(rot) {
    const uint32_t coneRays = axes.empty() ? 0u : uint32_t(double(rays) * kFlutterConeShare);
    mUniform = rays - coneRays;
    Pcg32 rng(seed, 0xF1077E2ULL);
    for (const Vec3d& a : axes)
      for (double sign : {1.0, -1.0})
        for (double angle : kFlutterConeHalfAngles) {
          Cone c;
          c.axis = a * sign;
          const Vec3d helper = std::fabs(c.axis.x) < 0.9 ? Vec3d{1, 0, 0} : Vec3d{0, 1, 0};
          c.u = normalize(cross(c.axis, helper));
          c.v = cross(c.axis, c.u);
          c.spin = 2.0 * kPi * rng.uniformDouble();
          c.cosHalf = std::cos(angle);
          c.solidAngle = 2.0 * kPi * (1.0 - c.cosHalf);
          mCones.push_back(c);
        }
    const uint32_t cones = uint32_t(mCones.size());
    for (uint32_t k = 0; k < cones; ++k) mCones[k].rays = coneRays / cones + (k < coneRays % cones ? 1u : 0u);
  }
  uint32_t coneRays() const {
    uint32_t n = 0;
    for (const Cone& c : mCones) n += c.rays;
    return n;
  }
  /** Index of ray i within its set (the sphere, or its cone). */
  uint32_t ordinalInSet(uint32_t i) const { return i < mUniform ? i : (i - mUniform) / uint32_t(mCones.size()); }
  /** Direction of ray i (of `rays`) and the energy it carries. */
  void ray(uint32_t i, Vec3d& dir, double& energy) const {
    if (i < mUniform) {
      dir = mRot.apply(fibonacciDirection(i, mUniform));
    } else {
      const uint32_t j = i - mUniform, cones = uint32_t(mCones.size());
      const Cone& c = mCones[j % cones];
      const uint32_t m = j / cones;
      const double cosT = 1.0 - (1.0 - c.cosHalf) * (double(m) + 0.5) / double(c.rays);
      const double sinT = std::sqrt(std::max(0.0, 1.0 - cosT * cosT));
      const double phi = c.spin + kPi * (3.0 - std::sqrt(5.0)) * double(m);
      dir = c.axis * cosT + (c.u * std::cos(phi) + c.v * std::sin(phi)) * sinT;
    }
    double density = double(mUniform) / (4.0 * kPi);
    for (const Cone& c : mCones)
      if (dot(dir, c.axis) >= c.cosHalf) density += double(c.rays) / c.solidAngle;
    energy = 1.0 / density;
  }

 private:
  struct Cone {
    Vec3d axis, u, v;
    double spin = 0, cosHalf = 1, solidAngle = 0;
    uint32_t rays = 0;
  };
  Rotation mRot;
  uint32_t mUniform = 0;
  std::vector<Cone> mCones;
};

}  // namespace

// The bit pattern of a positive float grows monotonically and piecewise
// linearly in log2: exponent and 6 mantissa bits give 64 bins per octave.
size_t freePathBin(double length) {
  const float l = float(std::max(length, 1.0 / 1024.0));
  uint32_t bits;
  std::memcpy(&bits, &l, sizeof bits);
  constexpr uint32_t kFirst = 117u << 23;  // 2^-10 m
  return std::min<size_t>(kFreePathBins - 1, (bits - kFirst) >> 17);
}

double freePathBinCenter(size_t bin) {
  // Octave bin / 64 above 2^-10, at the middle of the bin's mantissa range.
  const double octave = double(bin / 64), fraction = (double(bin % 64) + 0.5) / 64.0;
  return std::ldexp(1.0 + fraction, int(octave) - 10);
}

Vec3d fibonacciDirection(uint32_t i, uint32_t n) {
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  double z = 1.0 - (2.0 * i + 1.0) / n;
  double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  double phi = golden * i;
  return {r * std::cos(phi), r * std::sin(phi), z};
}

Status validate(const ReflectionSettings& s) {
  if (s.rays < 1 || s.rays > 100000000u) return invalidArgument("rays " + std::to_string(s.rays) + " is outside [1, 1e8]");
  if (s.bounces > 100000u) return invalidArgument("bounces " + std::to_string(s.bounces) + " is outside [0, 100000]");
  if (!(s.speedOfSound >= 1.0 && s.speedOfSound <= 1e5))
    return invalidArgument("speed of sound " + std::to_string(s.speedOfSound) + " m/s is outside [1, 1e5]");
  if (!(s.binSeconds >= 1e-5 && s.binSeconds <= 0.1))
    return invalidArgument("histogram bin " + std::to_string(s.binSeconds) + " s is outside [1e-5, 0.1]");
  if (!(s.maxTimeSeconds > 0 && s.maxTimeSeconds <= 600.0))
    return invalidArgument("histogram length " + std::to_string(s.maxTimeSeconds) + " s is outside (0, 600]");
  if (s.maxTimeSeconds / s.binSeconds > 5e7) return invalidArgument("histogram of over 5e7 bins requested");
  if (!(s.receiverRadiusMeters >= 0 && s.receiverRadiusMeters <= 1e3))
    return invalidArgument("receiver radius " + std::to_string(s.receiverRadiusMeters) + " m is outside [0, 1000]");
  if (!(s.convergenceDb >= 0 && s.convergenceDb <= 20))
    return invalidArgument("convergence target " + std::to_string(s.convergenceDb) + " dB is outside [0, 20]");
  if (!(s.sharedShadowRoulette >= 0 && s.sharedShadowRoulette <= 1e6))
    return invalidArgument("shared shadow-ray roulette " + std::to_string(s.sharedShadowRoulette) +
                           " is outside [0, 1e6]");
  if (!(s.minDistanceMeters > 0 && s.minDistanceMeters <= 10))
    return invalidArgument("minimum distance " + std::to_string(s.minDistanceMeters) + " m is outside (0, 10]");
  return validate(s.air);
}

const RayTail& TailData::rays() const {
  static const RayTail kNone;
  return shared ? *shared : kNone;
}

double traceMemoryBytes(const ReflectionSettings& s, size_t detectors, unsigned threads) {
  const double nd = double(std::max<size_t>(1, detectors)), sums = double(std::max(1u, threads)) + 1.0;
  const double bins = std::ceil(s.maxTimeSeconds / s.binSeconds) + 1.0;
  // traceCore's per-ray slots (cutRays, wasCut, probeEnds, probeEnded), and
  // the results' RayTail (one for all): at most a cut and a probe's end per
  // ray.
  const double perRay = 2.0 * (double(sizeof(CutRay)) + 1.0) + 2.0 * double(sizeof(CutRay));
  // Each thread's Accumulator and the merged one: every detector's hist and
  // probeHist, the in-flight diffs (aliveDiff, probeAliveDiff); each
  // result's histogram (doubles) and probeDetected curve, and the RayTail's
  // alive and probeAlive curves.
  const double perBin =
      sums * (nd * double(EnergyHistogram::kStride + kNumBands) + 2.0 * kNumBands) * double(sizeof(int64_t)) +
      nd * (double(EnergyHistogram::kStride) * sizeof(double) + double(sizeof(BandArrayD))) +
      2.0 * double(sizeof(BandArrayD));
  return double(s.rays) * perRay + bins * perBin;
}

namespace {

// A trace's state against the memory limit, before any of it is allocated.
Status checkTraceMemory(const ReflectionSettings& s, size_t detectors, unsigned threads) {
  return checkMemoryEstimate(traceMemoryBytes(s, detectors, threads),
                             "a trace of " + std::to_string(s.rays) + " rays and " +
                                 std::to_string(size_t(std::ceil(s.maxTimeSeconds / s.binSeconds))) +
                                 " histogram bins" +
                                 (detectors > 1 ? " for " + std::to_string(detectors) + " sources" : std::string()) +
                                 " on " + std::to_string(threads) + " threads");
}

// What a trace's paths depend on besides the detectors (SharedTracePaths).
struct PathKey {
  uint64_t tracer = 0;
  Vec3d emitter{};
  std::vector<float> materials;  // each material's reflect, transmit and scatter factors
  BandArrayD air{};              // energy attenuation per metre
  uint32_t rays = 0, bounces = 0, tailProbes = 0;
  uint64_t seed = 0;
  double speedOfSound = 0, binSeconds = 0, maxTimeSeconds = 0, shadowRoulette = 0;
  bool russianRoulette = false, flutterCones = false;
  bool operator==(const PathKey& o) const {
    return tracer == o.tracer && emitter.x == o.emitter.x && emitter.y == o.emitter.y && emitter.z == o.emitter.z &&
           materials == o.materials && air == o.air && rays == o.rays && bounces == o.bounces &&
           tailProbes == o.tailProbes && seed == o.seed && speedOfSound == o.speedOfSound &&
           binSeconds == o.binSeconds && maxTimeSeconds == o.maxTimeSeconds && shadowRoulette == o.shadowRoulette &&
           russianRoulette == o.russianRoulette && flutterCones == o.flutterCones;
  }
};

}  // namespace

struct SharedTracePaths::Impl {
  size_t budget = kSharedTracePathsBudgetBytes;
  bool valid = false;
  PathKey key;
  std::vector<PathEvents> tasks;  // per task of the trace
  ReflectionStats stats;          // the trace's counts (what every detector shares)
  std::shared_ptr<const RayTail> tail;  // the listener's rays' tail data
  size_t bytes = 0;
  uint64_t generation = 0;
  void clear() {
    ++generation;
    valid = false;
    tasks = {};
    tail.reset();
    bytes = 0;
  }
};

SharedTracePaths::SharedTracePaths() : mImpl(std::make_unique<Impl>()) {}
SharedTracePaths::SharedTracePaths(size_t budgetBytes) : mImpl(std::make_unique<Impl>()) { mImpl->budget = budgetBytes; }
SharedTracePaths::~SharedTracePaths() = default;
size_t SharedTracePaths::bytes() const { return mImpl->bytes; }
uint64_t SharedTracePaths::generation() const { return mImpl->generation; }
void SharedTracePaths::clear() { mImpl->clear(); }

namespace {

// The trace behind traceReflections (one detector, the listener; rays from
// the source) and traceReflectionsShared (rays from the listener, a
// detector per source: reciprocity). `reciprocal`: each detection's arrival
// direction at the listener is its ray's first direction, and the
// detector's directivity weighs what it detects. Inputs validated by the
// callers; one result per detector.
std::vector<ReflectionResult> traceCore(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& emitter,
                                        std::vector<Detector> detectors, bool reciprocal,
                                        const ReflectionSettings& settings, ThreadPool& pool,
                                        SharedTracePaths::Impl* paths = nullptr) {
  const auto start = std::chrono::steady_clock::now();
  const size_t bins = size_t(std::ceil(settings.maxTimeSeconds / settings.binSeconds));
  const uint32_t maxOrder = settings.bounces;
  const size_t nd = detectors.size();
  std::vector<ReflectionResult> results(nd);
  for (ReflectionResult& result : results) {
    result.histogram = EnergyHistogram(settings.binSeconds, bins);
    result.stats.detectedPerOrder.assign(maxOrder + 1, BandArrayD{});
    result.stats.raysTraced = settings.rays;
  }
  if (tracer.empty() || settings.bounces == 0) return results;  // nothing to reflect from

  bool anyProbeDetector = false;
  for (size_t r = 0; r < nd; ++r) {
    Detector& dt = detectors[r];
    const double R = dt.radius > 0 ? dt.radius : autoReceiverRadius(tracer, dt.position, settings.rays, settings.bounces);
    dt.radius = R;
    results[r].stats.receiverRadiusMeters = R;
    dt.probesDetected = R >= kMinProbeSphere;
    anyProbeDetector |= dt.probesDetected;
    dt.sphereR2 = float(R * R);
    dt.invSphereVolume = float(1.0 / (4.0 / 3.0 * kPi * R * R * R));
    // A convex room around the detector blocks no path from its surface to
    // it: next-event estimation needs no occlusion test.
    dt.shadowsNeeded = !tracer.convexAround(dt.position);
    // The roulette saves shadow rays: none where none are needed.
    dt.neeRouletteR2 = reciprocal && dt.shadowsNeeded ? float(settings.sharedShadowRoulette * R * R) : 0.0f;
    dt.directional = reciprocal && !dt.directivity.isOmni();
    dt.meanSquares = dt.directivity.meanSquares();
  }
  const DetectorLanes lanes(detectors);
  const size_t lanesWidth = lanes.width();
  // One detector (a trace from a source): the scalar tests alone, which
  // the lanes only select for (with them, a trace from a source in the
  // shoebox took 119 ms instead of 111, 1 thread).
  const bool oneDetector = nd == 1;
  const float invC = float(1.0 / settings.speedOfSound);
  const float invBin = float(1.0 / settings.binSeconds);
  const float minD2 = float(settings.minDistanceMeters * settings.minDistanceMeters);
  const float eps = tracer.surfaceEpsilon();
  // Paths longer than the histogram covers are counted as late whatever their air.
  const AirTable air(airEnergyAttenuationPerMeter(settings.air), settings.maxTimeSeconds * settings.speedOfSound);
  const Rotation rot = randomRotation(mix64(settings.seed));

  // Per-material factors, precomputed.
  struct MatFactors {
    float reflect[kNumBands], transmit[kNumBands], scatter[kNumBands];
    float meanReflect, meanTransmit;
  };
  std::vector<MatFactors> mats(materials.size());
  for (size_t i = 0; i < materials.size(); ++i) {
    const Material& m = materials[uint32_t(i)];
    MatFactors& f = mats[i];
    f.meanReflect = f.meanTransmit = 0;
    for (int b = 0; b < kNumBands; ++b) {
      f.reflect[b] = std::clamp(1.0f - m.absorption[b], 0.0f, 1.0f);
      f.transmit[b] = std::clamp(std::min(m.transmission[b], m.absorption[b]), 0.0f, 1.0f);
      f.scatter[b] = std::clamp(m.scattering[b], 0.0f, 1.0f);
      f.meanReflect += f.reflect[b] / kNumBands;
      f.meanTransmit += f.transmit[b] / kNumBands;
    }
  }

  // Kept paths (SharedTracePaths): replayed when they were traced with the
  // same scene, emitter and settings, else traced and recorded.
  PathKey key;
  if (paths) {
    key.tracer = tracer.id();
    key.emitter = emitter;
    for (const MatFactors& f : mats) {
      key.materials.insert(key.materials.end(), f.reflect, f.reflect + kNumBands);
      key.materials.insert(key.materials.end(), f.transmit, f.transmit + kNumBands);
      key.materials.insert(key.materials.end(), f.scatter, f.scatter + kNumBands);
    }
    key.air = airEnergyAttenuationPerMeter(settings.air);
    key.rays = settings.rays;
    key.bounces = settings.bounces;
    key.tailProbes = settings.tailProbes;
    key.seed = settings.seed;
    key.speedOfSound = settings.speedOfSound;
    key.binSeconds = settings.binSeconds;
    key.maxTimeSeconds = settings.maxTimeSeconds;
    key.shadowRoulette = settings.sharedShadowRoulette;
    key.russianRoulette = settings.russianRoulette;
    key.flutterCones = settings.flutterCones;
  }
  const bool replay = paths && paths->valid && paths->key == key && reciprocal &&
                     paths->tasks.size() == (settings.rays + kRaysPerTask - 1) / kRaysPerTask;
  const bool record = paths && !replay;
  if (record) paths->clear();
  std::vector<PathEvents> recorded;
  std::atomic<size_t> recordedBytes{0};
  std::atomic<bool> overBudget{false};
  // Paths are kept within their budget and within what the memory limit
  // leaves beside the trace's own state (traceMemoryBytes).
  const double keepable = double(defaultInputLimits().maxMemoryBytes) - traceMemoryBytes(settings, nd, pool.threadCount());
  const size_t keepBudget = paths ? size_t(std::clamp(keepable, 0.0, double(paths->budget))) : 0;

  // Flutter cones need the whole trace: the convergence rounds compare
  // subsets that must each cover the sphere alike.
  const std::vector<Vec3d> flutterAxes = !replay && settings.flutterCones && settings.convergenceDb == 0 &&
                                                 settings.rays >= kMinRaysForFlutterCones
                                             ? findFlutterAxes(tracer, materials)
                                             : std::vector<Vec3d>{};
  const DirectionSampler sampler(settings.rays, rot, flutterAxes, settings.seed);

  // The rays' own data (cut rays, probes' ends, energy in flight, free
  // paths): not made again from kept paths (they are kept with them).
  const uint32_t raySlots = replay ? 0u : settings.rays;
  std::vector<CutRay> cutRays(raySlots);  // slot per ray: deterministic
  std::vector<uint8_t> wasCut(raySlots, 0);
  // Tail probes: every probeStride-th ray of each direction set (so every
  // cone has its share); a slot per ray for where a probe ended.
  // Undetected probes (a sphere too small) give only the shape of the energy
  // in flight, a smooth sum: kUndetectedProbes of them do (the default up
  // to b20d7e4); more would cost time for nothing (in the two-room sample,
  // 3.7 million probe segments against 0.93 million). A shared trace keeps
  // every probe whatever its sources' spheres, so that what a source gets
  // does not depend on which others share the trace.
  const uint32_t probes = anyProbeDetector || reciprocal ? settings.tailProbes
                                                         : std::min(settings.tailProbes, kUndetectedProbes);
  const uint32_t probeStride = probes > 0 ? std::max(1u, settings.rays / probes) : 0;
  const uint32_t probeSlots = probeStride > 0 ? raySlots : 0;
  std::vector<CutRay> probeEnds(probeSlots);
  std::vector<uint8_t> probeEnded(probeSlots, 0);
  std::vector<Accumulator> acc(pool.threadCount());
  for (auto& a : acc) {
    a.det.resize(nd);
    for (size_t r = 0; r < nd; ++r) {
      a.det[r].hist.assign(bins * EnergyHistogram::kStride, 0);
      a.det[r].perOrder.assign(size_t(maxOrder + 1) * kNumBands, 0);
      if (probeStride > 0 && detectors[r].probesDetected) a.det[r].probeHist.assign(bins * kNumBands, 0);
    }
    if (replay) continue;
    a.aliveDiff.assign((bins + 1) * kNumBands, 0);
    a.pathEnergy.assign(kFreePathBins * kNumBands, 0);
    a.pathRetained.assign(kFreePathBins * kNumBands, 0);
    if (probeStride > 0) a.probeAliveDiff.assign((bins + 1) * kNumBands, 0);
  }
  const uint32_t lossFromOrder = std::max(1u, maxOrder / 2);  // the later half of the bounces
  constexpr float kSurvival = 0.1f;

  auto binOf = [&](float pathLength) { return std::min(bins, size_t(pathLength * invC * invBin)); };
#if defined(EARSHOT_FIXED_AVX)
  const bool avx = __builtin_cpu_supports("avx");  // toFixedBatch's four at a time
#else
  const bool avx = false;
#endif
  auto deposit = [&](DetectorSums& a, PendingAdds& pending, float pathLength, const float* energy, float weight,
                     const Vec3f& doa, uint32_t order) {
    const size_t bin = size_t(pathLength * invC * invBin);
    if (bin >= bins) {
      for (int b = 0; b < kNumBands; ++b) addSat(a.late[b], toFixed(double(energy[b]) * weight));
      return;
    }
    float f[kNumBands];
    air.factors(pathLength, f);
    // The bands' energies, then their mean along the direction.
    double v[kFixedBatch] = {};
    double mean = 0;
    for (int b = 0; b < kNumBands; ++b) {
      v[b] = double(energy[b]) * weight * f[b];
      mean += v[b];
    }
    mean *= 1.0 / kNumBands;
    v[kNumBands] = mean * doa.x;
    v[kNumBands + 1] = mean * doa.y;
    v[kNumBands + 2] = mean * doa.z;
    int64_t q[kFixedBatch];
    toFixedBatch(v, q, avx);
    pending.addRun(&a.hist[bin * EnergyHistogram::kStride], q, kNumBands + 3);
    int64_t* po = &a.perOrder[size_t(order) * kNumBands];
    for (int b = 0; b < kNumBands; ++b) addSat(po[b], q[b]);
  };
  // A tail probe's detection (no direction, no order): kept apart, for tail completion.
  auto depositProbe = [&](DetectorSums& a, PendingAdds& pending, float pathLength, const float* energy,
                          float weight) {
    const size_t bin = size_t(pathLength * invC * invBin);
    if (bin >= bins) return;
    float f[kNumBands];
    air.factors(pathLength, f);
    double v[kFixedBatch] = {};
    for (int b = 0; b < kNumBands; ++b) v[b] = double(energy[b]) * weight * f[b];
    int64_t q[kFixedBatch];
    toFixedBatch(v, q, avx);
    pending.addRun(&a.probeHist[bin * kNumBands], q, kNumBands);
  };
  // A detection by detector r. `away` is the direction from the detector
  // toward the event: forward, where the sound arrives from; in a shared
  // trace, where it left the source for (its directivity's argument), and
  // it arrives at the listener from the ray's first direction `first`.
  auto detect = [&](DetectorSums& a, PendingAdds& pending, const Detector& dt, float pathLength, const float* energy,
                    float weight, const Vec3f& away, const Vec3f& first, uint32_t order, bool probe) {
    const float* e = energy;
    float weighted[kNumBands];
    if (dt.directional) {
      const BandArrayD d = dt.directivity.energyFactors(Vec3d(away), dt.meanSquares);
      for (int b = 0; b < kNumBands; ++b) weighted[b] = float(double(energy[b]) * d[size_t(b)]);
      e = weighted;
    }
    ++a.detections;
    a.probeDetections += probe;
    if (probe)
      depositProbe(a, pending, pathLength, e, weight);
    else
      deposit(a, pending, pathLength, e, weight, reciprocal ? first : away, order);
  };
  // A purely specular path the image sources rendered. The planes are in
  // the ray's order: from the source forward, from the listener in a shared
  // trace (the image sources' sequences run from the source).
  auto excludedPath = [&](const Detector& dt, const PlaneSequence& planes, uint32_t order) {
    if (!reciprocal) return dt.excluded->count(planes) > 0;
    PlaneSequence reversed;
    reversed.fill(0xFFFFFFFFu);
    const uint32_t n = std::min<uint32_t>(order, kMaxImageSourceOrder);
    for (uint32_t k = 0; k < n; ++k) reversed[k] = planes[n - 1 - k];
    return dt.excluded->count(reversed) > 0;
  };
  // Energy in flight over [from, to) bins, without air: every ray in flight
  // at time t has travelled c t, so the air of the bin's centre applies to
  // all of them alike (integrate, below).
  auto alive = [&](std::vector<int64_t>& diff, float fromLength, float toLength, const float* energy) {
    const size_t b0 = binOf(fromLength), b1 = binOf(toLength);
    if (b0 >= b1) return;
    for (int b = 0; b < kNumBands; ++b) {
      const int64_t q = toFixed(double(energy[b]));
      addSat(diff[b0 * kNumBands + b], q);
      addSat(diff[b1 * kNumBands + b], -q);
    }
  };

  // Detection: what each detector makes of a ray's recorded events.
  struct NeeCandidate {
    uint32_t detector, shadowIndex;
    Vec3f toL;
    float d, d2, cosL, gain;
  };
  // Per task: a candidate and a shadow ray per detector, the held adds.
  struct DetectScratch {
    explicit DetectScratch(size_t n)
        : nee(n), shadowRays(n), blocked(n), pending(n == 1), rouletted((n + 7) / 8 * 8, 0u) {}
    std::vector<NeeCandidate> nee;
    std::vector<Ray> shadowRays;
    std::vector<uint8_t> blocked;
    PendingAdds pending;
    // Shadow rays rouletted away, per detector, counted a lane group at a
    // time (most of 32 sources lose at most reflections: one increment per
    // detector and reflection was a third of the reflections' detection).
    std::vector<uint32_t> rouletted;
    void flush(Accumulator& a) {
      pending.flush();
      for (size_t r = 0; r < a.det.size(); ++r) {
        a.det[r].shadowsRouletted += rouletted[r];
        rouletted[r] = 0;
      }
    }
  };
  // A segment through the spheres: a specular (or transmitted) path, or a
  // tail probe past its cut, detected by the sphere alone (no next-event
  // estimation: unbiased for specular and diffuse paths alike, and no
  // shadow rays), not by a sphere squeezed below kMinProbeSphere by a
  // nearby surface (too few hits). `planes`: its specular planes so far
  // (a purely specular path), else null.
  auto detectSegmentEvent = [&](const SegmentEvent& e, const PlaneSequence* planes, Accumulator& a,
                                DetectScratch& x) {
    const bool probing = e.probing;
    if (probing && !anyProbeDetector) return;
    for (size_t g = 0; g < lanes.groups(); ++g) {
      for (uint32_t bits = oneDetector ? 1u : lanes.crossedAny(g, e.origin, e.direction, e.length, probing);
           bits != 0; bits &= bits - 1) {
        const size_t r = g * lanesWidth + size_t(__builtin_ctz(bits));
        const Detector& dt = detectors[r];
        if (probing && !dt.probesDetected) continue;
        // Chord of this segment through the receiver sphere.
        const Vec3f oc(e.origin - dt.position);
        const float bq = dot(oc, e.direction);
        const float disc = bq * bq - (dot(oc, oc) - dt.sphereR2);
        if (!(disc > 0)) continue;
        const float root = std::sqrt(disc);
        const float t0 = std::max(0.0f, -bq - root), t1 = std::min(e.length, -bq + root);
        if (!(t1 > t0)) continue;
        DetectorSums& ds = a.det[r];
        if (planes && e.order <= dt.excludedMaxOrder && dt.excluded && excludedPath(dt, *planes, e.order)) {
          ++ds.excluded;
        } else {
          const float tc = std::clamp(-bq, t0, t1);
          detect(ds, x.pending, dt, e.pathLength + tc, e.energy, (t1 - t0) * dt.invSphereVolume, -e.direction,
                 e.first, e.order, probing);
        }
      }
    }
  };
  // Next-event estimation of a reflection's diffuse part: the detectors
  // facing it; their shadow rays go to Embree together (one stream call
  // per hit point; RayTracer::occludedMany).
  auto detectReflectionEvent = [&](const ReflectionEvent& e, Accumulator& a, DetectScratch& x) {
    size_t facing = 0;
    uint32_t shadowCount = 0;
    for (size_t g = 0; g < lanes.groups(); ++g) {
      uint32_t send = 1, lost = 0;
      if (!oneDetector) lanes.facingAny(g, e.p, e.n, e.u, minD2, send, lost);
      addLaneCounts(&x.rouletted[g * lanesWidth], lost, lanesWidth);
      for (; send != 0; send &= send - 1) {
        const size_t r = g * lanesWidth + size_t(__builtin_ctz(send));
        const Detector& dt = detectors[r];
        const Vec3f toL(dt.position - e.p);
        const float d2 = dot(toL, toL);
        const float cosL = dot(e.n, toL);
        if (!(cosL > 0)) continue;
        const float d = std::sqrt(d2);
        float gain = 1.0f;
        if (dt.neeRouletteR2 > 0) {
          const float pSend = dt.neeRouletteR2 * (cosL / d) / std::max(d2, minD2);
          if (pSend < 1.0f) {
            if (!(e.u < pSend)) {
              ++a.det[r].shadowsRouletted;
              continue;
            }
            gain = 1.0f / pSend;
          }
        }
        NeeCandidate& c = x.nee[facing++];
        c.detector = uint32_t(r);
        c.toL = toL;
        c.d = d;
        c.d2 = d2;
        c.cosL = cosL;
        c.gain = gain;
        if (dt.shadowsNeeded) {
          // Field by field: built whole (Ray{...}), the compiler wrote it
          // to the stack in floats and copied it in 16-byte loads, which
          // waited for those stores (perf: 15 % of this function's samples;
          // gone from the profile now, the time within the machine's noise).
          Ray& shadow = x.shadowRays[c.shadowIndex = shadowCount++];
          shadow.origin = e.shadowOrigin;
          shadow.tNear = 0.0f;
          shadow.direction = toL / d;
          shadow.tFar = d - eps;
        } else {
          c.shadowIndex = ~0u;
        }
      }
    }
    if (shadowCount == 1) {
      const Ray& shadow = x.shadowRays[0];
      x.blocked[0] = shadow.tFar > 0 && tracer.occluded(shadow);
    } else if (shadowCount > 1) {
      tracer.occludedMany(x.shadowRays.data(), shadowCount, x.blocked.data());
      for (uint32_t k = 0; k < shadowCount; ++k) x.blocked[k] &= x.shadowRays[k].tFar > 0;
    }
    for (size_t k = 0; k < facing; ++k) {
      const NeeCandidate& c = x.nee[k];
      const Detector& dt = detectors[c.detector];
      DetectorSums& ds = a.det[c.detector];
      bool visible = true;
      if (c.shadowIndex != ~0u) {
        ++ds.shadows;
        visible = !x.blocked[c.shadowIndex];
      } else {
        ++ds.shadowsSkipped;
      }
      if (visible) {
        const float w = c.gain * (c.cosL / c.d) / (float(kPi) * std::max(c.d2, minD2));
        detect(ds, x.pending, dt, e.pathLength + c.d, e.scattered, w, -c.toL / c.d, e.first, e.order + 1, false);
      }
    }
  };
  auto detectEvents = [&](const PathEvents& ev, size_t segmentsFrom, size_t reflectionsFrom, Accumulator& a,
                          DetectScratch& x) {
    for (size_t i = segmentsFrom; i < ev.segments.size(); ++i) {
      const SegmentEvent& e = ev.segments[i];
      detectSegmentEvent(e, e.planes != ~0u ? &ev.planes[e.planes] : nullptr, a, x);
    }
    for (size_t i = reflectionsFrom; i < ev.reflections.size(); ++i) detectReflectionEvent(ev.reflections[i], a, x);
  };

  // Rays go in rounds: round r traces the rays whose index is congruent to
  // bitReverse(r) modulo the round count, so every round, and every prefix
  // of rounds, covers the sphere evenly. With a convergence target the
  // trace stops after the round where the late histogram's estimated error
  // falls below it. The decision depends on completed rounds only: the
  // same whatever the thread count.
  const bool directional = !reciprocal && !settings.directivity.isOmni();
  const bool roulettedShadows = reciprocal && settings.sharedShadowRoulette > 0;
  const BandArrayD directivityMeanSquares = settings.directivity.meanSquares();
  const uint32_t rounds = !reciprocal && settings.convergenceDb > 0 ? std::min(kConvergenceRounds, settings.rays) : 1u;
  uint32_t traced = 0;
  double estimatedErrorDb = 0;
  ConvergenceMonitor monitor(bins, settings.binSeconds, rounds);
  for (uint32_t round = 0; round < rounds; ++round) {
    const uint32_t residue = rounds == 1 ? 0u : bitReverse(round, rounds);
    const uint32_t count = residue < settings.rays ? (settings.rays - residue + rounds - 1) / rounds : 0u;
    const uint32_t tasks = (count + kRaysPerTask - 1) / kRaysPerTask;
    if (record) recorded.resize(tasks);  // a shared trace: one round
    pool.parallelFor(tasks, [&](size_t task, unsigned worker) {
      Accumulator& a = acc[worker];
      DetectScratch scratch(nd);
      // The task's events: kept paths replayed, or recorded for keeping. A
      // trace that keeps none detects as it goes and stores nothing.
      PathEvents none;
      PathEvents& ev = replay ? paths->tasks[task] : record ? recorded[task] : none;
      if (replay) {
        detectEvents(ev, 0, 0, a, scratch);
        scratch.flush(a);
        return;
      }
      const uint32_t first = uint32_t(task) * kRaysPerTask;
      const uint32_t last = std::min(count, first + kRaysPerTask);
      for (uint32_t k = first; k < last; ++k) {
        const size_t segmentsBefore = ev.segments.size(), reflectionsBefore = ev.reflections.size(),
                     planesBefore = ev.planes.size();
        const uint32_t rayIndex = residue + k * rounds;
        Pcg32 rng(settings.seed, rayIndex);
        // The shared trace's shadow-ray roulette draws from a stream of its
        // own: the ray's path is the same with or without it.
        Pcg32 neeRng(settings.seed ^ 0x6e65652d726f756cULL, rayIndex);
        Vec3d direction;
        double startEnergy;
        sampler.ray(rayIndex, direction, startEnergy);
        const float rouletteThreshold = float(startEnergy) * 1e-6f;  // 60 dB down
        float thinBelow = float(startEnergy) * kProbeThinFrom, probeWeight = 1.0f;
        // The source's directivity weights what the ray carries (the
        // thresholds stay the omni ray's: a ray sent backwards by a
        // cardioid carries little and ends soon).
        float energy[kNumBands];
        if (directional) {
          const BandArrayD d = settings.directivity.energyFactors(direction, directivityMeanSquares);
          for (int b = 0; b < kNumBands; ++b) energy[b] = float(startEnergy * d[size_t(b)]);
        } else {
          for (float& e : energy) e = float(startEnergy);
        }
        // Positions (ray origins, hit points) in double world coordinates: in
        // float they are ~8 mm apart at 1e5 m, and a hit point near an edge
        // could round to beyond the neighbouring wall. Directions and
        // distances stay float.
        Ray ray{emitter, 0.0f, Vec3f(direction), 1e30f};
        const Vec3f first(direction);
        float pathLength = 0;
        bool detectSegment = false;  // last event specular/transmission after a reflection
        bool reflected = false;
        bool pureSpecular = true;    // every event so far a specular reflection
        const bool isProbe = probeStride > 0 && sampler.ordinalInSet(rayIndex) % probeStride == 0;
        bool probing = false;        // a tail probe past the bounce limit: sphere detections into probeHist only
        PlaneSequence planes;
        planes.fill(0xFFFFFFFFu);
        for (uint32_t order = 0;; ++order) {
          Hit hit;
          ++a.segments;
          a.probeSegments += probing;
          const bool hasHit = tracer.intersect(ray, hit);
          const float segment = hasHit ? hit.t : 1e30f;
          // Tail probes are detected on every segment past their cut, by the
          // sphere alone (no next-event estimation): unbiased for specular
          // and diffuse paths alike, and no shadow rays; not by a sphere
          // squeezed below kMinProbeSphere by a nearby surface (too few hits).
          // Detected now, or recorded and detected as the ray ends (a tail
          // probe's segments too when recorded: a later trace's sources
          // may detect probes; else only where a sphere does).
          if (probing ? record || anyProbeDetector : detectSegment) {
            SegmentEvent now;
            SegmentEvent& e = record ? ev.segments.emplace_back() : now;
            e.origin = ray.origin;
            e.direction = ray.direction;
            e.first = first;
            e.length = segment;
            e.pathLength = pathLength;
            std::copy(energy, energy + kNumBands, e.energy);
            e.order = order;
            e.probing = probing;
            e.planes = ~0u;
            const bool specularSoFar = !probing && pureSpecular;
            if (record && specularSoFar) {
              e.planes = uint32_t(ev.planes.size());
              ev.planes.push_back(planes);
            }
            if (!record) detectSegmentEvent(e, specularSoFar ? &planes : nullptr, a, scratch);
          }
          if (!hasHit) {
            if (probing) break;  // counted when it was cut
            ++a.raysEscaped;
            for (int b = 0; b < kNumBands; ++b) {
              addSat(a.escaped[b], toFixed(energy[b] / (4.0 * kPi)));
              if (order >= lossFromOrder) addSat(a.pathEnergy[(kFreePathBins - 1) * kNumBands + b], toFixed(energy[b]));
            }
            break;
          }
          alive(probing ? a.probeAliveDiff : a.aliveDiff, pathLength, pathLength + hit.t, energy);
          const MatFactors& m = mats[tracer.materialOf(hit.triangle)];
          if (order >= lossFromOrder && !probing) {
            const size_t fb = freePathBin(hit.t) * kNumBands;
            for (int b = 0; b < kNumBands; ++b) {
              addSat(a.pathEnergy[fb + b], toFixed(energy[b]));
              addSat(a.pathRetained[fb + b], toFixed(energy[b] * std::min(1.0f, m.reflect[b] + m.transmit[b])));
            }
          }
          pathLength += hit.t;
          if (order == maxOrder) {
            // Stopped by the bounce limit: what it would have carried on with.
            ++a.raysCut;
            CutRay& c = cutRays[rayIndex];
            wasCut[rayIndex] = 1;
            c.pathMeters = pathLength;
            for (int b = 0; b < kNumBands; ++b) c.energy[b] = energy[b] * std::min(1.0f, m.reflect[b] + m.transmit[b]);
            if (!isProbe) break;
            // A tail probe carries on, undetected, to measure the decay.
            probing = true;
            float f[kNumBands];
            air.factors(pathLength, f);
            for (int b = 0; b < kNumBands; ++b) addSat(a.probeCut[b], toFixed(double(c.energy[b]) * f[b]));
          } else if (probing && (order == maxOrder + kMaxProbeBounces || binOf(pathLength) >= bins)) {
            CutRay& c = probeEnds[rayIndex];
            probeEnded[rayIndex] = 1;
            c.pathMeters = pathLength;
            for (int b = 0; b < kNumBands; ++b) c.energy[b] = energy[b] * std::min(1.0f, m.reflect[b] + m.transmit[b]);
            break;
          }
          const Vec3d p = ray.origin + Vec3d(ray.direction) * double(hit.t);
          Vec3f n = hit.normal;
          if (dot(n, ray.direction) > 0) n = -n;  // face the incoming ray
          // Leaves the surface along n. Near an edge where the neighbour
          // meets this triangle at an acute angle (a corner of a room whose
          // walls lean), n * eps can cross the neighbour and start the next
          // ray outside: there the offset stops halfway to the neighbour.
          const bool nearEdge = std::min({hit.u, hit.v, 1.0f - hit.u - hit.v}) < kNearEdgeBarycentric;
          const Vec3d offset = nearEdge ? clearOffset(tracer, p, n, eps) : Vec3d(n * eps);

          // Next-event estimation of the diffusely reflected part.
          if (!probing) {
            float scattered[kNumBands];
            bool any = false;
            for (int b = 0; b < kNumBands; ++b) {
              scattered[b] = energy[b] * m.reflect[b] * m.scatter[b];
              any |= scattered[b] > 0;
            }
            // One number per reflection, whatever the sources: each source's
            // roulette depends on it and on the source alone.
            const float u = roulettedShadows ? neeRng.uniform() : 0.0f;
            if (any) {
              ReflectionEvent now;
              ReflectionEvent& e = record ? ev.reflections.emplace_back() : now;
              e.p = p;
              e.shadowOrigin = p + offset;
              e.n = n;
              e.first = first;
              e.pathLength = pathLength;
              std::copy(scattered, scattered + kNumBands, e.scattered);
              e.u = u;
              e.order = order;
              if (!record) detectReflectionEvent(e, a, scratch);
            }
          }

          // Continue: through the surface, specularly, or diffusely.
          const float pT = m.meanTransmit > 0 ? m.meanTransmit / (m.meanTransmit + m.meanReflect) : 0.0f;
          float maxEnergy = 0;
          if (pT > 0 && rng.uniform() < pT) {
            const float gain = 1.0f / pT;
            for (int b = 0; b < kNumBands; ++b) maxEnergy = std::max(maxEnergy, energy[b] *= m.transmit[b] * gain);
            ray.origin = p - (nearEdge ? clearOffset(tracer, p, -n, eps) : offset);  // direction unchanged
            detectSegment = reflected;
            pureSpecular = false;
          } else {
            float specW = 0, total = 0;
            const float gain = 1.0f / (1.0f - pT);
            for (int b = 0; b < kNumBands; ++b) {
              energy[b] *= m.reflect[b] * gain;
              specW += energy[b] * (1.0f - m.scatter[b]);
              total += energy[b];
            }
            const float pSpec = total > 0 ? specW / total : 0.0f;
            if (pSpec > 0 && rng.uniform() < pSpec) {
              const float specGain = 1.0f / pSpec;
              for (int b = 0; b < kNumBands; ++b)
                maxEnergy = std::max(maxEnergy, energy[b] *= (1.0f - m.scatter[b]) * specGain);
              ray.direction = normalize(ray.direction - n * (2.0f * dot(ray.direction, n)));
              detectSegment = true;
              if (order < kMaxImageSourceOrder) planes[order] = tracer.planeOf(hit.triangle);
            } else {
              const float diffuseGain = 1.0f / (1.0f - pSpec);
              for (int b = 0; b < kNumBands; ++b)
                maxEnergy = std::max(maxEnergy, energy[b] *= m.scatter[b] * diffuseGain);
              ray.direction = cosineDirection(n, rng);
              detectSegment = false;
              pureSpecular = false;
            }
            ray.origin = p + offset;
            reflected = true;
          }
          if (!(maxEnergy > 0)) break;
          if (probing && settings.russianRoulette && maxEnergy < thinBelow * probeWeight &&
              maxEnergy >= rouletteThreshold * probeWeight) {
            // Thinning (kProbeThinFrom): half the probes go on, with twice
            // the energy.
            thinBelow *= kProbeThinStep;
            if (rng.uniform() >= 0.5f) break;
            probeWeight *= 2.0f;
            for (float& e : energy) e *= 2.0f;
          }
          if (probing && settings.russianRoulette && maxEnergy < rouletteThreshold * probeWeight) {
            // A probe 60 dB down joins the virtual population here rather
            // than play roulette: its few survivors would make the measured
            // tail noisy where the population's rate serves as well.
            CutRay& c = probeEnds[rayIndex];
            probeEnded[rayIndex] = 1;
            c.pathMeters = pathLength;
            for (int b = 0; b < kNumBands; ++b) c.energy[b] = energy[b];
            break;
          }
          if (settings.russianRoulette && maxEnergy < rouletteThreshold) {
            if (rng.uniform() >= kSurvival) {
              ++a.rouletted;
              break;
            }
            for (float& e : energy) e /= kSurvival;
          }
        }
        if (record) {
          // The ray's recorded events, detected as it ends (still in the cache).
          detectEvents(ev, segmentsBefore, reflectionsBefore, a, scratch);
          if (!overBudget.load(std::memory_order_relaxed)) {
            const size_t added = (ev.segments.size() - segmentsBefore) * sizeof(SegmentEvent) +
                                 (ev.reflections.size() - reflectionsBefore) * sizeof(ReflectionEvent) +
                                 (ev.planes.size() - planesBefore) * sizeof(PlaneSequence);
            if (recordedBytes.fetch_add(added, std::memory_order_relaxed) + added > keepBudget)
              overBudget.store(true, std::memory_order_relaxed);
          }
          if (overBudget.load(std::memory_order_relaxed)) ev.clear();  // none will be kept
        }
      }
      scratch.flush(a);
    });
    traced += count;
    if (rounds > 1) {
      std::vector<const std::vector<int64_t>*> hists;
      for (const Accumulator& a : acc) hists.push_back(&a.det[0].hist);
      monitor.addRound(hists);
      estimatedErrorDb = monitor.errorDb();
      if (round + 1 < rounds && estimatedErrorDb <= settings.convergenceDb) break;
    }
  }
  // Energies were emitted as 4 pi / rays per ray: scale to the rays traced.
  const double unit = double(settings.rays) / double(traced) / kFixedScale;

  // Reduce in fixed point (exact, order-independent), then convert.
  Accumulator& total = acc[0];
  for (size_t w = 1; w < acc.size(); ++w) {
    for (size_t r = 0; r < nd; ++r) {
      DetectorSums& t = total.det[r];
      const DetectorSums& o = acc[w].det[r];
      for (size_t i = 0; i < t.hist.size(); ++i) addSat(t.hist[i], o.hist[i]);
      for (size_t i = 0; i < t.perOrder.size(); ++i) addSat(t.perOrder[i], o.perOrder[i]);
      for (size_t i = 0; i < t.probeHist.size(); ++i) addSat(t.probeHist[i], o.probeHist[i]);
      for (int b = 0; b < kNumBands; ++b) addSat(t.late[b], o.late[b]);
      t.shadows += o.shadows;
      t.shadowsSkipped += o.shadowsSkipped;
      t.shadowsRouletted += o.shadowsRouletted;
      t.excluded += o.excluded;
      t.detections += o.detections;
      t.probeDetections += o.probeDetections;
    }
    for (size_t i = 0; i < total.aliveDiff.size(); ++i) addSat(total.aliveDiff[i], acc[w].aliveDiff[i]);
    for (size_t i = 0; i < total.probeAliveDiff.size(); ++i) addSat(total.probeAliveDiff[i], acc[w].probeAliveDiff[i]);
    for (size_t i = 0; i < total.pathEnergy.size(); ++i) {
      addSat(total.pathEnergy[i], acc[w].pathEnergy[i]);
      addSat(total.pathRetained[i], acc[w].pathRetained[i]);
    }
    for (int b = 0; b < kNumBands; ++b) {
      addSat(total.escaped[b], acc[w].escaped[b]);
      addSat(total.probeCut[b], acc[w].probeCut[b]);
    }
    total.raysEscaped += acc[w].raysEscaped;
    total.segments += acc[w].segments;
    total.raysCut += acc[w].raysCut;
    total.rouletted += acc[w].rouletted;
    total.probeSegments += acc[w].probeSegments;
  }

  // What the detectors share: the rays' tail data and counts.
  ReflectionResult& shared = results[0];
  ReflectionStats& stats = shared.stats;
  std::shared_ptr<const RayTail> rayTail;
  if (replay) {
    const double radius = stats.receiverRadiusMeters;
    stats = paths->stats;
    stats.receiverRadiusMeters = radius;
    stats.pathsReused = true;
    rayTail = paths->tail;
  } else {
    auto made = std::make_shared<RayTail>();
    RayTail& tail = *made;
    stats.raysTraced = traced;
    stats.estimatedErrorDb = estimatedErrorDb;
    stats.flutterAxes = uint32_t(flutterAxes.size());
    stats.coneRays = sampler.coneRays();
    tail.cutRays.reserve(total.raysCut);
    const float rayScale = float(double(settings.rays) / double(traced));
    auto scaled = [&](CutRay c) {
      for (float& e : c.energy) e *= rayScale;
      return c;
    };
    for (uint32_t i = 0; i < settings.rays; ++i)
      if (wasCut[i]) tail.cutRays.push_back(scaled(cutRays[i]));
    auto integrate = [&](const std::vector<int64_t>& diff, std::vector<BandArrayD>& out) {
      out.assign(bins, BandArrayD{});
      int64_t running[kNumBands] = {};
      for (size_t i = 0; i < bins; ++i) {
        float f[kNumBands];
        air.factors(float((double(i) + 0.5) * settings.binSeconds * settings.speedOfSound), f);
        for (int b = 0; b < kNumBands; ++b) {
          addSat(running[b], diff[i * kNumBands + b]);
          out[i][b] = double(running[b]) * unit * f[b];
        }
      }
    };
    integrate(total.aliveDiff, tail.alive);
    if (probeStride > 0) {
      integrate(total.probeAliveDiff, tail.probeAlive);
      for (int b = 0; b < kNumBands; ++b) tail.probeCutEnergy[b] = double(total.probeCut[b]) * unit;
      for (uint32_t i = 0; i < probeSlots; ++i)
        if (probeEnded[i]) tail.probeEnds.push_back(scaled(probeEnds[i]));
    }
    for (int b = 0; b < kNumBands; ++b) stats.energyEscaped[b] = double(total.escaped[b]) * unit;
    tail.pathEnergy.assign(kFreePathBins, BandArrayD{});
    tail.pathRetained.assign(kFreePathBins, BandArrayD{});
    for (size_t i = 0; i < kFreePathBins; ++i)
      for (int b = 0; b < kNumBands; ++b) {
        tail.pathEnergy[i][b] = double(total.pathEnergy[i * kNumBands + b]) * unit;
        tail.pathRetained[i][b] = double(total.pathRetained[i * kNumBands + b]) * unit;
      }
    stats.raysEscaped = total.raysEscaped;
    stats.segmentsTraced = total.segments;
    stats.raysCut = total.raysCut;
    stats.raysRouletted = total.rouletted;
    stats.tailProbeSegments = total.probeSegments;
    if (record && !overBudget.load()) {
      paths->key = std::move(key);
      paths->tasks = std::move(recorded);
      for (PathEvents& e : paths->tasks) {  // without the vectors' growth slack
        e.segments.shrink_to_fit();
        e.reflections.shrink_to_fit();
        e.planes.shrink_to_fit();
      }
      paths->stats = stats;
      paths->tail = made;
      paths->bytes = sizeof(SharedTracePaths::Impl);
      for (const PathEvents& e : paths->tasks) paths->bytes += e.bytes();
      paths->valid = true;
    }
    rayTail = std::move(made);
  }
  stats.traceMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  // One RayTail for every detector: copies of it, one per source, were
  // fresh pages each (about 1 MB a source in the furnished room: for 32
  // sources 110-130 ms on one thread, about as long as their detection).
  for (size_t r = 0; r < nd; ++r) results[r].tail.shared = rayTail;
  // The counts (the first result's, `stats`) for the others, each with its own radius.
  for (size_t r = 1; r < nd; ++r) {
    const double radius = results[r].stats.receiverRadiusMeters;
    results[r].stats = stats;
    results[r].stats.receiverRadiusMeters = radius;
  }

  // Each detector's own: its histogram, per-order energies, probes' detections.
  for (size_t r = 0; r < nd; ++r) {
    const DetectorSums& t = total.det[r];
    ReflectionResult& result = results[r];
    auto& data = result.histogram.data();
    for (size_t i = 0; i < data.size(); ++i) data[i] = double(t.hist[i]) * unit;
    for (uint32_t o = 0; o <= maxOrder; ++o)
      for (int b = 0; b < kNumBands; ++b)
        result.stats.detectedPerOrder[o][b] = double(t.perOrder[size_t(o) * kNumBands + b]) * unit;
    if (probeStride > 0 && detectors[r].probesDetected) {
      result.tail.probeDetected.assign(bins, BandArrayD{});
      for (size_t i = 0; i < bins; ++i)
        for (int b = 0; b < kNumBands; ++b) result.tail.probeDetected[i][b] = double(t.probeHist[i * kNumBands + b]) * unit;
    }
    for (int b = 0; b < kNumBands; ++b) result.stats.energyLate[b] = double(t.late[b]) * unit;
    result.stats.shadowRays = t.shadows;
    result.stats.shadowRaysSkipped = t.shadowsSkipped;
    result.stats.shadowRaysRouletted = t.shadowsRouletted;
    result.stats.specularExcluded = t.excluded;
    result.stats.detections = t.detections;
    result.stats.probeDetections = t.probeDetections;
  }
  return results;
}

Status checkMaterials(const RayTracer& tracer, const MaterialTable& materials) {
  for (uint32_t id : tracer.mesh().materialIds)
    if (id >= materials.size())
      return invalidArgument("material id " + std::to_string(id) + " is beyond the " + std::to_string(materials.size()) +
                             " materials");
  return Status::ok();
}

}  // namespace

Result<ReflectionResult> traceReflections(const RayTracer& tracer, const MaterialTable& materials, const Vec3d& source,
                                          const Vec3d& listener, const ReflectionSettings& settings, ThreadPool& pool) {
  EARSHOT_RETURN_IF_ERROR(validate(settings));
  if (!isFinite(source) || !isFinite(listener)) return invalidArgument("source or listener position is not finite");
  EARSHOT_RETURN_IF_ERROR(checkMaterials(tracer, materials));
  EARSHOT_RETURN_IF_ERROR(checkTraceMemory(settings, 1, pool.threadCount()));
  Detector d;
  d.position = listener;
  d.radius = settings.receiverRadiusMeters;
  d.excluded = settings.excludedSpecular;
  d.excludedMaxOrder = settings.excludedMaxOrder;
  auto results = traceCore(tracer, materials, source, {d}, false, settings, pool);
  return std::move(results[0]);
}

Result<std::vector<ReflectionResult>> traceReflectionsShared(const RayTracer& tracer, const MaterialTable& materials,
                                                             const Vec3d& listener,
                                                             const std::vector<SharedTraceSource>& sources,
                                                             const ReflectionSettings& settings, ThreadPool& pool,
                                                             SharedTracePaths* paths) {
  EARSHOT_RETURN_IF_ERROR(validate(settings));
  if (!isFinite(listener)) return invalidArgument("listener position is not finite");
  if (sources.size() > kMaxSharedTraceSources)
    return invalidArgument(std::to_string(sources.size()) + " sources in one shared trace, over " +
                           std::to_string(kMaxSharedTraceSources));
  const double bins = std::ceil(settings.maxTimeSeconds / settings.binSeconds);
  if (double(sources.size()) * bins > 5e7)
    return invalidArgument("a shared trace of " + std::to_string(sources.size()) + " sources x " +
                           std::to_string(size_t(bins)) + " histogram bins is over 5e7 bins");
  EARSHOT_RETURN_IF_ERROR(checkMaterials(tracer, materials));
  if (!sources.empty()) EARSHOT_RETURN_IF_ERROR(checkTraceMemory(settings, sources.size(), pool.threadCount()));
  std::vector<Detector> detectors;
  for (size_t i = 0; i < sources.size(); ++i) {
    const SharedTraceSource& s = sources[i];
    if (!isFinite(s.position)) return invalidArgument("source " + std::to_string(i) + ": position is not finite");
    if (!(s.receiverRadiusMeters >= 0 && s.receiverRadiusMeters <= 1e3))
      return invalidArgument("source " + std::to_string(i) + ": receiver radius " +
                             std::to_string(s.receiverRadiusMeters) + " m is outside [0, 1000]");
    EARSHOT_RETURN_IF_ERROR(validate(s.directivity));
    Detector d;
    d.position = s.position;
    d.radius = s.receiverRadiusMeters;
    d.excluded = s.excludedSpecular;
    d.excludedMaxOrder = s.excludedMaxOrder;
    d.directivity = s.directivity;
    detectors.push_back(d);
  }
  if (detectors.empty()) return std::vector<ReflectionResult>{};
  ReflectionSettings rs = settings;
  rs.convergenceDb = 0;  // one trace serves every source: every ray is traced
  rs.directivity = Directivity{};
  return traceCore(tracer, materials, listener, std::move(detectors), true, rs, pool, paths ? &paths->impl() : nullptr);
}

}  // namespace earshot
