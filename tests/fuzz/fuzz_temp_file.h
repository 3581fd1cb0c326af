#pragma once
/** @file Per-process scratch file for fuzz targets whose parser takes a path.
 *  The file lives in its own mkdtemp() directory, so relative URIs in a glTF
 *  resolve to nothing; the directory is removed at exit. Not thread-safe
 *  (libFuzzer calls the target from one thread). */
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace earshot::fuzz {

class TempFile {
 public:
  /** `fileName`: name inside the private directory, e.g. "in.gltf". */
  explicit TempFile(const char* fileName) {
    const char* base = std::getenv("TMPDIR");
    std::string templ = std::string(base && *base ? base : "/tmp") + "/earshot-fuzz-XXXXXX";
    if (!mkdtemp(templ.data())) std::abort();  // no scratch space: nothing to fuzz
    mDir = templ;
    mPath = mDir + "/" + fileName;
  }
  ~TempFile() {
    std::remove(mPath.c_str());
    rmdir(mDir.c_str());
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;

  /** Replaces the file's content with `size` bytes; returns its path. */
  const std::string& write(const uint8_t* data, size_t size) {
    std::FILE* f = std::fopen(mPath.c_str(), "wb");
    if (!f) std::abort();
    if (size > 0 && std::fwrite(data, 1, size, f) != size) std::abort();
    std::fclose(f);
    return mPath;
  }

 private:
  std::string mDir, mPath;
};

/** What every error and warning message promises (core/status.h): one
 *  line, whatever the input held. */
inline bool oneLine(const std::string& message) {
  return !message.empty() && message.find('\n') == std::string::npos && message.find('\r') == std::string::npos;
}

}  // namespace earshot::fuzz

/** Invariant a parser promised for an accepted input; a violation is a
 *  finding, so it aborts with the condition (libFuzzer saves the input). */
#define EARSHOT_FUZZ_CHECK(cond)                                                  \
  do {                                                                            \
    if (!(cond)) {                                                                \
      std::fprintf(stderr, "%s:%d: fuzz invariant failed: %s\n", __FILE__, __LINE__, #cond); \
      std::abort();                                                               \
    }                                                                             \
  } while (0)
