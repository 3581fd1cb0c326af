// Untrusted input files: see input_file.h.
#include "earshot/io/input_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <set>
#include <utility>

namespace earshot {

namespace fs = std::filesystem;

namespace {

std::mutex gMutex;
InputLimits gDefaults;
std::set<std::pair<dev_t, ino_t>> gInputs;  // every input file read by this process

const char* kindOf(mode_t m) {
  if (S_ISDIR(m)) return "a directory";
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISCHR(m)) return "a character device";
  if (S_ISBLK(m)) return "a block device";
  if (S_ISSOCK(m)) return "a socket";
  return "not a regular file";
}

void remember(const struct stat& st) {
  std::lock_guard<std::mutex> lock(gMutex);
  gInputs.emplace(st.st_dev, st.st_ino);
}

}  // namespace

InputLimits defaultInputLimits() {
  std::lock_guard<std::mutex> lock(gMutex);
  return gDefaults;
}

void setDefaultInputLimits(const InputLimits& limits) {
  std::lock_guard<std::mutex> lock(gMutex);
  gDefaults = limits;
}

void setDefaultMaxMemoryBytes(uint64_t bytes) {
  std::lock_guard<std::mutex> lock(gMutex);
  gDefaults.maxMemoryBytes = bytes > 0 ? bytes : kDefaultMaxMemoryBytes;
}

namespace {
// This thread's MemoryLimitShare (0: none), and whether it refused a check
// the process's limit allows.
thread_local uint64_t tShare = 0;
thread_local bool tRefusedByShare = false;
}  // namespace

Status checkMemoryEstimate(double bytes, const std::string& what) {
  const uint64_t limit = defaultInputLimits().maxMemoryBytes;
  const bool overShare = tShare > 0 && tShare < limit && bytes > double(tShare);
  if (bytes <= double(limit) && !overShare) return Status::ok();
  // NaN (an estimate from NaN settings) has no byte count: uint64_t(NaN) is undefined.
  const std::string needs =
      what + (std::isnan(bytes) ? std::string(" needs an amount that is not a number")
                                : " needs about " + formatBytes(uint64_t(std::min(bytes, 1.8e19))));
  if (!(bytes <= double(limit)))
    return outOfRange(needs + ", over the memory limit of " + formatBytes(limit) + " (--max-memory)");
  tRefusedByShare = true;
  return outOfRange(needs + ", over this thread's share (" + formatBytes(tShare) + ") of the memory limit of " +
                    formatBytes(limit) + " (--max-memory) for work run side by side");
}

std::string renamedMemoryLimit(const std::string& message, const std::string& setter) {
  static const std::string kCli = "(--max-memory)";
  std::string out;
  size_t from = 0;
  for (size_t at; (at = message.find(kCli, from)) != std::string::npos; from = at + kCli.size())
    out.append(message, from, at - from).append("(").append(setter).append(")");
  return out.append(message, from, std::string::npos);
}

MemoryLimitShare::MemoryLimitShare(uint64_t bytes) : mOuterShare(tShare), mOuterRefused(tRefusedByShare) {
  tShare = std::max<uint64_t>(bytes, 1);
  tRefusedByShare = false;
}

MemoryLimitShare::~MemoryLimitShare() {
  tShare = mOuterShare;
  tRefusedByShare = mOuterRefused || tRefusedByShare;
}

bool MemoryLimitShare::refusedWithinTheLimit() const { return tRefusedByShare; }

Result<uint64_t> parseByteSize(const std::string& text) {
  if (text.empty()) return invalidArgument("empty size (expected bytes, or a number with K, M, G or T)");
  size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (...) {
    return invalidArgument("'" + text + "' is not a size (expected bytes, or a number with K, M, G or T)");
  }
  double scale = 1;
  std::string unit = text.substr(used);
  if (unit == "K" || unit == "KiB" || unit == "k") scale = 1024.0;
  else if (unit == "M" || unit == "MiB") scale = 1024.0 * 1024;
  else if (unit == "G" || unit == "GiB") scale = 1024.0 * 1024 * 1024;
  else if (unit == "T" || unit == "TiB") scale = 1024.0 * 1024 * 1024 * 1024;
  else if (!unit.empty())
    return invalidArgument("'" + text + "' has an unknown unit (expected K, M, G or T)");
  const double bytes = v * scale;
  if (!std::isfinite(bytes) || bytes < 1 || bytes > 1.8e19)
    return invalidArgument("'" + text + "' is not a size between 1 byte and 16 EiB");
  return static_cast<uint64_t>(bytes);
}

