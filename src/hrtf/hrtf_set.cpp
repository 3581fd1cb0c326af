// HrtfSet: SOFA loading (libmysofa), onset separation, resampling, and
// interpolated lookup.
//
// Interpolation: barycentric weights on the spherical Delaunay triangulation
// of the measured directions, computed as in vector-base amplitude panning:
// for a direction d inside the cone of triangle (a, b, c), the weights solve
// d = wa a + wb b + wc c and are normalised to sum 1 (V. Pulkki, "Virtual sound
// source positioning using vector base amplitude panning", JAES 45(6), 1997;
// the same scheme is used for HRTF interpolation by e.g. Gamper, "Head-related
// transfer function interpolation in azimuth, elevation, and distance", JASA
// 134(6), 2013). Minimum-phase HRIRs and onset delays are interpolated separately
// (onset/ITD separation, see hrir_dsp.cpp), which avoids comb filtering.
//
// Holes in the measurement grid (e.g. MIT KEMAR has nothing below -40 degrees
// elevation) are spanned by the large hull triangles across the hole, so a
// direction in the hole is interpolated from the rim measurements. Hull
// triangles whose plane passes within 1e-3 of the centre (a set covering only
// a hemisphere) are dropped; directions they would cover use the nearest
// measurement (clamping).
//
// Acceleration: a cube map of 6 x 24 x 24 cells; each cell lists the triangles
// whose bounding cap overlaps the cell's bounding cap, so a lookup tests a few
// candidates instead of thousands.
//
// Load time: per-measurement preparation (onsets, resampling, minimum phase)
// runs on up to kMaxLoadThreads threads (measurements are independent; same
// results for any thread count) while this thread builds the lookup
// structures. libmysofa's reading of the file is the largest part left: about
// 0.15 s of the KU100's 0.36 s of CPU time on the 2-core machines here.
#include "earshot/hrtf/hrtf_set.h"

#include "earshot/io/input_file.h"

#include <mysofa.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <thread>
#include <vector>

extern char** environ;

#include "earshot/core/math.h"
#include "earshot/hrtf/coordinates.h"
#include "earshot/core/random.h"
#include "earshot/io/disk_cache.h"
#include "hrir_dsp.h"
#include "install_layout.h"
#include "sofa_probe_status.h"
#include "sphere_triangulation.h"

