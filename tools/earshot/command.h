#pragma once
/** @file Subcommand registration for the `earshot` tool. Each cmd_*.cpp
 *  defines a static Registrar whose setup adds its subcommand (and sets the
 *  callback) to the root app. A callback reports failure by returning a
 *  non-zero code through setExitCode; errors print as one line through
 *  printError. Exit codes: 0 ok, 1 a judged failure (compare over
 *  tolerance), 2 an error (bad input, I/O). */
#include <CLI/CLI.hpp>

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "earshot/core/status.h"
#include "earshot/materials/material.h"
#include "earshot/propagation/air_absorption.h"
#include "earshot/scene/ray_tracer.h"

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

/** --air TEMP_C,HUMIDITY_PCT|off, the error naming the option. */
Result<AirConditions> parseCliAir(const std::string& text);

/** What a command needs of a scene: materials, and geometry in a tracer. */
struct SceneInputs {
  MaterialTable materials;
  TriangleMesh mesh;
  std::unique_ptr<RayTracer> tracer;
  std::vector<std::string> warnings;  ///< the loader's (already printed)
};

/** Prints "earshot: warning: <text>" on stderr and appends it to `warnings`
 *  (a command's --json lists them). */
void warn(const std::string& text, std::vector<std::string>& warnings);

/** Loads the materials (a file, or the built-in default set), the material
 *  map (optional) and the glTF geometry (empty path: free field), prints the
 *  loader's warnings and builds the tracer. */
Result<SceneInputs> loadSceneInputs(const std::string& geometryPath, const std::string& materialsPath,
                                    const std::string& materialMapPath);

/** Median of a non-empty set (benchmarks report medians: shared machines). */
double median(std::vector<double> values);

/** Wall time since `t`, in milliseconds. */
double msSince(std::chrono::steady_clock::time_point t);

/** The benchmarks' source placement: at `angle` (radians) on a horizontal
 *  ring (z up, as the samples) around the scene's centre, at 0.6 of its
 *  half extents. */
Vec3d ringPosition(const RayTracer& tracer, double angle);

/** Parses "X,Y,Z" (three finite numbers) for an option; a CLI11 validator
 *  rejects NaN/Inf and wrong counts with a message naming the option. */
CLI::Option* addVec3Option(CLI::App& app, const std::string& name, std::array<double, 3>& out,
                           const std::string& description);

/** A validator for whole numbers in [0, 2^64): refuses a sign ("-1" would
 *  wrap to 2^64 - 1), fractions and values that overflow, naming the text. */
const CLI::Validator& kUnsigned64();

}  // namespace earshot::cli
