#include <dlfcn.h>

#include <cstdlib>
#include <fstream>

#include "earshot/hrtf/hrtf_set.h"

#ifndef EARSHOT_HRTF_DIR
#define EARSHOT_HRTF_DIR ""
#endif

namespace earshot::hrtf {

namespace {

bool readable(const std::string& path) { return std::ifstream(path, std::ios::binary).good(); }

/** The installed layout: the binary holding this code (libearshot.so, or an
 *  executable linked statically) sits in PREFIX/lib, PREFIX/lib/<multiarch>
 *  or PREFIX/bin, and `cmake --install` puts the set in
 *  PREFIX/share/earshot/hrtf. Empty when not found there. */
std::string installedHrtfFile() {
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&defaultHrtfPath), &info) == 0 || info.dli_fname == nullptr) return "";
  const std::string binary = info.dli_fname;
  const size_t slash = binary.rfind('/');
  if (slash == std::string::npos) return "";
  const std::string dir = binary.substr(0, slash);
  for (const char* up : {"/../share/earshot/hrtf/", "/../../share/earshot/hrtf/"}) {
    const std::string path = dir + up + kDefaultHrtfFileName;
    if (readable(path)) return path;
  }
  return "";
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