namespace earshot::hrtf {

namespace {

constexpr int kGridN = 24;
// Gaussian weight (e^-1 point) on the onset cross-correlation: with the KU100
// set, 2 kHz keeps the largest ITD step of a 1-degree horizontal sweep at
// ~12 us (4 kHz: 31 us, no weight: 55 us, from contralateral outliers).
constexpr double kOnsetLowpassHz = 2000.0;
// Load: measurements per grab of a preparing thread, and at most this many threads.
constexpr std::size_t kLoadBlock = 32;
constexpr std::size_t kMaxLoadThreads = 4;

const char* mysofaErrorName(int err) {
  switch (err) {
    case MYSOFA_OK: return "ok";
    case MYSOFA_INTERNAL_ERROR: return "internal error";
    case MYSOFA_INVALID_FORMAT: return "invalid format (not HDF5/netCDF-4)";
    case MYSOFA_UNSUPPORTED_FORMAT: return "unsupported format";
    case MYSOFA_NO_MEMORY: return "out of memory";
    case MYSOFA_READ_ERROR: return "read error";
    case MYSOFA_INVALID_ATTRIBUTES: return "invalid attributes";
    case MYSOFA_INVALID_DIMENSIONS: return "invalid dimensions";
    case MYSOFA_INVALID_DIMENSION_LIST: return "invalid dimension list";
    case MYSOFA_INVALID_COORDINATE_TYPE: return "invalid coordinate type";
    case MYSOFA_ONLY_EMITTER_WITH_ECI_SUPPORTED: return "only emitters with ECI dimensions supported";
    case MYSOFA_ONLY_DELAYS_WITH_IR_OR_MR_SUPPORTED: return "only delays with IR or MR dimensions supported";
    case MYSOFA_ONLY_THE_SAME_SAMPLING_RATE_SUPPORTED: return "only one sampling rate supported";
    case MYSOFA_RECEIVERS_WITH_RCI_SUPPORTED: return "only receivers with RCI dimensions supported";
    case MYSOFA_RECEIVERS_WITH_CARTESIAN_SUPPORTED: return "only cartesian receiver positions supported";
    case MYSOFA_INVALID_RECEIVER_POSITIONS: return "invalid receiver positions";
    case MYSOFA_ONLY_SOURCES_WITH_MC_SUPPORTED: return "only source positions with MC dimensions supported";
    default: return "unknown error";
  }
}

Status notReadable(const std::string& path, int err) {
  return parseError(path + ": not a readable SOFA file (libmysofa: " + mysofaErrorName(err) + ")");
}

struct SofaDeleter {
  void operator()(MYSOFA_HRTF* h) const { mysofa_free(h); }
};

std::string attribute(MYSOFA_ATTRIBUTE* list, const char* name) {
  char* v = mysofa_getAttribute(list, const_cast<char*>(name));
  return v ? std::string(v) : std::string();
}

// Cube-map cell of a unit (or any non-zero) vector.
int cubeCell(double x, double y, double z) {
  double c[3] = {x, y, z};
  double ax = std::fabs(x), ay = std::fabs(y), az = std::fabs(z);
  int axis = ax >= ay && ax >= az ? 0 : (ay >= az ? 1 : 2);
  double m = std::fabs(c[axis]);
  int face = axis * 2 + (c[axis] < 0 ? 1 : 0);
  double u = c[(axis + 1) % 3] / m, v = c[(axis + 2) % 3] / m;
  int i = std::clamp(int((u + 1.0) * 0.5 * kGridN), 0, kGridN - 1);
  int j = std::clamp(int((v + 1.0) * 0.5 * kGridN), 0, kGridN - 1);
  return (face * kGridN + j) * kGridN + i;
}

Vec3d cubePoint(int face, double u, double v) {
  int axis = face / 2;
  double s = (face % 2) ? -1.0 : 1.0;
  double c[3];
  c[axis] = s;
  c[(axis + 1) % 3] = u;
  c[(axis + 2) % 3] = v;
  return normalize(Vec3d{c[0], c[1], c[2]});
}

double angleBetween(const Vec3d& a, const Vec3d& b) {
  return std::acos(std::clamp(dot(a, b), -1.0, 1.0));
}

// A cube-map cell's centre direction and angular radius (the largest angle
// from the centre to a corner).
std::pair<Vec3d, double> gridCell(int face, int i, int j, int n) {
  const double u0 = -1.0 + 2.0 * i / n, u1 = -1.0 + 2.0 * (i + 1) / n;
  const double v0 = -1.0 + 2.0 * j / n, v1 = -1.0 + 2.0 * (j + 1) / n;
  const Vec3d centre = cubePoint(face, 0.5 * (u0 + u1), 0.5 * (v0 + v1));
  const double r = std::max({angleBetween(centre, cubePoint(face, u0, v0)), angleBetween(centre, cubePoint(face, u1, v0)),
                             angleBetween(centre, cubePoint(face, u0, v1)), angleBetween(centre, cubePoint(face, u1, v1))});
  return {centre, r};
}

// Cube-map cells in blocks of kBlockN x kBlockN, for a coarse pass that
// rules out whole blocks before the per-cell tests (same per-cell results,
// a sixteenth of the tests).
constexpr int kBlockN = 4;
static_assert(kGridN % kBlockN == 0, "blocks tile the cube-map faces");

struct CellCap {
  Vec3d centre;
  double radius;
  int index;  // cell index, (face * kGridN + j) * kGridN + i
};

struct CellBlock {
  Vec3d centre;
  double radius;  // every point of every cell lies within this angle of centre
  std::vector<CellCap> cells;
};

std::vector<CellBlock> cellBlocks() {
  std::vector<CellBlock> blocks;
  const int perFace = kGridN / kBlockN;
  for (int face = 0; face < 6; ++face) {
    for (int bj = 0; bj < perFace; ++bj) {
      for (int bi = 0; bi < perFace; ++bi) {
        CellBlock b;
        b.centre = cubePoint(face, -1.0 + 2.0 * (bi + 0.5) / perFace, -1.0 + 2.0 * (bj + 0.5) / perFace);
        b.radius = 0.0;
        for (int j = bj * kBlockN; j < (bj + 1) * kBlockN; ++j) {
          for (int i = bi * kBlockN; i < (bi + 1) * kBlockN; ++i) {
            const auto [centre, r] = gridCell(face, i, j, kGridN);
            b.cells.push_back({centre, r, (face * kGridN + j) * kGridN + i});
            b.radius = std::max(b.radius, angleBetween(b.centre, centre) + r);
          }
        }
        blocks.push_back(std::move(b));
      }
    }
  }
  return blocks;
}

/** Seconds libmysofa may take to read a file in the probe. */
constexpr int kSofaProbeSeconds = 10;

/** libmysofa (an HDF5 reader in C) hangs on some malformed files and may
 *  allocate what a header claims; it offers no time-out or limit. So
 *  earshot-sofa-probe (tools/sofa_probe), a separate small program started
 *  with posix_spawn, reads the file first under an address-space limit of
 *  `maxBytes` and a deadline of kSofaProbeSeconds; only a file it read and
 *  validated in time is read in this process. A hang, a crash or an
 *  allocation failure there is a refused file here, never a hung or dead
 *  host. (A fork without exec would be cheaper but is not safe in a
 *  multi-threaded host: CI saw the child of a process running Embree's
 *  threads stall for 10 s.) Without the program (not installed, or
 *  $EARSHOT_SOFA_PROBE wrong) or when the host reaps children itself, the
 *  file is read directly, as the dimension checks in load() still guard
 *  memory. */
Status probeSofaFile(const std::string& path, uint64_t maxBytes) {
  const std::string probe = detail::sofaProbePath();
  if (probe.empty()) return Status::ok();
  posix_spawn_file_actions_t actions;
  if (posix_spawn_file_actions_init(&actions) != 0) return Status::ok();
  for (int fd : {0, 1, 2}) posix_spawn_file_actions_addopen(&actions, fd, "/dev/null", fd == 0 ? O_RDONLY : O_WRONLY, 0);
  const std::string bytes = std::to_string(maxBytes);
  std::vector<char> arg0(probe.begin(), probe.end()), arg1(path.begin(), path.end()), arg2(bytes.begin(), bytes.end());
  arg0.push_back('\0');
  arg1.push_back('\0');
  arg2.push_back('\0');
  char* argv[] = {arg0.data(), arg1.data(), arg2.data(), nullptr};
  pid_t pid = -1;
  const int spawned = posix_spawn(&pid, probe.c_str(), &actions, nullptr, argv, environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) return Status::ok();  // cannot probe: read it directly
  const timespec step{0, 2 * 1000 * 1000};
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(kSofaProbeSeconds);
  int status = 0;
  for (;;) {
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) break;
    if (r < 0 && errno != EINTR) return Status::ok();  // reaped elsewhere: read it directly
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      }
      return parseError(path + ": not a usable SOFA file (libmysofa did not finish reading it within " +
                        std::to_string(kSofaProbeSeconds) + " s)");
    }
    ::nanosleep(&step, nullptr);
  }
  if (WIFEXITED(status) && WEXITSTATUS(status) <= 1) return Status::ok();  // 1: this process reports the error
  if (WIFEXITED(status) && WEXITSTATUS(status) == 3)
    return outOfRange(path + ": reading it takes more than the memory limit of " + formatBytes(maxBytes) +
                      " (--max-memory)");
  if (WIFEXITED(status) && WEXITSTATUS(status) == 2) return Status::ok();  // a probe of another version
  // mysofa_load failed: reported as reading it here would, without reading
  // it again (libmysofa can leak on the way out of a failed read).
  const int loadError = WIFEXITED(status) ? detail::loadErrorForProbeStatus(WEXITSTATUS(status)) : MYSOFA_OK;
  if (loadError != MYSOFA_OK) return notReadable(path, loadError);
  return parseError(path + ": not a usable SOFA file (libmysofa failed reading it: " +
                    (WIFSIGNALED(status) ? "signal " + std::to_string(WTERMSIG(status)) : std::string("out of memory")) +
                    ")");
}

