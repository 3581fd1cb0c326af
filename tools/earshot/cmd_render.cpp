// `earshot render`: a scene file to a binaural WAV.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "command.h"
#include "earshot/io/temp_files.h"
#include "earshot/io/wav.h"
#include "earshot/offline/render_scene.h"
#include "earshot/render/scene_file.h"

namespace earshot::cli {
namespace {

namespace fs = std::filesystem;

struct RenderCliOptions {
  std::string scene;
  std::string output;
  std::string quality;
  unsigned threads = 0;
  uint64_t seed = 0;
  double from = 0.0;
  double to = 0.0;
  bool strict = false;
  double minMove = 0.25;
  double minTurn = 5.0;
  int ambisonicOrder = 1;
  std::string outputFormat;
  std::string trace;
  bool quiet = false;
  double normalizeDbfs = 0.0;  // with --normalize
};

bool samePath(const std::string& a, const std::string& b) {
  std::error_code ea, eb;
  const fs::path pa = fs::weakly_canonical(fs::absolute(a), ea), pb = fs::weakly_canonical(fs::absolute(b), eb);
  return !ea && !eb && pa == pb;
}

std::string clock(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "--:--";
  const long s = long(seconds + 0.5);
  char buf[32];
  std::snprintf(buf, sizeof buf, "%ld:%02ld", s / 60, s % 60);
  return buf;
}

// Progress on stderr: a bar redrawn in place on a terminal, a plain line
// every 10 % otherwise.
class Progress {
 public:
  Progress(bool quiet) : mQuiet(quiet), mTerminal(isatty(STDERR_FILENO) == 1) {}
  void update(double fraction) {
    if (mQuiet) return;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - mStart).count();
    const double left = fraction > 0 ? elapsed * (1.0 - fraction) / fraction : NAN;
    if (mTerminal) {
      const int width = 30, filled = int(fraction * width + 0.5);
      std::fprintf(stderr, "\r[%s%s] %3.0f%%  elapsed %s  left %s ", std::string(size_t(filled), '#').c_str(),
                   std::string(size_t(width - filled), '.').c_str(), fraction * 100.0, clock(elapsed).c_str(),
                   clock(left).c_str());
      if (fraction >= 1.0) std::fprintf(stderr, "\n");
    } else if (fraction >= mNextLine || fraction >= 1.0) {
      std::fprintf(stderr, "earshot: render %3.0f%%, elapsed %s, about %s left\n", fraction * 100.0,
                   clock(elapsed).c_str(), clock(left).c_str());
      while (mNextLine <= fraction) mNextLine += 0.1;
    }
    std::fflush(stderr);
  }

