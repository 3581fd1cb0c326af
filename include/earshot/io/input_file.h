#pragma once
/** @file Untrusted input files: what a file may make earshot read and
 *  allocate, where its references may point, and which paths an output may
 *  never replace. Every loader in earshot goes through these.
 *
 *  The rules (README "Untrusted input"):
 *  - Only regular files are inputs (never a FIFO, a device or a directory),
 *    and each kind has a size limit checked before reading.
 *  - A file reference inside a file (a glTF buffer or image URI, a scene's
 *    audio, materials, geometry or HRTF) resolves inside the referring file's
 *    folder, symlinks resolved first; anything else is refused unless
 *    InputLimits::allowOutsidePaths.
 *  - Loaders estimate what a file makes them allocate (triangles after
 *    instancing, samples after resampling, a render's sources) and refuse
 *    past InputLimits::maxMemoryBytes before allocating.
 *  - JSON nesting is capped (kMaxJsonDepth) before any parser sees the text:
 *    parsers recurse on nesting.
 *  - Every input file read is remembered (device and inode); an output path
 *    that is one of them, a directory, a FIFO or a device is refused.
 *  Error messages name the file and the field, never its contents. */
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "earshot/core/status.h"

namespace earshot {

/** Default of InputLimits::maxMemoryBytes: 1 GiB (documented in the README). */
constexpr uint64_t kDefaultMaxMemoryBytes = uint64_t(1) << 30;
/** Deepest JSON nesting accepted (objects and arrays) in any input. */
constexpr int kMaxJsonDepth = 128;
/** Largest JSON text (scene, materials, material map, tolerances) read. */
constexpr uint64_t kMaxJsonFileBytes = uint64_t(64) << 20;

/** What an input may make the engine do. */
struct InputLimits {
  /** Estimated allocation a loaded file may cause (bytes). */
  uint64_t maxMemoryBytes = kDefaultMaxMemoryBytes;
  /** true: references may leave the referring file's folder (absolute paths, ..). */
  bool allowOutsidePaths = false;
};

/** The process-wide defaults every loader uses unless given limits
 *  explicitly (the CLI sets them from --max-memory / --allow-outside-paths).
 *  Thread-safe. */
InputLimits defaultInputLimits();
void setDefaultInputLimits(const InputLimits& limits);
/** The process's memory limit set to `bytes` (0: kDefaultMaxMemoryBytes),
 *  the other limits kept (earshot_set_memory_limit, earshot.set_memory_limit). */
void setDefaultMaxMemoryBytes(uint64_t bytes);
/** kOutOfRange "<what> needs about B, over the memory limit of L
 *  (--max-memory)" when an estimate of `bytes` passes the process's memory
 *  limit (before allocating it); ok otherwise. */
Status checkMemoryEstimate(double bytes, const std::string& what);
/** `message` with the CLI's name of the memory limit, "(--max-memory)",
 *  replaced by `setter` (how the caller's API sets it: the C API's
 *  "earshot_set_memory_limit", Python's "earshot.set_memory_limit"). */
std::string renamedMemoryLimit(const std::string& message, const std::string& setter);

/** While alive, this thread's checkMemoryEstimate compares with `bytes`
 *  (its share of the limit) where that is below the process's limit: work
 *  run side by side on T threads (Python's ir_batch) gives each the limit
 *  / T, so together they stay within it. A check refused by the share alone
 *  (within the whole limit) is remembered: that work may be run again
 *  alone, under the whole limit. Shares nest (the innermost one counts);
 *  one lives and dies on one thread. */
class MemoryLimitShare {
 public:
  explicit MemoryLimitShare(uint64_t bytes);
  ~MemoryLimitShare();
  MemoryLimitShare(const MemoryLimitShare&) = delete;
  MemoryLimitShare& operator=(const MemoryLimitShare&) = delete;
  /** A check on this thread, while this share lived, was refused by the
   *  share and would have passed the process's limit. */
  bool refusedWithinTheLimit() const;

 private:
  uint64_t mOuterShare;
  bool mOuterRefused;
};

/** Parses a byte count: "512M", "2G", "1073741824", "64K" (powers of 1024). */
Result<uint64_t> parseByteSize(const std::string& text);
/** "1.0 GiB", "512 MiB": for messages. */
std::string formatBytes(uint64_t bytes);

/** Checks that `path` is a regular file (symlinks followed) no larger than
 *  maxBytes, and records it as an input of this process (see
 *  checkOutputPath). `what` names the file's role in messages ("materials
 *  file"). Returns its size. */
Result<uint64_t> checkInputFile(const std::string& path, const std::string& what, uint64_t maxBytes);

/** checkInputFile, then the whole file's bytes. */
Result<std::string> readInputFile(const std::string& path, const std::string& what, uint64_t maxBytes);

/** Refuses JSON (or JSON-like) text nested deeper than maxDepth, before a
 *  recursive parser sees it. Counts brackets outside strings; says where
 *  (byte offset), never what. */
Status checkJsonDepth(std::string_view text, const std::string& path, int maxDepth = kMaxJsonDepth);

/** A JSON parser's message without what it quotes of the text (nlohmann's
 *  "; last read: '...'", the exception tag): where and what kind of error,
 *  never the file's bytes, which may be another file's (a secret) when a
 *  reference pointed there. */
std::string jsonErrorWithoutContent(std::string parserMessage);

/** Resolves `reference`, a path written in a file whose folder is `folder`
 *  ("" for the working directory), relative to that folder. Unless
 *  allowOutside, the result (symlinks resolved) must lie inside the folder:
 *  absolute references, ones that climb out with .., and symlinks that lead
 *  out are refused. `where` starts each message ("scene.json: sources[0].audio"). */
Result<std::string> resolveReference(const std::string& folder, const std::string& where,
                                     const std::string& reference, bool allowOutside);
/** The folder of `file` ("" when it has none). */
std::string folderOf(const std::string& file);

/** An output may be written to `path`: refused if it is one of the files this
 *  process has read as input (same device and inode), a directory, a FIFO, a
 *  device or a socket. A path that does not exist yet is fine when its
 *  folder exists and this process may write into it. */
Status checkOutputPath(const std::string& path);

/** checkOutputPath for each of one command's outputs (empty ones skipped),
 *  and no two of them the same file: the same device and inode when it
 *  exists (a hard link, a symlink), else the same path once its existing
 *  folders are resolved. `names` are the options shown in messages
 *  ("-o", "--json"), one per path. */
Status checkOutputPaths(const std::vector<std::string>& paths, const std::vector<std::string>& names);

/** Records `path` as an input without reading it (for files a library opens
 *  itself); silently nothing if it cannot be stat'ed. */
void rememberInputFile(const std::string& path);

}  // namespace earshot