// One measurement's preparation, both ears: the onsets at the file's rate,
// then resampling to the engine's and minimum phase. Resampling keeps
// margins that hold the whole interpolation kernel (its tails before tap 0
// and after the last tap), so the minimum-phase version, which moves that
// energy to the front, loses none of it. Scratch for one thread.
class MeasurementPreparer {
 public:
  MeasurementPreparer(std::size_t n, double fsIn, double rate)
      : mN(n), mFsIn(fsIn), mRate(rate), mLength(std::size_t(std::ceil(double(n) * rate / fsIn))),
        mMargin(std::size_t(std::ceil(detail::SincKernel::kZeroCrossings / std::min(1.0, 0.95 * rate / fsIn) *
                                      rate / fsIn))),
        mPadded(mLength + 2 * mMargin),
        mEstimator(n, std::min(kOnsetLowpassHz, 0.25 * fsIn) / fsIn),
        mMinPhase(mPadded),
        mResampled(2 * mPadded, 0.0f) {}
  /** HRIR taps per ear at the engine's rate. */
  std::size_t length() const { return mLength; }
  /** left: n taps, the right ear's n after them; taps: 2 x length() (left,
   *  right); onsets: 2, in samples at the file's rate. */
  void run(const float* left, float* taps, double* onsets) {
    mEstimator.onsetPair(left, left + mN, &onsets[0], &onsets[1]);
    for (std::size_t ear = 0; ear < 2; ++ear) {
      const float* ir = left + ear * mN;
      float* out = mResampled.data() + ear * mPadded;
      if (mFsIn == mRate) {
        // resampleShifted at equal rates and a whole-sample shift copies
        // exactly (the kernel is 1 at 0 and 0 at the other integers).
        std::copy(ir, ir + mN, out + mMargin);
      } else {
        detail::resampleShifted(ir, mN, mFsIn, mRate, -double(mMargin) * mFsIn / mRate, out, mPadded);
      }
    }
    mMinPhase.computePair(mResampled.data(), mResampled.data() + mPadded, taps, taps + mLength, mLength);
  }

 private:
  std::size_t mN;
  double mFsIn, mRate;
  std::size_t mLength, mMargin, mPadded;
  detail::OnsetEstimator mEstimator;
  detail::MinimumPhase mMinPhase;
  std::vector<float> mResampled;  // left, right
};

