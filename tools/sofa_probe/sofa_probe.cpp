// earshot-sofa-probe: reads one SOFA file with libmysofa and says by its exit
// status whether it could. HrtfSet::load runs it (posix_spawn, a fresh
// process: no state shared with a multi-threaded host) before reading a SOFA
// file that earshot does not ship, because libmysofa hangs on some malformed
// files and allocates what a header claims. Here a hang meets the parent's
// deadline and an allocation meets the address-space limit; the host lives.
//
//   earshot-sofa-probe FILE MAX_BYTES
//
// Exit status (src/hrtf/sofa_probe_status.h): 0 read and valid, 1 refused
// (the caller reads it again to report why), 2 usage, 3 it needs more than
// MAX_BYTES, 15 and up: mysofa_load failed with the error the status
// carries (the caller reports it without reading the file again).
#include <mysofa.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>

#include "sofa_probe_status.h"

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define EARSHOT_PROBE_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define EARSHOT_PROBE_SANITIZED 1
#endif
#endif

namespace {
// What this small process maps before reading anything (libc, libmysofa,
// zlib, stacks): the limit is MAX_BYTES beyond it.
[[maybe_unused]] constexpr unsigned long long kBaseBytes = 256ull << 20;  // unused when sanitized
// The parent kills at its deadline; this is the fallback should it be gone.
constexpr unsigned kSelfDeadlineSeconds = 60;
}  // namespace

int main(int argc, char** argv) {
  if (argc != 3 || argv[2][0] < '0' || argv[2][0] > '9') return 2;
  char* end = nullptr;
  const unsigned long long maxBytes = std::strtoull(argv[2], &end, 10);
  if (end == argv[2] || *end != '\0' || maxBytes == 0) return 2;
#ifndef EARSHOT_PROBE_SANITIZED  // sanitizers reserve terabytes of address space up front
  rlimit lim{};
  lim.rlim_cur = lim.rlim_max = rlim_t(maxBytes > (1ull << 60) ? (1ull << 60) : maxBytes + kBaseBytes);
  setrlimit(RLIMIT_AS, &lim);
#endif
  alarm(kSelfDeadlineSeconds);
  int err = 0;
  MYSOFA_HRTF* h = mysofa_load(argv[1], &err);
  // Out without the exit handlers: a failed load can leak inside libmysofa
  // (sofa_probe_status.h), which a sanitized build would report at exit.
  if (!h) std::_Exit(earshot::hrtf::detail::probeStatusForLoadError(err));
  const int check = mysofa_check(h);
  mysofa_free(h);
  return check == MYSOFA_OK ? 0 : 1;
}
