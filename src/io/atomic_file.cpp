#include "earshot/io/atomic_file.h"

#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <random>

#include "earshot/io/input_file.h"
#include "earshot/io/temp_files.h"

namespace earshot {

Status writeFileAtomically(const std::string& path, const std::function<Status(const std::string&)>& write) {
  // Never replace an input of this process, a directory, a FIFO or a device.
  EARSHOT_RETURN_IF_ERROR(checkOutputPath(path));
  // Unique name in the same directory (rename is atomic only within a filesystem).
  std::random_device rd;
  std::string tmp = path + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(rd());
  const TempFileGuard guard(tmp);  // removed if a signal ends the program meanwhile
  Status s = write(tmp);
  if (!s.isOk()) {
    std::remove(tmp.c_str());
    return s;
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    return ioError(path + ": cannot write (rename failed)");
  }
  return Status::ok();
}

Status writeTextFileAtomically(const std::string& path, const std::string& text) {
  return writeFileAtomically(path, [&](const std::string& tmp) -> Status {
    std::ofstream f(tmp, std::ios::binary);
    if (!f) return ioError(path + ": cannot open for writing");
    f << text;
    f.close();
    if (!f) return ioError(path + ": write failed");
    return Status::ok();
  });
}

}  // namespace earshot