// Changes with anything in load() that the fingerprint below does not see
// (how delays are made from onsets, what is kept): a cached set of another
// version is then prepared again. 2: Data.Delay checked (a set cached
// before may hold delays from values now refused).
constexpr uint64_t kPreparationVersion = 2;

// The prepared-set cache's guard against stale numerics: a hash of what
// MeasurementPreparer makes of a fixed test pair at this rate, from this
// rate and from another (the resampling path). Any change to the onset
// estimate, resampling or minimum phase changes it.
uint64_t preparationFingerprint(double rate) {
  constexpr std::size_t kN = 64;
  std::vector<float> pair(2 * kN, 0.0f);
  Pcg32 rng(kPreparationVersion, 0x50F4);
  for (std::size_t i = 0; i < kN; ++i) {
    const float decay = float(std::exp(-double(i) / 8.0));
    pair[i] = (i >= 10 ? decay : 0.0f) * float(rng.uniformDouble() - 0.5);
    pair[kN + i] = (i >= 14 ? decay : 0.0f) * float(rng.uniformDouble() - 0.5);
  }
  pair[10] = 1.0f;
  pair[kN + 14] = 0.7f;
  std::vector<double> out;
  for (double fsIn : {rate, rate == 44100.0 ? 48000.0 : 44100.0}) {
    MeasurementPreparer preparer(kN, fsIn, rate);
    std::vector<float> taps(2 * preparer.length());
    double onsets[2];
    preparer.run(pair.data(), taps.data(), onsets);
    out.insert(out.end(), taps.begin(), taps.end());
    out.insert(out.end(), onsets, onsets + 2);
  }
  return hashBytes(out.data(), out.size() * sizeof(double), kPreparationVersion).a;
}

// Slack (radians) of the coarse tests over the per-cell ones: covers their
// 1e-6 margins on cosines (at most 1.5e-3 rad) and rounding.
constexpr double kCoarseMargin = 1e-2;

}  // namespace