std::string formatBytes(uint64_t bytes) {
  char buf[48];
  if (bytes >= (uint64_t(1) << 30))
    std::snprintf(buf, sizeof buf, "%.1f GiB", double(bytes) / double(uint64_t(1) << 30));
  else if (bytes >= (uint64_t(1) << 20))
    std::snprintf(buf, sizeof buf, "%.1f MiB", double(bytes) / double(uint64_t(1) << 20));
  else
    std::snprintf(buf, sizeof buf, "%llu bytes", static_cast<unsigned long long>(bytes));
  return buf;
}

Result<uint64_t> checkInputFile(const std::string& path, const std::string& what, uint64_t maxBytes) {
  if (path.empty()) return invalidArgument(what + ": empty path");
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int e = errno;
    if (e == ENOENT || e == ENOTDIR) return notFound(displayPath(path) + ": " + what + " not found");
    return ioError(displayPath(path) + ": cannot open " + what + " (" + std::strerror(e) + ")");
  }
  if (!S_ISREG(st.st_mode))
    return invalidArgument(displayPath(path) + ": " + what + " is " + kindOf(st.st_mode) + ", expected a regular file");
  const uint64_t size = static_cast<uint64_t>(st.st_size);
  if (size > maxBytes)
    return outOfRange(displayPath(path) + ": " + what + " of " + formatBytes(size) + " is over the limit of " +
                      formatBytes(maxBytes));
  remember(st);
  return size;
}

Result<std::string> readInputFile(const std::string& path, const std::string& what, uint64_t maxBytes) {
  auto size = checkInputFile(path, what, maxBytes);
  if (!size) return size.status();
  // O_NONBLOCK: a path swapped for a FIFO after the check cannot block us;
  // fstat again on what was opened.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return ioError(displayPath(path) + ": cannot open " + what + " (" + std::strerror(errno) + ")");
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || static_cast<uint64_t>(st.st_size) > maxBytes) {
    ::close(fd);
    return invalidArgument(displayPath(path) + ": " + what + " changed while being opened (expected a regular file)");
  }
  std::string bytes(static_cast<size_t>(st.st_size), '\0');
  size_t got = 0;
  while (got < bytes.size()) {
    const ssize_t n = ::read(fd, &bytes[got], bytes.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += static_cast<size_t>(n);
  }
  ::close(fd);
  if (got != bytes.size()) return ioError(displayPath(path) + ": read error in " + what);
  return bytes;
}

Status checkJsonDepth(std::string_view text, const std::string& path, int maxDepth) {
  int depth = 0;
  bool inString = false, escaped = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (inString) {
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') inString = false;
      continue;
    }
    if (c == '"') {
      inString = true;
    } else if (c == '{' || c == '[') {
      if (++depth > maxDepth)
        return parseError(displayPath(path) + ": JSON nested deeper than " + std::to_string(maxDepth) +
                          " levels (at byte " + std::to_string(i) + ")");
    } else if (c == '}' || c == ']') {
      if (depth > 0) --depth;
    }
  }
  return Status::ok();
}

std::string jsonErrorWithoutContent(std::string what) {
  if (!what.empty() && what[0] == '[') {
    const size_t close = what.find("] ");
    if (close != std::string::npos) what.erase(0, close + 2);
  }
  const size_t lastRead = what.find("; last read");
  if (lastRead != std::string::npos) what.erase(lastRead);
  // The number nlohmann could not hold is the text's too ("number overflow
  // parsing '1e999'"); the tokens it names ("unexpected ','; expected
  // ':'") are the grammar's, and stay.
  const size_t parsing = what.find(" parsing '");
  if (parsing != std::string::npos) {
    const size_t from = what.find(" '", parsing + 1);  // the space before the number's quote
    const size_t close = what.find('\'', from + 2);
    what.erase(from, close == std::string::npos ? std::string::npos : close + 1 - from);
  }
  for (char& c : what)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '?';
  if (what.size() > 200) what = what.substr(0, 200) + "...";
  return what;
}

namespace {

/** `inner` lies inside `folder` (both canonical). */
bool isInside(const fs::path& inner, const fs::path& folder) {
  auto i = inner.begin();
  for (auto f = folder.begin(); f != folder.end(); ++f, ++i) {
    if (f->empty()) continue;  // a trailing separator
    if (i == inner.end() || *i != *f) return false;
  }
  return true;
}

}  // namespace

std::string folderOf(const std::string& file) { return fs::path(file).parent_path().string(); }

