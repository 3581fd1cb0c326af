// earshot: command-line front end. Subcommands register themselves; see command.h.
#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cmath>
#include <csignal>
#include <iostream>
#include <map>
#include <sstream>
#include <vector>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "command.h"
#include "earshot/earshot_version.h"
#include "earshot/core/math.h"
#include "earshot/io/input_file.h"
#include "earshot/io/temp_files.h"
#include "earshot/scene/gltf_loader.h"

namespace earshot::cli {
namespace {
std::vector<Setup>& registry() {
  static std::vector<Setup> r;
  return r;
}
int gExitCode = 0;
}  // namespace

Registrar::Registrar(Setup setup) { registry().push_back(std::move(setup)); }

CLI::App& subcommandGroup(CLI::App& parent, const std::string& name, const std::string& description) {
  for (CLI::App* existing : parent.get_subcommands([&](CLI::App* a) { return a->get_name() == name; }))
    return *existing;
  CLI::App* sub = parent.add_subcommand(name, description);
  sub->require_subcommand(1);
  return *sub;
}

void setExitCode(int code) { gExitCode = code; }

void printError(const std::string& message) {
  std::cerr << "earshot: error: " << message << "\n";
  gExitCode = 2;
}

bool check(const Status& status) {
  if (status.isOk()) return true;
  printError(status.message());
  return false;
}

Result<AirConditions> parseCliAir(const std::string& text) {
  auto air = parseAirConditions(text);
  if (!air.isOk()) return invalidArgument("--air: " + air.status().message());
  return air;
}

Result<SceneInputs> loadSceneInputs(const std::string& geometryPath, const std::string& materialsPath,
                                    const std::string& materialMapPath) {
  SceneInputs in;
  in.materials = defaultMaterials();
  if (!materialsPath.empty()) {
    auto m = loadMaterials(materialsPath);
    if (!m.isOk()) return m.status();
    in.materials = std::move(m.value());
  }
  std::map<std::string, std::string> materialMap;
  if (!materialMapPath.empty()) {
    auto m = loadMaterialMap(materialMapPath);
    if (!m.isOk()) return m.status();
    materialMap = std::move(m.value());
  }
  if (!geometryPath.empty()) {
    auto g = loadGltf(geometryPath, in.materials, materialMap);
    if (!g.isOk()) return g.status();
    for (const auto& w : g->warnings) warn(w, in.warnings);
    in.mesh = std::move(g->mesh);
  }
  auto tracer = RayTracer::create(in.mesh);
  if (!tracer.isOk()) return Status(tracer.status().code(), geometryPath + ": " + tracer.status().message());
  in.tracer = std::move(tracer.value());
  return in;
}

const CLI::Validator& kUnsigned64() {
  static const CLI::Validator v(
      [](std::string& text) -> std::string {
        const bool digits = !text.empty() && text.size() <= 20 &&
                            std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; });
        if (!digits) return "'" + text.substr(0, 32) + "' is not a whole number in [0, 2^64)";
        errno = 0;
        (void)std::strtoull(text.c_str(), nullptr, 10);
        if (errno == ERANGE) return "'" + text + "' is not a whole number in [0, 2^64)";
        return {};
      },
      "UINT64");
  return v;
}