Result<std::shared_ptr<const HrtfSet>> HrtfSet::load(const std::string& sofaPath, double sampleRateHz,
                                                      InterpolationMode mode) {
  if (!(sampleRateHz >= 8000.0 && sampleRateHz <= 192000.0)) {
    return invalidArgument(sofaPath + ": engine sample rate " + std::to_string(sampleRateHz) +
                           " Hz is outside [8000, 192000]");
  }
  const InputLimits limits = defaultInputLimits();
  auto size = checkInputFile(sofaPath, "HRTF file", limits.maxMemoryBytes);
  if (!size) return size.status();
  // The set earshot ships and installs is trusted (and loaded by every
  // context that names none): only other files pay the probe (~0.18 s for
  // the 2354-direction KU100 set, median of `earshot ir` runs).
  bool shipped = false;
  if (auto def = defaultHrtfPath(); def.isOk()) {
    std::error_code e1, e2;
    shipped = std::filesystem::equivalent(sofaPath, *def, e1) && !e1 && !e2;
  }
  // The prepared-set cache (see the header): a hit skips libmysofa, the
  // probe and the preparation; these bytes were prepared before.
  const std::string folder = cacheFolder();
  CacheKey cacheKey{};
  std::string cacheName;
  if (!folder.empty()) {
    auto bytes = readInputFile(sofaPath, "HRTF file", limits.maxMemoryBytes);
    if (!bytes) return bytes.status();
    const Hash128 h = hashBytes(bytes->data(), bytes->size());
    cacheKey = {h.a, h.b, uint64_t(bytes->size()), preparationFingerprint(sampleRateHz)};
    cacheName = cacheFileName(cacheKey, sampleRateHz, mode);
    auto cached = readPrepared(folder + "/" + cacheName, cacheKey, sampleRateHz, mode, limits.maxMemoryBytes);
    // The shipped set's prepared form that earshot builds and installs (at
    // 44.1 and 48 kHz, the default interpolation), read like an entry of
    // the cache: a first run on a machine need not prepare it.
    if (!cached && shipped) {
      const std::string file = detail::shippedPreparedFile(cacheName);
      if (!file.empty()) cached = readPrepared(file, cacheKey, sampleRateHz, mode, limits.maxMemoryBytes);
    }
    if (cached) {
      cached->mPath = sofaPath;
      cached->buildNearestGrid();
      if (mode == InterpolationMode::kBarycentric) cached->buildTriangulation();
      return std::shared_ptr<const HrtfSet>(std::move(cached));
    }
  }
  if (!shipped) EARSHOT_RETURN_IF_ERROR(probeSofaFile(sofaPath, limits.maxMemoryBytes));
  int err = 0;
  std::unique_ptr<MYSOFA_HRTF, SofaDeleter> raw(mysofa_load(sofaPath.c_str(), &err));
  if (!raw) {
    return notReadable(sofaPath, err);
  }
  MYSOFA_HRTF* h = raw.get();
  // Dimensions against each other before anything reads by them (libmysofa
  // takes them from the file; mysofa_check and the conversions below trust them).
  if (h->M == 0 || h->N == 0 || h->R == 0 || h->M > (1u << 20) || h->N > (1u << 20) || h->R > 64)
    return parseError(sofaPath + ": implausible dimensions (M = " + std::to_string(h->M) + ", R = " +
                      std::to_string(h->R) + ", N = " + std::to_string(h->N) + ")");
  if (h->SourcePosition.elements != 3u * h->M || !h->SourcePosition.values)
    return parseError(sofaPath + ": SourcePosition has " + std::to_string(h->SourcePosition.elements) +
                      " values, expected M x 3 = " + std::to_string(3u * h->M));
  if (h->ReceiverPosition.elements < 3u * h->R || !h->ReceiverPosition.values)
    return parseError(sofaPath + ": ReceiverPosition has " + std::to_string(h->ReceiverPosition.elements) +
                      " values, expected R x 3 = " + std::to_string(3u * h->R));
  if (uint64_t(h->DataIR.elements) != uint64_t(h->M) * h->R * h->N || !h->DataIR.values)
    return parseError(sofaPath + ": Data.IR has " + std::to_string(h->DataIR.elements) +
                      " values, expected M x R x N = " + std::to_string(uint64_t(h->M) * h->R * h->N));
  if (h->DataDelay.elements != 0 && !h->DataDelay.values)
    return parseError(sofaPath + ": Data.Delay has no values");
  if (!h->DataSamplingRate.values) return parseError(sofaPath + ": Data.SamplingRate has no values");
  std::string conventions = attribute(h->attributes, "Conventions");
  if (conventions != "SOFA") {
    return parseError(sofaPath + ": attribute Conventions is " + quotedName(conventions) + ", expected \"SOFA\"");
  }
  std::string sofaConventions = attribute(h->attributes, "SOFAConventions");
  if (sofaConventions != "SimpleFreeFieldHRIR") {
    return unsupported(sofaPath + ": SOFA convention " + quotedName(sofaConventions) +
                       " is not supported (expected SimpleFreeFieldHRIR)");
  }
  std::string dataType = attribute(h->attributes, "DataType");
  if (dataType != "FIR") {
    return unsupported(sofaPath + ": DataType " + quotedName(dataType) + " is not supported (expected FIR)");
  }
  if (h->R != 2) {
    return unsupported(sofaPath + ": has " + std::to_string(h->R) + " receivers, expected 2 (left and right ear)");
  }
  if (h->M == 0 || h->N == 0) {
    return parseError(sofaPath + ": no measurements (M = " + std::to_string(h->M) +
                      ", N = " + std::to_string(h->N) + ")");
  }
  if (h->DataSamplingRate.elements < 1 || !(h->DataSamplingRate.values[0] > 0.0f)) {
    return parseError(sofaPath + ": Data.SamplingRate is missing or not positive");
  }
  // A measured rate lies far inside [kMinFileRateHz, kMaxFileRateHz] (HRTF
  // sets are measured at 44.1-192 kHz); outside it (3e38, 1e-30, inf) the
  // resampled length below would be 0, 1 tap or past what a size_t holds.
  if (!(h->DataSamplingRate.values[0] >= kMinFileRateHz && h->DataSamplingRate.values[0] <= kMaxFileRateHz)) {
    char rate[32];
    std::snprintf(rate, sizeof rate, "%g", double(h->DataSamplingRate.values[0]));
    return parseError(sofaPath + ": Data.SamplingRate " + rate + " Hz is outside [" +
                      std::to_string(int(kMinFileRateHz)) + ", " + std::to_string(int(kMaxFileRateHz)) + "]");
  }
  int check = mysofa_check(h);
  if (check != MYSOFA_OK) {
    return parseError(sofaPath + ": fails SOFA SimpleFreeFieldHRIR validation (libmysofa: " +
                      mysofaErrorName(check) + ")");
  }
  const std::size_t m = h->M, n = h->N;
  if (h->DataIR.elements != m * 2 * n) {
    return parseError(sofaPath + ": Data.IR has " + std::to_string(h->DataIR.elements) + " values, expected M*R*N = " +
                      std::to_string(m * 2 * n));
  }
  const double fsIn = h->DataSamplingRate.values[0];

  auto set = std::shared_ptr<HrtfSet>(new HrtfSet());
  set->mPath = sofaPath;
  set->mMode = mode;
  set->mSampleRateHz = sampleRateHz;
  set->mFileSampleRateHz = fsIn;

  // Directions: angles as in the file, then unit vectors (SOFA frame).
  mysofa_tospherical(h);
  set->mFileAngles.resize(m);
  for (std::size_t i = 0; i < m; ++i) {
    const float* sp = h->SourcePosition.values + 3 * i;
    set->mFileAngles[i] = Vec3f(sp[0], sp[1], sp[2]);
  }
  mysofa_tocartesian(h);
  set->mDirections.resize(m);
  for (std::size_t i = 0; i < m; ++i) {
    const float* sp = h->SourcePosition.values + 3 * i;
    Vec3d d = normalize(Vec3d(sp[0], sp[1], sp[2]));
    if (!(length(d) > 0.5) || !isFinite(d)) {
      return parseError(sofaPath + ": SourcePosition of measurement " + std::to_string(i) + " is at the origin or not finite");
    }
    set->mDirections[i] = Vec3f(d);
  }

  for (std::size_t k = 0; k < m * 2 * n; ++k) {
    if (!std::isfinite(h->DataIR.values[k])) {
      return parseError(sofaPath + ": Data.IR of measurement " + std::to_string(k / (2 * n)) +
                        " has a non-finite value");
    }
  }
  // Data.Delay (samples, I x R or M x R) becomes every arrival's ear delay:
  // finite, and within a second (a NaN made every binaural IR NaN).
  for (std::size_t k = 0; k < h->DataDelay.elements; ++k) {
    if (!(std::fabs(double(h->DataDelay.values[k])) <= fsIn)) {
      return parseError(sofaPath + ": Data.Delay value " + std::to_string(k) +
                        " is not finite or longer than a second of samples");
    }
  }
  // Resampled length; the minimum-phase HRIR concentrates at least as much
  // energy in its first taps as any other phase version, so it fits as well.
  const std::size_t length = std::size_t(std::ceil(double(n) * sampleRateHz / fsIn));
  if (length > HrirPair::kMaxTaps) {
    return outOfRange(sofaPath + ": HRIRs need " + std::to_string(length) + " taps at " +
                      std::to_string(sampleRateHz) + " Hz, more than the maximum " +
                      std::to_string(HrirPair::kMaxTaps));
  }
  set->mLength = length;
  set->mOnsetTap = 0;
  set->mTaps.assign(m * 2 * length, 0.0f);
  set->mDelays.resize(m * 2);

  // Per measurement (both ears at once): the onsets at the file's rate, then
  // resampling and minimum phase. Measurements are independent, so threads
  // take blocks of them in turn, each with its own scratch: the results do
  // not depend on the thread count.
  std::vector<double> onset(m * 2);
  std::atomic<std::size_t> nextBlock{0};
  auto prepare = [&]() {
    MeasurementPreparer preparer(n, fsIn, sampleRateHz);
    for (;;) {
      const std::size_t first = nextBlock.fetch_add(kLoadBlock);
      if (first >= m) return;
      for (std::size_t j = first; j < std::min(m, first + kLoadBlock); ++j)
        preparer.run(h->DataIR.values + 2 * j * n, set->mTaps.data() + 2 * j * length, &onset[2 * j]);
    }
  };
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  const std::size_t threads = std::min<std::size_t>({cores, kMaxLoadThreads, (m + kLoadBlock - 1) / kLoadBlock});
  std::vector<std::thread> helpers;
  struct JoinAll {  // also when this thread throws (bad_alloc): helpers use this frame
    std::vector<std::thread>& threads;
    ~JoinAll() {
      for (std::thread& t : threads)
        if (t.joinable()) t.join();
    }
  } joinAll{helpers};
  for (std::size_t t = 1; t < threads; ++t) {
    try {
      helpers.emplace_back(prepare);
    } catch (const std::system_error&) {
      break;  // no more threads: this one does the rest
    }
  }
  // Meanwhile, here: the lookup structures (they read only the directions).
  set->buildNearestGrid();
  if (mode == InterpolationMode::kBarycentric) set->buildTriangulation();
  prepare();
  for (std::thread& t : helpers) t.join();

  // Delays relative to the mean onset, plus any Data.Delay (samples, I x R or M x R).
  std::vector<double> fileDelay(m * 2, 0.0);
  for (std::size_t i = 0; i < m * 2; ++i) {
    if (h->DataDelay.elements == 2) fileDelay[i] = h->DataDelay.values[i % 2];
    if (h->DataDelay.elements == m * 2) fileDelay[i] = h->DataDelay.values[i];
  }
  double sum = 0.0;
  for (std::size_t i = 0; i < m * 2; ++i) sum += (onset[i] + fileDelay[i]) / fsIn;
  set->mReferenceOnsetSeconds = sum / double(m * 2);
  for (std::size_t i = 0; i < m * 2; ++i)
    set->mDelays[i] = (onset[i] + fileDelay[i]) / fsIn - set->mReferenceOnsetSeconds;
  if (!cacheName.empty()) set->writePrepared(folder, cacheName, cacheKey);
  return std::shared_ptr<const HrtfSet>(std::move(set));
}