Result<std::string> resolveReference(const std::string& folder, const std::string& where,
                                     const std::string& reference, bool allowOutside) {
  if (reference.empty()) return invalidArgument(where + ": empty file reference");
  if (reference.find('\0') != std::string::npos) return invalidArgument(where + ": file reference contains NUL");
  const fs::path ref(reference);
  const fs::path base = folder.empty() ? fs::path(".") : fs::path(folder);
  const fs::path joined = ref.is_absolute() ? ref.lexically_normal() : (base / ref).lexically_normal();
  if (allowOutside) return joined.string();
  // The reference is the referring file's text: shown as every path is
  // (quoted when it holds what could forge a line).
  const std::string quoted = displayPath(reference), folderShown = displayPath(base.string());
  if (ref.is_absolute())
    return invalidArgument(where + ": absolute path " + quoted + " is refused (references must stay inside " +
                           folderShown + "; --allow-outside-paths allows it)");
  std::error_code e1, e2;
  const fs::path canonicalFolder = fs::weakly_canonical(fs::absolute(base, e1), e1);
  const fs::path target = fs::weakly_canonical(fs::absolute(joined, e2), e2);
  if (e1 || e2) return ioError(where + ": cannot resolve " + quoted);
  if (!isInside(target, canonicalFolder))
    return invalidArgument(where + ": " + quoted + " leads outside " + folderShown +
                           " (refused; --allow-outside-paths allows it)");
  return joined.string();
}

Status checkOutputPath(const std::string& path) {
  if (path.empty()) return invalidArgument("output path is empty");
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    // A new file: its folder must exist and take it, so that a command with
    // several outputs fails before writing the first rather than after.
    const fs::path parent = fs::path(path).parent_path();
    const std::string folder = parent.empty() ? "." : parent.string();
    struct stat dir {};
    if (::stat(folder.c_str(), &dir) != 0)
      return notFound(displayPath(path) + ": cannot write: folder " + displayPath(folder) + " does not exist");
    if (!S_ISDIR(dir.st_mode))
      return invalidArgument(displayPath(path) + ": cannot write: " + displayPath(folder) + " is not a folder");
    if (::access(folder.c_str(), W_OK | X_OK) != 0)
      return ioError(displayPath(path) + ": cannot write into folder " + displayPath(folder) + " (" +
                     std::strerror(errno) + ")");
    return Status::ok();
  }
  if (!S_ISREG(st.st_mode))
    return invalidArgument(displayPath(path) + ": output is " + std::string(kindOf(st.st_mode)) +
                           "; refusing to replace it (outputs must be regular files)");
  std::lock_guard<std::mutex> lock(gMutex);
  if (gInputs.count({st.st_dev, st.st_ino}))
    return invalidArgument(displayPath(path) +
                           ": output is one of this command's input files; refusing to overwrite it");
  return Status::ok();
}

Status checkOutputPaths(const std::vector<std::string>& paths, const std::vector<std::string>& names) {
  if (names.size() != paths.size()) return invalidArgument("checkOutputPaths: one name per path");
  // Two outputs are one file when their paths are the same once the folders
  // that exist are resolved (symlinks, ., ..), or when both exist with the
  // same device and inode (a hard link).
  struct Identity {
    size_t index;
    std::string path;
    bool exists;
    dev_t dev;
    ino_t ino;
  };
  std::vector<Identity> seen;
  for (size_t i = 0; i < paths.size(); ++i) {
    if (paths[i].empty()) continue;
    Status s = checkOutputPath(paths[i]);
    if (!s.isOk()) return Status(s.code(), names[i] + ": " + s.message());
    Identity id{i, {}, false, 0, 0};
    std::error_code ec;
    const fs::path resolved = fs::weakly_canonical(fs::absolute(paths[i], ec), ec);
    id.path = ec ? fs::path(paths[i]).lexically_normal().string() : resolved.string();
    struct stat st {};
    if (::stat(paths[i].c_str(), &st) == 0) {
      id.exists = true;
      id.dev = st.st_dev;
      id.ino = st.st_ino;
    }
    for (const Identity& o : seen)
      if (o.path == id.path || (o.exists && id.exists && o.dev == id.dev && o.ino == id.ino))
        return invalidArgument(names[i] + " " + displayPath(paths[i]) + " and " + names[o.index] + " " +
                               displayPath(paths[o.index]) + " are the same file; each output needs its own");
    seen.push_back(std::move(id));
  }
  return Status::ok();
}

void rememberInputFile(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode)) remember(st);
}

}  // namespace earshot
