#include <cstdlib>
#include <fstream>

#include "earshot/hrtf/hrtf_set.h"

#ifndef EARSHOT_HRTF_DIR
#define EARSHOT_HRTF_DIR ""
#endif

namespace earshot::hrtf {

Result<std::string> defaultHrtfPath() {
  const char* env = std::getenv("EARSHOT_HRTF_DIR");
  bool fromEnv = env != nullptr && env[0] != '\0';
  std::string dir = fromEnv ? std::string(env) : std::string(EARSHOT_HRTF_DIR);
  if (dir.empty()) return notFound("default HRTF: no hrtf/ folder known; set EARSHOT_HRTF_DIR");
  std::string path = dir + "/" + kDefaultHrtfFileName;
  std::ifstream f(path, std::ios::binary);
  if (!f) {
    return notFound("default HRTF: " + path + " does not exist" +
                    (fromEnv ? " (from EARSHOT_HRTF_DIR)" : " (set EARSHOT_HRTF_DIR to the folder holding it)"));
  }
  return path;
}

}  // namespace earshot::hrtf