void HrtfSet::buildTriangulation() {
  std::vector<Vec3d> pts(mDirections.size());
  for (std::size_t i = 0; i < pts.size(); ++i) pts[i] = Vec3d(mDirections[i]);
  auto hull = detail::convexHullTriangles(pts);

  struct Cap {
    Vec3d centre;
    double radius, cosR, sinR;
    double cosCoarse, sinCoarse;  // of radius + kCoarseMargin
  };
  std::vector<Cap> caps;
  for (const auto& t : hull) {
    const Vec3d a = pts[t[0]], b = pts[t[1]], c = pts[t[2]];
    const double det = dot(a, cross(b, c));
    const double area2 = length(cross(b - a, c - a));
    // Drop triangles whose plane passes (nearly) through the centre: their
    // cones are degenerate and the weights would blow up.
    if (!(area2 > 0.0) || det / area2 < 1e-3) continue;
    Triangle tri;
    tri.v = t;
    tri.n[0] = Vec3f(cross(b, c) / det);
    tri.n[1] = Vec3f(cross(c, a) / det);
    tri.n[2] = Vec3f(cross(a, b) / det);
    mTriangles.push_back(tri);
    Vec3d centre = normalize(a + b + c);
    double r = std::max({angleBetween(centre, a), angleBetween(centre, b), angleBetween(centre, c)});
    const double coarse = r + kCoarseMargin;
    caps.push_back({centre, r, std::cos(r), std::sin(r), std::cos(coarse), std::sin(coarse)});
  }

  mGridN = kGridN;
  const int cells = 6 * kGridN * kGridN;
  std::vector<std::vector<uint32_t>> lists(cells);
  std::vector<uint32_t> candidates;
  for (const CellBlock& block : cellBlocks()) {
    // Coarse: caps that can overlap some cell of the block (ascending t).
    // angle(block, cap) <= block.radius + cap.radius + margin, compared as cosines.
    candidates.clear();
    const double cb = std::cos(block.radius), sb = std::sin(block.radius);
    for (uint32_t t = 0; t < caps.size(); ++t) {
      const Cap& cp = caps[t];
      if (cp.radius >= 0.49 * kPi || block.radius + cp.radius + kCoarseMargin >= kPi ||
          dot(block.centre, cp.centre) >= cb * cp.cosCoarse - sb * cp.sinCoarse)
        candidates.push_back(t);
    }
    for (const CellCap& cell : block.cells) {
      auto& list = lists[cell.index];
      const double r = cell.radius, cr = std::cos(r), sr = std::sin(r);
      for (uint32_t t : candidates) {
        // Caps overlap iff angle(centres) <= r + radius, i.e. the dot product
        // >= cos(r + radius) (with a small margin). A cap of radius >= 90
        // degrees is not convex: keep that triangle everywhere.
        const Cap& cp = caps[t];
        bool keep = cp.radius >= 0.49 * kPi || r + cp.radius >= kPi ||
                    dot(cell.centre, cp.centre) >= cr * cp.cosR - sr * cp.sinR - 1e-6;
        if (keep) list.push_back(t);
      }
    }
  }
  mCellStart.assign(cells + 1, 0);
  for (int c = 0; c < cells; ++c) mCellStart[c + 1] = mCellStart[c] + uint32_t(lists[c].size());
  mCellTriangles.reserve(mCellStart[cells]);
  for (const auto& l : lists) mCellTriangles.insert(mCellTriangles.end(), l.begin(), l.end());
}

