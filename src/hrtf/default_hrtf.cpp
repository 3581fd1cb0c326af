#include <dlfcn.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>

#include "earshot/hrtf/hrtf_set.h"
#include "install_layout.h"

#ifndef EARSHOT_SOFA_PROBE_BUILD_PATH
#define EARSHOT_SOFA_PROBE_BUILD_PATH ""
#endif
#ifndef EARSHOT_HRTF_DIR
#define EARSHOT_HRTF_DIR ""
#endif
#ifndef EARSHOT_PREPARED_BUILD_DIR
#define EARSHOT_PREPARED_BUILD_DIR ""
#endif

namespace earshot::hrtf {

namespace detail {

std::string installedFile(const std::string& relative, bool executable) {
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&installedFile), &info) == 0 || info.dli_fname == nullptr) return "";
  const std::string binary = info.dli_fname;
  const size_t slash = binary.rfind('/');
  if (slash == std::string::npos) return "";
  const std::string dir = binary.substr(0, slash);
  for (const char* up : {"/../", "/../../"}) {
    const std::string path = dir + up + relative;
    if (::access(path.c_str(), executable ? X_OK : R_OK) == 0) return path;
  }
  return "";
}

std::string shippedPreparedFile(const std::string& name) {
  std::string installed = installedFile("share/earshot/prepared/" + name, false);
  if (!installed.empty()) return installed;
  const std::string built = std::string(EARSHOT_PREPARED_BUILD_DIR) + "/" + name;
  if (std::string(EARSHOT_PREPARED_BUILD_DIR).empty() || ::access(built.c_str(), R_OK) != 0) return "";
  return built;
}

std::string sofaProbePath() {
  const char* env = std::getenv("EARSHOT_SOFA_PROBE");
  if (env != nullptr && env[0] != '\0') return ::access(env, X_OK) == 0 ? std::string(env) : std::string();
  std::string installed = installedFile("libexec/earshot/earshot-sofa-probe", true);
  if (!installed.empty()) return installed;
  const std::string built = EARSHOT_SOFA_PROBE_BUILD_PATH;
  if (!built.empty() && ::access(built.c_str(), X_OK) == 0) return built;
  return "";
}

}  // namespace detail

namespace {

bool readable(const std::string& path) { return std::ifstream(path, std::ios::binary).good(); }

std::string installedHrtfFile() {
  return detail::installedFile(std::string("share/earshot/hrtf/") + kDefaultHrtfFileName, false);
}

}  // namespace

Result<std::string> defaultHrtfPath() {
  // 1. $EARSHOT_HRTF_DIR (an explicit choice: no fallback when it is wrong).
  const char* env = std::getenv("EARSHOT_HRTF_DIR");
  if (env != nullptr && env[0] != '\0') {
    const std::string path = std::string(env) + "/" + kDefaultHrtfFileName;
    if (!readable(path)) return notFound("default HRTF: " + path + " does not exist (from EARSHOT_HRTF_DIR)");
    return path;
  }
  // 2. Next to the installed library; 3. the source tree it was built from.
  std::string installed = installedHrtfFile();
  if (!installed.empty()) return installed;
  const std::string dir = EARSHOT_HRTF_DIR;
  if (dir.empty()) return notFound("default HRTF: no hrtf/ folder known; set EARSHOT_HRTF_DIR");
  const std::string path = dir + "/" + kDefaultHrtfFileName;
  if (!readable(path))
    return notFound("default HRTF: " + path +
                    " does not exist, nor share/earshot/hrtf next to the library (set EARSHOT_HRTF_DIR to the "
                    "folder holding it)");
  return path;
}

}  // namespace earshot::hrtf