 private:
  bool mQuiet, mTerminal;
  double mNextLine = 0.1;
  std::chrono::steady_clock::time_point mStart = std::chrono::steady_clock::now();
};

int run(const RenderCliOptions& o, const CLI::App& cmd) {
  SceneParseOptions po;
  po.strict = o.strict;
  std::vector<std::string> warnings;
  auto scene = loadSceneFile(o.scene, po, &warnings);
  if (!check(scene.status())) return 2;
  for (const auto& w : warnings) std::cerr << "earshot: warning: " << w << "\n";

  // Never overwrite an input.
  std::vector<std::string> inputs = {o.scene, scene->geometryPath, scene->materialsPath, scene->materialMapPath,
                                     scene->settings.hrtfPath};
  for (const auto& s : scene->sources) inputs.push_back(s.audioPath);
  // Remembered now (the audio is opened as the render reaches it): the
  // output's open then refuses a hard link to one, before rendering.
  for (const auto& in : inputs)
    if (!in.empty()) rememberInputFile(in);
  for (const auto& in : inputs)
    if (!in.empty() && samePath(in, o.output)) {
      printError("-o " + o.output + ": is an input of the scene (" + in + "); refusing to overwrite it");
      return 2;
    }

  RenderOptions ro;
  if (cmd.count("--quality")) ro.quality = o.quality;
  if (cmd.count("--seed")) ro.seed = o.seed;
  ro.threads = o.threads;
  ro.fromSeconds = o.from;
  if (cmd.count("--to")) ro.toSeconds = o.to;
  ro.minMoveMeters = o.minMove;
  ro.minTurnDegrees = o.minTurn;
  if (cmd.count("--ambisonic-order")) ro.ambisonicOrder = o.ambisonicOrder;
  if (cmd.count("--output-format")) ro.outputFormat = o.outputFormat;
  if (cmd.count("--trace")) ro.trace = o.trace;
  auto channels = renderOutputChannels(*scene, ro);
  if (!check(channels.status())) return 2;
  Progress progress(o.quiet);
  ro.progress = [&](double f) { progress.update(f); };
  // The output streams to a temporary file renamed at the end: a render of
  // any length holds no output in memory, and the target is never partial.
  // --normalize: a first pass into a float WAV beside the output (its peak
  // unknown until the end), then scaled into the output's own format.
  const bool normalize = cmd.count("--normalize") > 0;
  if (normalize && !check(audioFormatForPath(o.output).status())) return 2;
  const std::string firstPass = normalize ? o.output + ".first-pass-" + std::to_string(::getpid()) + ".wav" : o.output;
  struct Remove {
    std::string path;
    ~Remove() {
      if (!path.empty()) std::remove(path.c_str());
    }
  } removeFirstPass{normalize ? firstPass : std::string()};
  // And if a signal ends the program before that.
  std::optional<TempFileGuard> firstPassGuard;
  if (normalize) firstPassGuard.emplace(firstPass);
  auto writer = WavStreamWriter::open(firstPass, *channels, scene->settings.sampleRateHz);
  if (!check(writer.status())) return 2;
  ro.sink = [&](const float* const* planar, size_t n) { return (*writer)->write(planar, n); };
  auto result = renderScene(*scene, ro);
  if (!check(result.status())) return 2;
  const RenderResult& r = *result;
  if (!check((*writer)->commit())) return 2;
  double normalizeGain = 1.0;
  if (normalize) {
    auto final = WavStreamWriter::open(o.output, *channels, scene->settings.sampleRateHz);
    if (!check(final.status())) return 2;
    normalizeGain = r.peak > 0 ? std::pow(10.0, o.normalizeDbfs / 20.0) / r.peak : 1.0;
    if (!check(appendScaled(firstPass, float(normalizeGain), **final)) || !check((*final)->commit())) return 2;
    writer = std::move(final);
    std::fprintf(stderr, "earshot: normalised: peak %.2f dBFS -> %.2f dBFS (gain %+.2f dB)\n",
                 20.0 * std::log10(std::max(r.peak, 1e-30)), o.normalizeDbfs, 20.0 * std::log10(normalizeGain));
  }
  for (const auto& line : r.log)  // warnings even with --quiet
    if (!o.quiet || line.rfind("warning:", 0) == 0) std::cerr << "earshot: " << line << "\n";
  if (!o.quiet) {
    std::fprintf(stderr,
                 "earshot: rendered %.2f s of audio in %.2f s (%.1fx real time; simulation %.2f s for %llu source IRs, "
                 "audio %.2f s) to %s\n",
                 r.audioSeconds, r.wallSeconds, r.audioSeconds / std::max(r.wallSeconds, 1e-9), r.simulationSeconds,
                 (unsigned long long)r.simulations, r.audioProcessSeconds, o.output.c_str());
    std::fprintf(stderr, "earshot: peak %.2f dBFS (%.4f)\n", 20.0 * std::log10(std::max(r.peak, 1e-30)), r.peak);
  }
  if ((*writer)->clippedSamples() > 0)
    std::fprintf(stderr,
                 "earshot: warning: %llu samples beyond full scale were clipped in %s (%s); lower the sources' "
                 "gain_db, or write .wav (float keeps them)\n",
                 (unsigned long long)(*writer)->clippedSamples(), o.output.c_str(), (*writer)->format().name);
  else if (r.clipped && !normalize)
    std::fprintf(stderr,
                 "earshot: warning: the peak %.3f (%+.2f dBFS) exceeds full scale; the float WAV keeps it, but lower "
                 "the sources' gain_db to play it without clipping\n",
                 r.peak, 20.0 * std::log10(r.peak));
  return 0;
}

const Registrar registrar([](CLI::App& root) {
  auto o = std::make_shared<RenderCliOptions>();
  CLI::App* cmd = root.add_subcommand(
      "render",
      "Render a scene file (moving sources and listener) to binaural or ambisonic audio: WAV, FLAC or Ogg "
      "(docs/scene-format.md)");
  cmd->add_option("scene", o->scene, "Scene file (JSON)")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", o->output,
                  "Output audio, 2 channels (left, right) or with --output-format ambisonic the AmbiX channels, format by extension: .wav (32-bit float; also for a name without one), .flac (24-bit), "
                  ".ogg (Vorbis; FLAC and Ogg clip beyond full scale, and say how many samples). Written to a "
                  "temporary file and renamed at the end: an existing file is replaced only on success")
      ->required();
  cmd->add_option("--quality", o->quality, "Override the scene's preset: draft | balanced | high | reference")
      ->check(CLI::IsMember({"draft", "balanced", "high", "reference"}));
  cmd->add_option("--threads", o->threads, "Tracing threads (0 = all cores); the output does not depend on it")
      ->check(CLI::Range(0u, 256u))
      ->capture_default_str();
  cmd->add_option("--seed", o->seed, "Override the scene's random seed")->check(kUnsigned64());
  cmd->add_option("--from", o->from, "Start of the rendered window, seconds of scene time (reverberation from up to "
                                     "2 s before it is included)")
      ->check(CLI::Range(0.0, 86400.0))
      ->capture_default_str();
  cmd->add_option("--to", o->to, "End of the rendered window, seconds (default: the scene's duration)")
      ->check(CLI::Range(0.0, 86400.0));
  cmd->add_option("--min-move", o->minMove,
                  "Re-simulate a source's reflections only after it or the listener moved this far (m; 0: any "
                  "change). The direct sound follows every block")
      ->check(CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  cmd->add_option("--min-turn", o->minTurn,
                  "... or the listener turned this far (degrees; 0: any change). Applies only to binaural "
                  "reflections (--ambisonic-order 0): ambisonic ones follow the head every block")
      ->check(CLI::Range(0.0, 180.0))
      ->capture_default_str();
  cmd->add_option("--output-format", o->outputFormat,
                  "Override the scene's settings.output: binaural (2 channels, the default) or ambisonic "
                  "((order+1)^2 AmbiX channels, ACN order, SN3D, in the listener's frame: x forward, y left, z up)")
      ->check(CLI::IsMember({"binaural", "ambisonic"}));
  cmd->add_option("--trace", o->trace,
                  "Override the scene's settings.trace: shared (the sources simulated together share one trace "
                  "from the listener, by reciprocity the same energies), per-source (a trace from each) or auto "
                  "(the default: shared for 3 sources or more, and for any number when the listener stays in place, "
                  "whose paths are then kept and reused)")
      ->check(CLI::IsMember({"auto", "shared", "per-source"}));
  cmd->add_option("--ambisonic-order", o->ambisonicOrder,
                  "Override the scene's settings.ambisonic_order (default 1): 1-3 world-frame ambisonic "
                  "reflections rotated by the head every block, so a head turn needs no simulation; 0 a binaural "
                  "IR per source with each arrival's exact HRTF, simulated again after --min-turn degrees")
      ->check(CLI::Range(0, 3));
  cmd->add_option("--normalize", o->normalizeDbfs,
                  "Scale the whole output so that its peak is at this level (dBFS, e.g. -1), reported on stderr; "
                  "two passes through a temporary float WAV beside the output (default: no scaling, the levels "
                  "stay physical and a peak over full scale is warned about)")
      ->check(CLI::Range(-120.0, 0.0));
  cmd->add_flag("--strict", o->strict, "Unknown keys in the scene file are errors (default: warnings)");
  cmd->add_flag("-q,--quiet", o->quiet, "No progress, log or summary on stderr (errors and clipping warnings remain)");
  cmd->callback([o, cmd] { setExitCode(run(*o, *cmd)); });
});

}  // namespace
}  // namespace earshot::cli