void HrtfSet::buildNearestGrid() {
  // A site can be nearest to a point of a cell (cap centre c, radius r) only
  // if it lies within angle(c, nearest site of c) + 2 r of c (triangle
  // inequality), so each cell keeps just those candidates. A block's
  // candidates, the sites within 3 rho + theta of its centre (rho its radius,
  // theta the angle to its nearest site), hold for each of its cells the
  // cell's nearest site (within rho + theta of the cell) and every site the
  // cell keeps (within that + 2 r).
  const int cells = 6 * kGridN * kGridN;
  std::vector<std::vector<uint32_t>> lists(cells);
  std::vector<uint32_t> candidates;
  for (const CellBlock& block : cellBlocks()) {
    double blockBest = -2.0;
    for (const Vec3f& d : mDirections) blockBest = std::max(blockBest, dot(block.centre, Vec3d(d)));
    const double reach = std::acos(std::clamp(blockBest, -1.0, 1.0)) + 3.0 * block.radius + kCoarseMargin;
    const double cosReach = reach >= kPi ? -2.0 : std::cos(reach);
    candidates.clear();
    for (uint32_t k = 0; k < mDirections.size(); ++k)
      if (dot(block.centre, Vec3d(mDirections[k])) >= cosReach) candidates.push_back(k);
    for (const CellCap& cell : block.cells) {
      double bestDot = -2.0;
      for (uint32_t k : candidates) bestDot = std::max(bestDot, dot(cell.centre, Vec3d(mDirections[k])));
      double limit = std::acos(std::clamp(bestDot, -1.0, 1.0)) + 2.0 * cell.radius + 1e-4;
      double cosLimit = limit >= kPi ? -2.0 : std::cos(limit);
      for (uint32_t k : candidates)
        if (dot(cell.centre, Vec3d(mDirections[k])) >= cosLimit) lists[cell.index].push_back(k);
    }
  }
  mNearStart.assign(cells + 1, 0);
  mNearSites.clear();
  for (int c = 0; c < cells; ++c) {
    mNearSites.insert(mNearSites.end(), lists[c].begin(), lists[c].end());
    mNearStart[c + 1] = uint32_t(mNearSites.size());
  }
}

