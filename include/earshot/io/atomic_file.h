#pragma once
/** @file Write-to-temporary-then-rename, for every output file earshot writes. */
#include <functional>
#include <string>

#include "earshot/core/status.h"

namespace earshot {

/** Calls write(tmpPath) with a temporary path in the directory of `path`; on
 *  success renames it to `path`, on failure removes it. The target is never
 *  left partial. Refuses (before writing) a `path` that checkOutputPath
 *  refuses: an input file of this process, a directory, a FIFO, a device. */
Status writeFileAtomically(const std::string& path, const std::function<Status(const std::string& tmpPath)>& write);

/** Writes text through writeFileAtomically. */
Status writeTextFileAtomically(const std::string& path, const std::string& text);

}  // namespace earshot