void warn(const std::string& text, std::vector<std::string>& warnings) {
  std::cerr << "earshot: warning: " << text << "\n";
  warnings.push_back(text);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

double msSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

Vec3d ringPosition(const RayTracer& tracer, double angle) {
  const Vec3d lo(tracer.boundsMin()), hi(tracer.boundsMax());
  const Vec3d centre = (lo + hi) * 0.5, half = (hi - lo) * 0.5;
  return {centre.x + 0.6 * half.x * std::cos(angle), centre.y + 0.6 * half.y * std::sin(angle), centre.z};
}

CLI::Option* addVec3Option(CLI::App& app, const std::string& name, std::array<double, 3>& out,
                           const std::string& description) {
  auto* opt = app.add_option_function<std::string>(
      name,
      [&out, name](const std::string& text) {
        std::stringstream ss(text);
        std::string item;
        std::vector<double> v;
        while (std::getline(ss, item, ',')) {
          size_t used = 0;
          double d = 0;
          try {
            d = std::stod(item, &used);
          } catch (...) {
            throw CLI::ValidationError(name, "'" + text + "' is not X,Y,Z (three numbers)");
          }
          if (used != item.size()) throw CLI::ValidationError(name, "'" + text + "' is not X,Y,Z (three numbers)");
          if (!std::isfinite(d)) throw CLI::ValidationError(name, "'" + item + "' in '" + text + "' is not a finite number");
          if (std::fabs(d) > earshot::kMaxCoordinateMeters)
            throw CLI::ValidationError(name, "'" + item + "' in '" + text + "' is farther than 1e6 m from the origin");
          v.push_back(d);
        }
        if (v.size() != 3) throw CLI::ValidationError(name, "'" + text + "' has " + std::to_string(v.size()) + " values, expected X,Y,Z");
        out = {v[0], v[1], v[2]};
      },
      description);
  opt->type_name("X,Y,Z");
  return opt;
}

}  // namespace earshot::cli

int main(int argc, char** argv) {
#if defined(__GLIBC__)
  // Memory a trace or a synthesis frees stays in the process for the next
  // one. By default glibc maps large blocks afresh and trims the heap's top
  // back to the system, so every trace's histograms and every IR's buffers
  // were new pages again: ~760 page faults a shoebox trace, ~12 us each on a
  // virtual machine (docs/performance.md, fifteenth session). Blocks over
  // 32 MiB (glibc's most for this setting) are still mapped and unmapped.
  // The process keeps what it freed until it exits; what it may allocate at
  // once is still --max-memory's to limit.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
  // Ctrl-C or kill: the outputs' temporary files go too (temp_files.h).
  earshot::removeTempFilesOnTerminationSignals();
  // A file-size limit (ulimit -f) then fails the write (EFBIG: an error
  // naming the output, the temporary file removed) instead of killing.
  std::signal(SIGXFSZ, SIG_IGN);
  CLI::App app{"earshot: CPU audio propagation for VR spatial audio (impulse responses, rendering, analysis)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "earshot " EARSHOT_VERSION_STRING);
  app.footer(
      "Environment:\n"
      "  EARSHOT_CACHE_DIR   folder for prepared HRTF sets and late noises that later runs read instead of\n"
      "                      computing again ('off': none; default $XDG_CACHE_HOME/earshot or ~/.cache/earshot)\n"
      "  EARSHOT_HRTF_DIR    folder of the default HRTF set (default: share/earshot/hrtf next to the installed\n"
      "                      library, else the source tree's hrtf/)\n"
      "  EARSHOT_SOFA_PROBE  the program that reads a SOFA file earshot does not ship before it is loaded");
  // Limits on what input files may make earshot do (README "Untrusted
  // input"); given before or after the subcommand.
  app.fallthrough();
  app.add_option_function<std::string>(
         "--max-memory",
         [](const std::string& text) {
           auto bytes = earshot::parseByteSize(text);
           if (!bytes) throw CLI::ValidationError("--max-memory", bytes.status().message());
           auto limits = earshot::defaultInputLimits();
           limits.maxMemoryBytes = *bytes;
           earshot::setDefaultInputLimits(limits);
         },
         "Most memory an input file or an option may make earshot allocate (estimated first: triangles after "
         "instancing, samples after resampling, a render's sources, a trace's rays and histogram bins, an IR's "
         "synthesis), e.g. 512M, 4G (default 1G)")
      ->type_name("SIZE");
  app.add_flag_callback(
      "--allow-outside-paths",
      [] {
        auto limits = earshot::defaultInputLimits();
        limits.allowOutsidePaths = true;
        earshot::setDefaultInputLimits(limits);
      },
      "Let file references inside input files (glTF buffers, a scene's geometry, audio, materials, HRTF) lead "
      "outside the referring file's folder (absolute paths, ..); refused by default");
  for (auto& setup : earshot::cli::registry()) setup(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "earshot: error: " << e.what() << "\n";
    std::cerr << "Run with --help for usage.\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "earshot: error: " << e.what() << "\n";
    return 2;
  }
  return earshot::cli::gExitCode;
}