int HrtfSet::cellOf(const Vec3f& d) const { return cubeCell(d.x, d.y, d.z); }

int HrtfSet::nearestMeasurement(const Vec3f& d) const {
  const int cell = cellOf(d);
  int best = 0;
  float bestDot = -2.0f;
  for (uint32_t k = mNearStart[cell]; k < mNearStart[cell + 1]; ++k) {
    float c = dot(d, mDirections[mNearSites[k]]);
    if (c > bestDot) {
      bestDot = c;
      best = int(mNearSites[k]);
    }
  }
  return best;
}

InterpolationWeights HrtfSet::weights(const Vec3f& headDirection) const {
  Vec3f d = headToSofa(headDirection);
  float len = length(d);
  if (!(len > 0.0f) || !std::isfinite(len)) {
    d = Vec3f(1.0f, 0.0f, 0.0f);  // forward
  } else {
    d = d / len;
  }
  InterpolationWeights w;
  if (mMode == InterpolationMode::kBarycentric && !mTriangles.empty()) {
    const int cell = cellOf(d);
    float bestMin = -1e30f;
    float bestW[3] = {0, 0, 0};
    const Triangle* best = nullptr;
    for (uint32_t k = mCellStart[cell]; k < mCellStart[cell + 1]; ++k) {
      const Triangle& t = mTriangles[mCellTriangles[k]];
      float w0 = dot(d, t.n[0]), w1 = dot(d, t.n[1]), w2 = dot(d, t.n[2]);
      float s = w0 + w1 + w2;
      if (!(s > 0.0f)) continue;  // direction opposite to this triangle
      float mn = std::min({w0, w1, w2}) / s;
      if (mn > bestMin) {
        bestMin = mn;
        best = &t;
        bestW[0] = w0 / s;
        bestW[1] = w1 / s;
        bestW[2] = w2 / s;
        if (mn >= 0.0f) break;  // inside this triangle's cone
      }
    }
    // Accept a hair outside (rounding on shared edges): clamp and renormalise.
    if (best && bestMin > -1e-3f) {
      float s = 0.0f;
      for (int k = 0; k < 3; ++k) {
        bestW[k] = std::max(bestW[k], 0.0f);
        s += bestW[k];
      }
      w.count = 3;
      for (int k = 0; k < 3; ++k) {
        w.index[k] = best->v[k];
        w.weight[k] = bestW[k] / s;
      }
      return w;
    }
  }
  // Nearest measurement: the explicit mode, or a direction no triangle covers.
  w.count = 1;
  w.index[0] = std::size_t(nearestMeasurement(d));
  w.weight[0] = 1.0f;
  return w;
}

void HrtfSet::lookup(const Vec3f& headDirection, HrirPair& out) const {
  const InterpolationWeights w = weights(headDirection);
  const std::size_t len = mLength;
  out.length = len;
  const float* l0 = mTaps.data() + (w.index[0] * 2) * len;
  const float* r0 = l0 + len;
  if (w.count == 1) {
    std::copy(l0, l0 + len, out.left.begin());
    std::copy(r0, r0 + len, out.right.begin());
    out.leftDelaySeconds = mDelays[w.index[0] * 2];
    out.rightDelaySeconds = mDelays[w.index[0] * 2 + 1];
    return;
  }
  const float* l1 = mTaps.data() + (w.index[1] * 2) * len;
  const float* r1 = l1 + len;
  const float* l2 = mTaps.data() + (w.index[2] * 2) * len;
  const float* r2 = l2 + len;
  const float a = w.weight[0], b = w.weight[1], c = w.weight[2];
  for (std::size_t k = 0; k < len; ++k) {
    out.left[k] = a * l0[k] + b * l1[k] + c * l2[k];
    out.right[k] = a * r0[k] + b * r1[k] + c * r2[k];
  }
  out.leftDelaySeconds = a * mDelays[w.index[0] * 2] + b * mDelays[w.index[1] * 2] + c * mDelays[w.index[2] * 2];
  out.rightDelaySeconds =
      a * mDelays[w.index[0] * 2 + 1] + b * mDelays[w.index[1] * 2 + 1] + c * mDelays[w.index[2] * 2 + 1];
}

HrtfMeasurement HrtfSet::measurement(std::size_t i) const {
  HrtfMeasurement m;
  if (i >= mDirections.size()) return m;
  m.headDirection = sofaToHead(mDirections[i]);
  m.azimuthDegrees = mFileAngles[i].x;
  m.elevationDegrees = mFileAngles[i].y;
  m.distanceMeters = mFileAngles[i].z;
  m.left = mTaps.data() + (i * 2) * mLength;
  m.right = m.left + mLength;
  m.leftDelaySeconds = mDelays[i * 2];
  m.rightDelaySeconds = mDelays[i * 2 + 1];
  return m;
}

}  // namespace earshot::hrtf
