// earshot-sofa-probe's exit status, shared by the probe
// (tools/sofa_probe/sofa_probe.cpp) and HrtfSet::load, which runs it.
//
//   0   read and valid
//   1   refused (mysofa_check, or a reason the status cannot carry): the
//       caller reads the file again to report why
//   2   usage
//   3   reading it needs more than the memory limit
//   15  mysofa_load failed with MYSOFA_INTERNAL_ERROR
//   16+ mysofa_load failed with MYSOFA_INVALID_FORMAT + (status - 16)
//
// A failed mysofa_load carries its error out, so the caller does not read
// the file again: libmysofa 1.3.1 (Debian 12) leaks what it allocated
// before failing on some malformed files (~1 KB each; found by fuzz_sofa).
#pragma once

#include <mysofa.h>

namespace earshot::hrtf::detail {

constexpr int kProbeLoadInternalError = 15;
constexpr int kProbeLoadErrorBase = 16;
// The last error this libmysofa names (mysofa.h's enum).
constexpr int kLastMysofaError = MYSOFA_ONLY_SOURCES_WITH_MC_SUPPORTED;

/** The probe's exit status for mysofa_load's error `err`: 3 for
 *  MYSOFA_NO_MEMORY, 1 when the status cannot carry it (an errno value, an
 *  error newer than this header). */
constexpr int probeStatusForLoadError(int err) {
  if (err == MYSOFA_NO_MEMORY) return 3;
  if (err == MYSOFA_INTERNAL_ERROR) return kProbeLoadInternalError;
  if (err >= MYSOFA_INVALID_FORMAT && err <= kLastMysofaError)
    return kProbeLoadErrorBase + (err - MYSOFA_INVALID_FORMAT);
  return 1;
}

/** mysofa_load's error that the probe's exit status `status` carries, or
 *  MYSOFA_OK when it carries none. */
constexpr int loadErrorForProbeStatus(int status) {
  if (status == kProbeLoadInternalError) return MYSOFA_INTERNAL_ERROR;
  if (status >= kProbeLoadErrorBase && status <= kProbeLoadErrorBase + (kLastMysofaError - MYSOFA_INVALID_FORMAT))
    return MYSOFA_INVALID_FORMAT + (status - kProbeLoadErrorBase);
  return MYSOFA_OK;
}

static_assert(kProbeLoadErrorBase + (kLastMysofaError - MYSOFA_INVALID_FORMAT) < 126,
              "exit statuses from 126 up are the shell's");
static_assert(loadErrorForProbeStatus(probeStatusForLoadError(MYSOFA_READ_ERROR)) == MYSOFA_READ_ERROR);
static_assert(loadErrorForProbeStatus(probeStatusForLoadError(MYSOFA_INTERNAL_ERROR)) == MYSOFA_INTERNAL_ERROR);
static_assert(loadErrorForProbeStatus(1) == MYSOFA_OK && loadErrorForProbeStatus(3) == MYSOFA_OK);
static_assert(probeStatusForLoadError(MYSOFA_NO_MEMORY) == 3);

}  // namespace earshot::hrtf::detail
