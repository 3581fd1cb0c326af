// `earshot cache`: where the cache folder is and what it holds (prepared
// HRTF sets, late noises: README "The cache folder"); --clear empties it of
// earshot's files; --prepare prepares the default HRTF set into it (the
// build runs it to make the prepared set earshot installs).
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "command.h"
#include "earshot/core/status.h"
#include "earshot/hrtf/hrtf_set.h"
#include "earshot/io/disk_cache.h"
#include "earshot/io/input_file.h"

namespace earshot::cli {
namespace {

struct CacheOptions {
  bool clear = false;
  bool prepare = false;
};

// The rates the default set is prepared at (build time and --prepare).
constexpr double kPreparedRates[] = {44100.0, 48000.0};

/** Why nothing new can be kept in `folder`, or "" when earshot can write
 *  there (or make it: its nearest existing ancestor is a writable folder).
 *  Earshot itself then quietly prepares what it needs afresh each run. */
std::string unusableBecause(const std::string& folder) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::path p(folder);
  const fs::file_status st = fs::status(p, ec);
  if (fs::exists(st)) {
    if (!fs::is_directory(st)) return "it is not a folder";
    return ::access(folder.c_str(), W_OK | X_OK) == 0 ? "" : "the folder is not writable";
  }
  for (p = p.parent_path(); !p.empty(); p = p.parent_path()) {
    const fs::file_status up = fs::status(p, ec);
    if (!fs::exists(up)) {
      if (p == p.parent_path()) break;
      continue;
    }
    if (!fs::is_directory(up)) return "it cannot be made: " + displayPath(p.string()) + " is not a folder";
    if (::access(p.c_str(), W_OK | X_OK) != 0)
      return "it cannot be made: " + displayPath(p.string()) + " is not writable";
    return "";
  }
  return "";
}

void runCache(const CacheOptions& o) {
  const std::string folder = cacheFolder();
  if (folder.empty()) {
    if (o.prepare) {
      printError("no cache folder (EARSHOT_CACHE_DIR is \"off\" or empty, or no HOME): nothing to prepare into");
      return;
    }
    std::printf("no cache folder (EARSHOT_CACHE_DIR is \"off\" or empty, or no HOME): nothing is kept\n");
    return;
  }
  if (o.prepare) {
    auto path = hrtf::defaultHrtfPath();
    if (!path.isOk()) {
      printError(path.status().message());
      return;
    }
    for (double rate : kPreparedRates) {
      auto set = hrtf::HrtfSet::load(*path, rate);
      if (!set.isOk()) {
        printError(set.status().message());
        return;
      }
      std::printf("%s at %.0f Hz: %s\n", displayPath(*path).c_str(), rate,
                  (*set)->loadedFromCache() ? "already prepared" : "prepared");
    }
  }
  const auto files = listCacheFiles(folder);
  if (o.clear) {
    const size_t removed = clearCacheFiles(folder);
    std::printf("%s: removed %zu file%s\n", displayPath(folder).c_str(), removed, removed == 1 ? "" : "s");
    if (removed != files.size()) {
      printError(displayPath(folder) + ": " + std::to_string(files.size() - removed) + " files could not be removed");
    }
    return;
  }
  std::map<std::string, std::pair<size_t, uint64_t>> byKind;
  uint64_t total = 0;
  for (const auto& f : files) {
    auto& k = byKind[f.kind];
    ++k.first;
    k.second += f.bytes;
    total += f.bytes;
  }
  std::printf("%s: %zu file%s, %s\n", displayPath(folder).c_str(), files.size(), files.size() == 1 ? "" : "s",
              formatBytes(total).c_str());
  for (const auto& [kind, count] : byKind)
    std::printf("  %-8s %zu, %s\n", kind.c_str(), count.first, formatBytes(count.second).c_str());
  const std::string why = unusableBecause(folder);
  if (!why.empty())
    std::fprintf(stderr,
                 "earshot: warning: %s: %s, so nothing new is kept there and every run prepares HRTF sets and late "
                 "noises afresh (set EARSHOT_CACHE_DIR to a writable folder, or to 'off')\n",
                 displayPath(folder).c_str(), why.c_str());
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<CacheOptions>();
  CLI::App* cmd = root.add_subcommand(
      "cache", "Where the cache folder is and what it holds: HRTF sets and late noises prepared by earlier runs "
               "(EARSHOT_CACHE_DIR, else ~/.cache/earshot; 'off' for none)");
  cmd->add_flag("--clear", o->clear, "Remove earshot's files from it (entries and leftovers of interrupted writes; "
                                     "other files stay). Later runs prepare them again");
  cmd->add_flag("--prepare", o->prepare,
                "Prepare the default HRTF set (at 44.1 and 48 kHz) into it now, so that no later run pays for it")
      ->excludes("--clear");
  cmd->callback([o] { runCache(*o); });
});

}  // namespace
}  // namespace earshot::cli
