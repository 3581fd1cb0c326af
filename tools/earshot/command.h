#pragma once
/** @file Subcommand registration for the `earshot` tool. Each cmd_*.cpp
 *  defines a static Registrar whose setup adds its subcommand (and sets the
 *  callback) to the root app. A callback reports failure by returning a
 *  non-zero code through setExitCode; errors print as one line through
 *  printError. Exit codes: 0 ok, 1 a judged failure (compare over
 *  tolerance), 2 an error (bad input, I/O). */
#include <CLI/CLI.hpp>

#include <functional>
#include <string>

#include "earshot/core/status.h"

namespace earshot::cli {

using Setup = std::function<void(CLI::App& root)>;

struct Registrar {
  explicit Registrar(Setup setup);
};

/** Gets or creates a grouping subcommand (e.g. "bench") under `parent`. */
CLI::App& subcommandGroup(CLI::App& parent, const std::string& name, const std::string& description);

void setExitCode(int code);
/** Prints "earshot: error: <message>" on stderr and sets exit code 2. */
void printError(const std::string& message);
/** printError(status.message()) unless ok; returns status.isOk(). */
bool check(const Status& status);

/** Parses "X,Y,Z" (three finite numbers) for an option; a CLI11 validator
 *  rejects NaN/Inf and wrong counts with a message naming the option. */
CLI::Option* addVec3Option(CLI::App& app, const std::string& name, std::array<double, 3>& out,
                           const std::string& description);

}  // namespace earshot::cli
