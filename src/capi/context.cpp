// The C API's context (engine, listener, simulation, audio) and sources.
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <future>
#include <string>

#include "capi_internal.h"
#include "earshot/core/thread_pool.h"
#include "earshot/hrtf/hrtf_set.h"
#include "earshot/ir/binaural_synthesis.h"
#include "earshot/propagation/image_sources.h"

namespace earshot::capi {

namespace {

// Largest block earshot_process accepts (2^24 frames: ~350 s at 48 kHz); a
// bound that catches sizes that are garbage rather than limits real use.
constexpr size_t kMaxProcessFrames = size_t(1) << 24;

/** The convolver's block for a requested block size: the smallest even
 *  2^a 3^b 5^c number >= max(requested, 8) (KissFFT allocates inside its
 *  transform for other prime factors, which the audio thread must not). */
uint32_t convolverBlock(uint32_t requested) {
  for (uint32_t m = std::max<uint32_t>(requested, 8);; ++m) {
    if (m % 2 != 0) continue;
    uint32_t rest = m;
    for (uint32_t f : {2u, 3u, 5u})
      while (rest % f == 0) rest /= f;
    if (rest == 1) return m;
  }
}

std::string checkSettings(const earshot_context_settings& s) {
  if (s.flags & ~uint32_t(EARSHOT_CONTEXT_VALIDATION))
    return "settings->flags has unknown bits " + std::to_string(s.flags);
  // Every context loads an HRTF (binaural reflections, the decoder, the
  // direct sound), which is prepared at 8-192 kHz.
  if (!(s.sample_rate_hz >= 8000.0 && s.sample_rate_hz <= 192000.0))
    return "settings->sample_rate_hz " + describe(s.sample_rate_hz) + " is outside [8000, 192000]";
  if (s.block_frames < 1 || s.block_frames > 65536)
    return "settings->block_frames " + std::to_string(s.block_frames) + " is outside [1, 65536]";
  if (s.max_sources < 1 || s.max_sources > 4096)
    return "settings->max_sources " + std::to_string(s.max_sources) + " is outside [1, 4096]";
  if (!(s.max_ir_seconds > 0.0 && s.max_ir_seconds <= 60.0))
    return "settings->max_ir_seconds " + describe(s.max_ir_seconds) + " is outside (0, 60]";
  if (s.rays < 1 || s.rays > 100000000) return "settings->rays " + std::to_string(s.rays) + " is outside [1, 1e8]";
  if (s.bounces > 100000) return "settings->bounces " + std::to_string(s.bounces) + " is outside [0, 100000]";
  if (s.image_source_order > kMaxImageSourceOrder)
    return "settings->image_source_order " + std::to_string(s.image_source_order) + " is outside [0, " +
           std::to_string(kMaxImageSourceOrder) + "]";
  if (s.threads > 256) return "settings->threads " + std::to_string(s.threads) + " is outside [0, 256]";
  if (!(s.max_distance_meters > 0.0 && s.max_distance_meters <= 20000.0))
    return "settings->max_distance_meters " + describe(s.max_distance_meters) + " is outside (0, 20000]";
  const int64_t level = rawEnum(s.log_level);
  if (level < EARSHOT_LOG_ERROR || level > EARSHOT_LOG_DEBUG)
    return "settings->log_level " + std::to_string(level) + " is not an earshot_log_level";
  if ((s.allocate == nullptr) != (s.free == nullptr))
    return "settings->allocate and settings->free must both be set or both NULL";
  if (s.ambisonic_order > uint32_t(kMaxAmbisonicOrder))
    return "settings->ambisonic_order " + std::to_string(s.ambisonic_order) + " is outside [0, 3]";
  const int64_t format = rawEnum(s.output_format);
  if (format != EARSHOT_OUTPUT_BINAURAL && format != EARSHOT_OUTPUT_AMBISONIC)
    return "settings->output_format " + std::to_string(format) + " is not an earshot_output_format";
  if (format == EARSHOT_OUTPUT_AMBISONIC && s.ambisonic_order == 0)
    return "settings->output_format EARSHOT_OUTPUT_AMBISONIC needs settings->ambisonic_order 1-3, not 0";
  const int64_t trace = rawEnum(s.trace_mode);
  if (trace != EARSHOT_TRACE_AUTO && trace != EARSHOT_TRACE_SHARED && trace != EARSHOT_TRACE_PER_SOURCE)
    return "settings->trace_mode " + std::to_string(trace) + " is not an earshot_trace_mode";
  return "";
}

Env envOf(const earshot_context_settings& s) {
  Env e;
  e.log = s.log;
  e.logUser = s.log_user_data;
  // Called before the settings are checked (their errors go to this log).
  const int64_t level = rawEnum(s.log_level);
  e.level = level >= EARSHOT_LOG_ERROR && level <= EARSHOT_LOG_DEBUG ? earshot_log_level(level) : EARSHOT_LOG_ERROR;
  e.allocate = s.allocate;
  e.free = s.free;
  e.allocUser = s.allocator_user_data;
  e.validation = (s.flags & EARSHOT_CONTEXT_VALIDATION) != 0;
  return e;
}

/** Hands the followed scene's latest commit to the engine if it is new. */
void syncScene(earshot_context* c) {
  std::lock_guard<std::mutex> lock(c->sceneMutex);
  uint64_t version = 0;
  std::shared_ptr<const RayTracer> tracer;
  std::shared_ptr<const MaterialTable> materials;
  if (c->scene) {
    std::lock_guard<std::mutex> publish(c->scene->publishMutex);
    version = c->scene->version;
    tracer = c->scene->snapshot;
    materials = c->scene->snapshotMaterials;
  }
  if (c->appliedAny && version == c->appliedVersion) return;
  c->engine->setScene(std::move(tracer), std::move(materials));
  c->appliedVersion = version;
  c->appliedAny = true;
}

/** One simulation step (earshot_simulate and the built-in thread). */
Status step(earshot_context* c, uint32_t count) {
  std::lock_guard<std::mutex> lock(c->stepMutex);
  syncScene(c);
  Status s = c->engine->simulate(count);
  const runtime::SimulationStats stats = c->engine->lastSimulation();
  c->lastStepSources = stats.sourcesSimulated;
  c->lastStepMs = stats.totalMs;
  return s;
}

void simulationLoop(earshot_context* c, double rateHz, uint32_t count) {
  lowerThisThreadsPriority(runtime::EngineSettings{}.workerNice);  // below the audio thread, as the workers
  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / rateHz));
  auto next = Clock::now();
  std::unique_lock<std::mutex> lock(c->threadMutex);
  while (!c->threadStop) {
    lock.unlock();
    try {
      Status s = step(c, count);
      if (!s.isOk()) c->env.logMessage(EARSHOT_LOG_ERROR, "simulation thread: " + s.message());
    } catch (const std::exception& e) {
      c->env.logMessage(EARSHOT_LOG_ERROR, std::string("simulation thread: ") + e.what());
    } catch (...) {
      c->env.logMessage(EARSHOT_LOG_ERROR, "simulation thread: unexpected exception");
    }
    lock.lock();
    // An overrunning step delays the next one instead of queueing a burst.
    next += period;
    const auto now = Clock::now();
    if (next < now) next = now;
    c->threadWake.wait_until(lock, next, [c] { return c->threadStop; });
  }
}

void stopThread(earshot_context* c) {
  std::lock_guard<std::mutex> control(c->threadControl);
  if (!c->thread.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(c->threadMutex);
    c->threadStop = true;
  }
  c->threadWake.notify_all();
  c->thread.join();
  c->threadRunning.store(false);
}

}  // namespace

void releaseContext(earshot_context* c) {
  if (c->refs.fetch_sub(1, std::memory_order_acq_rel) == 1) destroy(c);
}

}  // namespace earshot::capi

using namespace earshot;
using namespace earshot::capi;

earshot_context::~earshot_context() {
  stopThread(this);
  if (scene) releaseScene(scene);
  scene = nullptr;
  engine.reset();
}

extern "C" {

earshot_status earshot_context_settings_init(earshot_context_settings* s) {
  if (!s) return argError(nullptr, "earshot_context_settings_init", "settings is NULL");
  *s = earshot_context_settings{};
  s->struct_size = sizeof(earshot_context_settings);
  s->flags = 0;
  s->sample_rate_hz = 48000.0;
  s->block_frames = 256;
  s->max_sources = 32;
  s->max_ir_seconds = 3.0;
  const OmniIrSettings defaults;
  s->rays = defaults.rays;
  s->bounces = defaults.bounces;
  s->image_source_order = defaults.imageSourceOrder;
  s->threads = 0;
  s->seed = defaults.seed;
  s->max_distance_meters = 343.0;
  s->hrtf_path = nullptr;
  s->log = nullptr;
  s->log_user_data = nullptr;
  s->log_level = EARSHOT_LOG_WARNING;
  s->allocate = nullptr;
  s->free = nullptr;
  s->allocator_user_data = nullptr;
  s->ambisonic_order = uint32_t(runtime::EngineSettings{}.ambisonicOrder);
  s->output_format = EARSHOT_OUTPUT_BINAURAL;
  s->trace_mode = EARSHOT_TRACE_AUTO;
  return EARSHOT_OK;
}

earshot_status earshot_context_create(const earshot_context_settings* settings, earshot_context** out) {
  static const char* kFn = "earshot_context_create";
  if (out) *out = nullptr;
  if (!settings) return argError(nullptr, kFn, "settings is NULL");
  return guard(nullptr, kFn, [&]() -> earshot_status {
    const std::string badSize = checkStructSize(settings->struct_size, sizeof(earshot_context_settings), "settings");
    if (!badSize.empty()) return argError(nullptr, kFn, badSize);
    const Env env = envOf(*settings);
    return guard(&env, kFn, [&]() -> earshot_status {
      if (!out) return argError(&env, kFn, "out is NULL");
      const std::string bad = checkSettings(*settings);
      if (!bad.empty()) return argError(&env, kFn, bad);
      const std::string hrtfPath = settings->hrtf_path ? settings->hrtf_path : "";

      // The HRTF loads in the background (~0.5 s for the default set): the
      // context is ready at once and the first earshot_source_create or
      // binaural IR waits for the load and reports its error. A file that is
      // missing or unreadable is refused here.
      std::string resolved = hrtfPath;
      if (resolved.empty()) {
        auto def = hrtf::defaultHrtfPath();
        if (!def.isOk()) return fromStatus(&env, kFn, def.status());
        resolved = *def;
      }
      {
        struct stat st {};
        if (::stat(resolved.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || ::access(resolved.c_str(), R_OK) != 0)
          return fromStatus(&env, kFn, notFound("HRTF " + resolved + " is not a readable file"));
      }
      const double rate = settings->sample_rate_hz;
      runtime::BinauralModelFuture model =
          std::async(std::launch::async, [resolved, rate]() -> Result<std::shared_ptr<const BinauralModel>> {
            try {
              return loadBinauralModel(resolved, rate);
            } catch (const std::bad_alloc&) {
              return outOfRange("HRTF " + resolved + ": out of memory while loading it");
            } catch (const std::exception& e) {
              return Status(StatusCode::kInternal, "HRTF " + resolved + ": " + e.what());
            }
          }).share();

      runtime::EngineSettings es;
      es.sampleRateHz = settings->sample_rate_hz;
      es.blockFrames = convolverBlock(settings->block_frames);
      es.maxSources = settings->max_sources;
      es.maxIrSeconds = settings->max_ir_seconds;
      es.simulation.rays = settings->rays;
      es.simulation.bounces = settings->bounces;
      es.simulation.imageSourceOrder = settings->image_source_order;
      es.simulation.seed = settings->seed;
      es.threads = settings->threads;
      es.maxDistanceMeters = settings->max_distance_meters;
      es.ambisonicOrder = int(settings->ambisonic_order);
      es.output = settings->output_format == EARSHOT_OUTPUT_AMBISONIC ? runtime::OutputFormat::kAmbisonic
                                                                      : runtime::OutputFormat::kBinaural;
      es.traceMode = settings->trace_mode == EARSHOT_TRACE_PER_SOURCE ? TraceMode::kPerSource
                     : settings->trace_mode == EARSHOT_TRACE_SHARED   ? TraceMode::kShared
                                                                      : TraceMode::kAuto;
      auto engine = runtime::Engine::create(es, model);
      if (!engine.isOk()) return fromStatus(&env, kFn, engine.status());

      earshot_context* c = create<earshot_context>(env);
      c->engine = std::move(engine.value());
      c->sampleRateHz = settings->sample_rate_hz;
      c->blockFrames = settings->block_frames;
      c->maxSources = settings->max_sources;
      try {
        c->inputs.assign(settings->max_sources, nullptr);
      } catch (...) {
        destroy(c);
        throw;
      }
      env.logMessage(EARSHOT_LOG_INFO, std::string(kFn) + ": HRTF " + (hrtfPath.empty() ? "(default)" : hrtfPath) +
                                           ", " + describe(settings->sample_rate_hz) + " Hz, " +
                                           std::to_string(settings->max_sources) + " source slots");
      *out = c;
      return EARSHOT_OK;
    });
  });
}

earshot_status earshot_context_retain(earshot_context* c) {
  return retainHandle(c, "earshot_context_retain", "context");
}

earshot_status earshot_context_release(earshot_context* c) {
  return releaseHandle(c, "earshot_context_release", "context", releaseContext);
}

earshot_status earshot_context_get_info(earshot_context* c, earshot_context_info* info) {
  static const char* kFn = "earshot_context_get_info";
  if (!alive(c)) return argError(nullptr, kFn, "context is not a live earshot_context");
  if (!info) return argError(&c->env, kFn, "info is NULL");
  return guard(&c->env, kFn, [&]() -> earshot_status {
    const std::string badSize = checkStructSize(info->struct_size, sizeof(earshot_context_info), "info");
    if (!badSize.empty()) return argError(&c->env, kFn, badSize);
    earshot_context_info i{};
    i.struct_size = sizeof(earshot_context_info);
    i.sample_rate_hz = c->sampleRateHz;
    i.block_frames = c->blockFrames;
    i.max_sources = c->maxSources;
    i.latency_frames = uint32_t(c->engine->latencyFrames());
    {
      std::lock_guard<std::mutex> lock(c->sourcesMutex);
      i.active_sources = c->activeSources;
    }
    i.simulation_thread_running = c->threadRunning.load() ? 1 : 0;
    {
      std::lock_guard<std::mutex> lock(c->stepMutex);
      i.last_simulation_sources = c->lastStepSources;
      i.last_simulation_ms = c->lastStepMs;
    }
    const runtime::ContainmentStats contained = c->engine->containment();
    i.muted_source_blocks = contained.mutedSourceChunks;
    i.cleared_output_blocks = contained.clearedOutputChunks;
    const runtime::EngineSettings& es = c->engine->settings();
    i.ambisonic_order = uint32_t(es.ambisonicOrder);
    i.output_format = es.output == runtime::OutputFormat::kAmbisonic ? EARSHOT_OUTPUT_AMBISONIC : EARSHOT_OUTPUT_BINAURAL;
    i.output_channels = uint32_t(c->engine->outputChannels());
    i.trace_mode = es.traceMode == TraceMode::kPerSource ? EARSHOT_TRACE_PER_SOURCE
                   : es.traceMode == TraceMode::kShared  ? EARSHOT_TRACE_SHARED
                                                         : EARSHOT_TRACE_AUTO;
    *info = i;
    return EARSHOT_OK;
  });
}

earshot_status earshot_context_set_listener(earshot_context* c, earshot_vec3 position, earshot_vec3 forward,
                                            earshot_vec3 up) {
  static const char* kFn = "earshot_context_set_listener";
  if (!alive(c)) return argError(nullptr, kFn, "context is not a live earshot_context");
  return guard(&c->env, kFn, [&]() -> earshot_status {
    for (auto [v, name] : {std::pair{position, "position"}, std::pair{forward, "forward"}, std::pair{up, "up"}}) {
      const std::string bad = checkVec3(v, name);
      if (!bad.empty()) return argError(&c->env, kFn, bad);
    }
    ListenerOrientation o;
    o.forward = {forward.x, forward.y, forward.z};
    o.up = {up.x, up.y, up.z};
    const Status valid = validate(o);
    if (!valid.isOk()) return argError(&c->env, kFn, "forward/up: " + valid.message());
    return fromStatus(&c->env, kFn, c->engine->setListener({position.x, position.y, position.z}, o));
  });
}

earshot_status earshot_context_set_scene(earshot_context* c, earshot_scene* scene) {
  static const char* kFn = "earshot_context_set_scene";
  if (!alive(c)) return argError(nullptr, kFn, "context is not a live earshot_context");
  if (scene && !alive(scene)) return argError(&c->env, kFn, "scene is not NULL and not a live earshot_scene");
  return guard(&c->env, kFn, [&] {
    earshot_scene* old = nullptr;
    {
      std::lock_guard<std::mutex> lock(c->sceneMutex);
      if (scene) scene->refs.fetch_add(1, std::memory_order_relaxed);
      old = c->scene;
      c->scene = scene;
      c->appliedAny = false;
    }
    syncScene(c);
    if (old) releaseScene(old);
    return EARSHOT_OK;
  });
}

earshot_status earshot_simulate(earshot_context* c, uint32_t sourceCount) {
  static const char* kFn = "earshot_simulate";
  if (!alive(c)) return argError(nullptr, kFn, "context is not a live earshot_context");
  return guard(&c->env, kFn, [&]() -> earshot_status {
    if (c->threadRunning.load())
      return fail(&c->env, kFn, EARSHOT_ERROR_INVALID_STATE, "the built-in simulation thread is running");
    return fromStatus(&c->env, kFn, step(c, sourceCount));
  });
}

earshot_status earshot_context_start_simulation(earshot_context* c, double rateHz, uint32_t sourcesPerStep) {
  static const char* kFn = "earshot_context_start_simulation";
  if (!alive(c)) return argError(nullptr, kFn, "context is not a live earshot_context");
  return guard(&c->env, kFn, [&]() -> earshot_status {
    // At least a step every 1000 s: a period of 1 / 1e-40 s overflowed the
    // clock's 64-bit nanoseconds (undefined; the thread then stepped in a loop).
    if (!(rateHz >= 0.001 && rateHz <= 1000.0))
      return argError(&c->env, kFn, "rate_hz " + describe(rateHz) + " is outside [0.001, 1000]");
    std::lock_guard<std::mutex> control(c->threadControl);
    if (c->thread.joinable())
      return fail(&c->env, kFn, EARSHOT_ERROR_INVALID_STATE, "the simulation thread is already running");
    {
      std::lock_guard<std::mutex> lock(c->threadMutex);
      c->threadStop = false;
    }
    try {
      c->thread = std::thread(simulationLoop, c, rateHz, sourcesPerStep);
    } catch (const std::system_error& e) {
      return fail(&c->env, kFn, EARSHOT_ERROR_OUT_OF_MEMORY, std::string("cannot start a thread: ") + e.what());
    }
    c->threadRunning.store(true);
    return EARSHOT_OK;
  });
}

earshot_status earshot_context_stop_simulation(earshot_context* c) {
  static const char* kFn = "earshot_context_stop_simulation";
  if (!alive(c)) return argError(nullptr, kFn, "context is not a live earshot_context");
  return guard(&c->env, kFn, [&] {
    stopThread(c);
    return EARSHOT_OK;
  });
}

earshot_status earshot_process(earshot_context* c, const float* const* inputs, size_t inputCount, float* left,
                               float* right, size_t frames) {
  // The audio thread: no allocation, lock or log here, so no guard() (which
  // may format a message); the engine's process() does not throw.
  if (!alive(c)) return EARSHOT_ERROR_INVALID_ARGUMENT;
  if (c->engine->outputChannels() != 2) return EARSHOT_ERROR_INVALID_STATE;  // ambisonic output: earshot_process_channels
  float* outputs[2] = {left, right};
  return earshot_process_channels(c, inputs, inputCount, outputs, 2, frames);
}

earshot_status earshot_process_channels(earshot_context* c, const float* const* inputs, size_t inputCount,
                                        float* const* outputs, size_t outputCount, size_t frames) {
  // The audio thread: as earshot_process, no allocation, lock or log.
  if (!alive(c)) return EARSHOT_ERROR_INVALID_ARGUMENT;
  if (inputCount > c->maxSources || (inputCount > 0 && !inputs)) return EARSHOT_ERROR_INVALID_ARGUMENT;
  if (frames > kMaxProcessFrames) return EARSHOT_ERROR_INVALID_ARGUMENT;
  if (!outputs || outputCount != c->engine->outputChannels()) return EARSHOT_ERROR_INVALID_ARGUMENT;
  if (frames == 0) return EARSHOT_OK;
  const uintptr_t bytes = frames * sizeof(float);
  for (size_t a = 0; a < outputCount; ++a) {
    if (!outputs[a]) return EARSHOT_ERROR_INVALID_ARGUMENT;
    for (size_t b = 0; b < a; ++b) {
      const uintptr_t x = reinterpret_cast<uintptr_t>(outputs[a]), y = reinterpret_cast<uintptr_t>(outputs[b]);
      if ((x < y ? y - x : x - y) < bytes) return EARSHOT_ERROR_INVALID_ARGUMENT;  // overlapping outputs
    }
  }
  // An input may be an output (in place: the engine reads each chunk's
  // input before it writes that chunk); any other overlap would be read
  // after it was written.
  for (size_t i = 0; i < inputCount; ++i) {
    if (!inputs[i]) continue;
    const uintptr_t x = reinterpret_cast<uintptr_t>(inputs[i]);
    for (size_t a = 0; a < outputCount; ++a) {
      const uintptr_t y = reinterpret_cast<uintptr_t>(outputs[a]);
      if (x != y && (x < y ? y - x : x - y) < bytes) return EARSHOT_ERROR_INVALID_ARGUMENT;
    }
  }
  for (size_t i = 0; i < c->maxSources; ++i) c->inputs[i] = i < inputCount ? inputs[i] : nullptr;
  c->engine->process(c->inputs.data(), outputs, frames);
  return EARSHOT_OK;
}

// ---- sources ----

earshot_status earshot_source_settings_init(earshot_source_settings* s) {
  if (!s) return argError(nullptr, "earshot_source_settings_init", "settings is NULL");
  *s = earshot_source_settings{};
  s->struct_size = sizeof(earshot_source_settings);
  s->gain_db = 0.0f;
  s->direct = EARSHOT_DIRECT_PER_BLOCK;
  s->direct_gain_db = 0.0f;
  s->reflections_gain_db = 0.0f;
  s->distance_model = EARSHOT_DISTANCE_PHYSICAL;
  s->min_distance = 1.0f;
  s->max_distance = 100.0f;
  s->rolloff = 1.0f;
  s->occlusion = EARSHOT_OCCLUSION_RAY;
  s->radius = 0.5f;
  s->transmission = 1;
  s->priority = 0;
  s->directivity_alpha = 0.0f;
  s->directivity_sharpness = 1.0f;
  return EARSHOT_OK;
}

}  // extern "C": C++ helpers (clang warns of C linkage on a function returning std::string)

namespace {

/** The runtime's settings from the C struct, or a message naming the field. */
std::string toRuntime(const earshot_source_settings& s, runtime::SourceSettings& rs) {
  auto gainOk = [](float db) { return db >= -120.0f && db <= 40.0f; };
  if (!gainOk(s.gain_db)) return "settings->gain_db " + describe(s.gain_db) + " is outside [-120, 40]";
  if (!gainOk(s.direct_gain_db)) return "settings->direct_gain_db " + describe(s.direct_gain_db) + " is outside [-120, 40]";
  if (!gainOk(s.reflections_gain_db))
    return "settings->reflections_gain_db " + describe(s.reflections_gain_db) + " is outside [-120, 40]";
  const int64_t direct = rawEnum(s.direct);
  if (direct != EARSHOT_DIRECT_PER_BLOCK && direct != EARSHOT_DIRECT_IN_IMPULSE_RESPONSE)
    return "settings->direct " + std::to_string(direct) + " is not an earshot_direct_mode";
  const int64_t model = rawEnum(s.distance_model);
  if (model < EARSHOT_DISTANCE_PHYSICAL || model > EARSHOT_DISTANCE_TABLE)
    return "settings->distance_model " + std::to_string(model) + " is not an earshot_distance_model";
  const int64_t occlusion = rawEnum(s.occlusion);
  if (occlusion < EARSHOT_OCCLUSION_RAY || occlusion > EARSHOT_OCCLUSION_VOLUMETRIC)
    return "settings->occlusion " + std::to_string(occlusion) + " is not an earshot_occlusion_mode";
  if (!(s.min_distance > 0.0f && s.min_distance <= 1e6f))
    return "settings->min_distance " + describe(s.min_distance) + " is outside (0, 1e6]";
  if (!(s.max_distance >= s.min_distance && s.max_distance <= 1e6f))
    return "settings->max_distance " + describe(s.max_distance) + " is not in [min_distance, 1e6]";
  if (!(s.rolloff >= 0.0f && s.rolloff <= 100.0f)) return "settings->rolloff " + describe(s.rolloff) + " is outside [0, 100]";
  if (!(s.radius > 0.0f && s.radius <= 100.0f)) return "settings->radius " + describe(s.radius) + " is outside (0, 100]";
  if (!(s.directivity_alpha >= 0.0f && s.directivity_alpha <= 1.0f))
    return "settings->directivity_alpha " + describe(s.directivity_alpha) + " is outside [0, 1]";
  if (!(s.directivity_sharpness >= 1.0f && s.directivity_sharpness <= 16.0f))
    return "settings->directivity_sharpness " + describe(s.directivity_sharpness) + " is outside [1, 16]";
  if (s.directivity_per_band != 0 && s.directivity_per_band != 1)
    return "settings->directivity_per_band " + std::to_string(s.directivity_per_band) + " is not 0 or 1";
  if (s.directivity_per_band)
    for (int b = 0; b < EARSHOT_BAND_COUNT; ++b)
      if (!(s.directivity_band_alpha[b] >= 0.0f && s.directivity_band_alpha[b] <= 1.0f))
        return "settings->directivity_band_alpha[" + std::to_string(b) + "] " + describe(s.directivity_band_alpha[b]) +
               " is outside [0, 1]";
  if (s.transmission != 0 && s.transmission != 1)
    return "settings->transmission " + std::to_string(s.transmission) + " is not 0 or 1";
  rs.gainDb = s.gain_db;
  rs.direct = direct == EARSHOT_DIRECT_PER_BLOCK ? runtime::DirectMode::kPerBlock
                                                 : runtime::DirectMode::kInImpulseResponse;
  rs.directGainDb = s.direct_gain_db;
  rs.reflectionsGainDb = s.reflections_gain_db;
  rs.distance.model = runtime::DistanceModel(model);  // the enumerators match
  rs.distance.minDistance = s.min_distance;
  rs.distance.maxDistance = s.max_distance;
  rs.distance.rolloff = s.rolloff;
  if (model == EARSHOT_DISTANCE_TABLE) {
    if (s.distance_table_count < 1 || s.distance_table_count > EARSHOT_DISTANCE_TABLE_POINTS)
      return "settings->distance_table_count " + std::to_string(s.distance_table_count) + " is outside [1, " +
             std::to_string(EARSHOT_DISTANCE_TABLE_POINTS) + "]";
    for (uint32_t i = 0; i < s.distance_table_count; ++i)
      rs.distance.table.emplace_back(s.distance_table_distance[i], s.distance_table_gain[i]);
    const Status v = runtime::validate(rs);
    if (!v.isOk()) return "settings->" + v.message();
  }
  rs.occlusion = occlusion == EARSHOT_OCCLUSION_OFF          ? runtime::OcclusionMode::kOff
                 : occlusion == EARSHOT_OCCLUSION_VOLUMETRIC ? runtime::OcclusionMode::kVolumetric
                                                             : runtime::OcclusionMode::kRay;
  rs.radiusMeters = s.radius;
  rs.transmission = s.transmission != 0;
  rs.priority = s.priority;
  rs.directivityAlpha = s.directivity_alpha;
  rs.directivitySharpness = s.directivity_sharpness;
  rs.directivityPerBand = s.directivity_per_band != 0;
  for (int b = 0; b < EARSHOT_BAND_COUNT; ++b) rs.directivityBandAlpha[size_t(b)] = s.directivity_band_alpha[b];
  return "";
}

/** earshot_source_create (pose null: at the origin, until the game moves
 *  it) and earshot_source_create_at (pose[0] position, pose[1] forward). */
earshot_status createSource(const char* kFn, earshot_context* c, const earshot_source_settings* settings,
                            const earshot_vec3* pose, earshot_source** out) {
  if (out) *out = nullptr;
  if (!alive(c)) return argError(nullptr, kFn, "context is not a live earshot_context");
  if (!out) return argError(&c->env, kFn, "out is NULL");
  if (pose) {
    for (int k = 0; k < 2; ++k) {
      const std::string bad = checkVec3(pose[k], k == 0 ? "position" : "forward");
      if (!bad.empty()) return argError(&c->env, kFn, bad);
    }
  }
  return guard(&c->env, kFn, [&]() -> earshot_status {
    earshot_source_settings s;
    earshot_source_settings_init(&s);
    if (settings) {
      const std::string badSize = checkStructSize(settings->struct_size, sizeof(earshot_source_settings), "settings");
      if (!badSize.empty()) return argError(&c->env, kFn, badSize);
      s = *settings;
    }
    runtime::SourceSettings rs;
    const std::string bad = toRuntime(s, rs);
    if (!bad.empty()) return argError(&c->env, kFn, bad);
    std::lock_guard<std::mutex> lock(c->sourcesMutex);
    auto slot = pose ? c->engine->addSource(rs, {pose[0].x, pose[0].y, pose[0].z}, {pose[1].x, pose[1].y, pose[1].z})
                     : c->engine->addSource(rs);
    if (!slot.isOk()) return fromStatus(&c->env, kFn, slot.status());
    earshot_source* src = nullptr;
    try {
      src = create<earshot_source>(c->env);
    } catch (...) {
      (void)c->engine->removeSource(*slot);
      throw;
    }
    src->slot = *slot;
    src->context = c;
    c->refs.fetch_add(1, std::memory_order_relaxed);
    ++c->activeSources;
    *out = src;
    return EARSHOT_OK;
  });
}

}  // namespace

extern "C" {

earshot_status earshot_source_create(earshot_context* c, const earshot_source_settings* settings,
                                     earshot_source** out) {
  return createSource("earshot_source_create", c, settings, nullptr, out);
}

earshot_status earshot_source_create_at(earshot_context* c, const earshot_source_settings* settings,
                                        earshot_vec3 position, earshot_vec3 forward, earshot_source** out) {
  const earshot_vec3 pose[2] = {position, forward};
  return createSource("earshot_source_create_at", c, settings, pose, out);
}

earshot_status earshot_source_retain(earshot_source* s) {
  return retainHandle(s, "earshot_source_retain", "source");
}

earshot_status earshot_source_release(earshot_source* s) {
  static const char* kFn = "earshot_source_release";
  if (!alive(s)) return argError(nullptr, kFn, "source is not a live earshot_source");
  return guard(&s->env, kFn, [&] {
    if (s->refs.fetch_sub(1, std::memory_order_acq_rel) != 1) return EARSHOT_OK;
    earshot_context* c = s->context;
    {
      std::lock_guard<std::mutex> lock(c->sourcesMutex);
      (void)c->engine->removeSource(s->slot);
      --c->activeSources;
    }
    destroy(s);
    releaseContext(c);
    return EARSHOT_OK;
  });
}

earshot_status earshot_source_get_index(earshot_source* s, uint32_t* index) {
  static const char* kFn = "earshot_source_get_index";
  if (!alive(s)) return argError(nullptr, kFn, "source is not a live earshot_source");
  if (!index) return argError(&s->env, kFn, "index is NULL");
  *index = s->slot;
  return EARSHOT_OK;
}

earshot_status earshot_source_set_position(earshot_source* s, earshot_vec3 position) {
  static const char* kFn = "earshot_source_set_position";
  if (!alive(s)) return argError(nullptr, kFn, "source is not a live earshot_source");
  return guard(&s->env, kFn, [&]() -> earshot_status {
    const std::string bad = checkVec3(position, "position");
    if (!bad.empty()) return argError(&s->env, kFn, bad);
    return fromStatus(&s->env, kFn,
                      s->context->engine->setSourcePosition(s->slot, {position.x, position.y, position.z}));
  });
}

earshot_status earshot_source_set_gain_db(earshot_source* s, float gainDb) {
  static const char* kFn = "earshot_source_set_gain_db";
  if (!alive(s)) return argError(nullptr, kFn, "source is not a live earshot_source");
  return guard(&s->env, kFn, [&]() -> earshot_status {
    if (!(gainDb >= -120.0f && gainDb <= 40.0f))
      return argError(&s->env, kFn, "gain_db " + describe(gainDb) + " is outside [-120, 40]");
    return fromStatus(&s->env, kFn, s->context->engine->setSourceGainDb(s->slot, gainDb));
  });
}

}  // extern "C"

earshot_status earshot_source_set_settings(earshot_source* src, const earshot_source_settings* settings) {
  static const char* kFn = "earshot_source_set_settings";
  if (!alive(src)) return argError(nullptr, kFn, "source is not a live earshot_source");
  if (!settings) return argError(&src->env, kFn, "settings is NULL");
  return guard(&src->env, kFn, [&]() -> earshot_status {
    const std::string badSize = checkStructSize(settings->struct_size, sizeof(earshot_source_settings), "settings");
    if (!badSize.empty()) return argError(&src->env, kFn, badSize);
    runtime::SourceSettings rs;
    const std::string bad = toRuntime(*settings, rs);
    if (!bad.empty()) return argError(&src->env, kFn, bad);
    auto current = src->context->engine->sourceControls(src->slot);
    if (!current.isOk()) return fromStatus(&src->env, kFn, current.status());
    if (current->direct != rs.direct)
      return argError(&src->env, kFn, "settings->direct differs from the source's: the direct mode is fixed at creation");
    return fromStatus(&src->env, kFn, src->context->engine->setSourceControls(src->slot, rs));
  });
}

earshot_status earshot_source_get_settings(earshot_source* src, earshot_source_settings* out) {
  static const char* kFn = "earshot_source_get_settings";
  if (!alive(src)) return argError(nullptr, kFn, "source is not a live earshot_source");
  if (!out) return argError(&src->env, kFn, "settings is NULL");
  return guard(&src->env, kFn, [&]() -> earshot_status {
    const std::string badSize = checkStructSize(out->struct_size, sizeof(earshot_source_settings), "settings");
    if (!badSize.empty()) return argError(&src->env, kFn, badSize);
    auto rs = src->context->engine->sourceControls(src->slot);
    if (!rs.isOk()) return fromStatus(&src->env, kFn, rs.status());
    earshot_source_settings_init(out);
    out->gain_db = float(rs->gainDb);
    out->direct = rs->direct == runtime::DirectMode::kPerBlock ? EARSHOT_DIRECT_PER_BLOCK
                                                               : EARSHOT_DIRECT_IN_IMPULSE_RESPONSE;
    out->direct_gain_db = float(rs->directGainDb);
    out->reflections_gain_db = float(rs->reflectionsGainDb);
    out->distance_model = earshot_distance_model(int(rs->distance.model));
    out->min_distance = float(rs->distance.minDistance);
    out->max_distance = float(rs->distance.maxDistance);
    out->rolloff = float(rs->distance.rolloff);
    out->distance_table_count = uint32_t(rs->distance.table.size());
    for (size_t i = 0; i < rs->distance.table.size() && i < EARSHOT_DISTANCE_TABLE_POINTS; ++i) {
      out->distance_table_distance[i] = float(rs->distance.table[i].first);
      out->distance_table_gain[i] = float(rs->distance.table[i].second);
    }
    out->occlusion = rs->occlusion == runtime::OcclusionMode::kOff          ? EARSHOT_OCCLUSION_OFF
                     : rs->occlusion == runtime::OcclusionMode::kVolumetric ? EARSHOT_OCCLUSION_VOLUMETRIC
                                                                           : EARSHOT_OCCLUSION_RAY;
    out->radius = float(rs->radiusMeters);
    out->transmission = rs->transmission ? 1 : 0;
    out->priority = rs->priority;
    out->directivity_alpha = float(rs->directivityAlpha);
    out->directivity_sharpness = float(rs->directivitySharpness);
    out->directivity_per_band = rs->directivityPerBand ? 1 : 0;
    for (int b = 0; b < EARSHOT_BAND_COUNT; ++b) out->directivity_band_alpha[b] = float(rs->directivityBandAlpha[size_t(b)]);
    return EARSHOT_OK;
  });
}

earshot_status earshot_source_get_occlusion(earshot_source* src, earshot_source_occlusion* out) {
  static const char* kFn = "earshot_source_get_occlusion";
  if (!alive(src)) return argError(nullptr, kFn, "source is not a live earshot_source");
  if (!out) return argError(&src->env, kFn, "occlusion is NULL");
  return guard(&src->env, kFn, [&]() -> earshot_status {
    const std::string badSize = checkStructSize(out->struct_size, sizeof(earshot_source_occlusion), "occlusion");
    if (!badSize.empty()) return argError(&src->env, kFn, badSize);
    auto ro = src->context->engine->sourceOcclusion(src->slot);
    if (!ro.isOk()) return fromStatus(&src->env, kFn, ro.status());
    for (int b = 0; b < EARSHOT_BAND_COUNT; ++b) out->transmission[b] = float(ro->transmission[size_t(b)]);
    out->audible = ro->audible ? 1 : 0;
    out->simulated = ro->simulated ? 1 : 0;
    return EARSHOT_OK;
  });
}

earshot_status earshot_source_set_orientation(earshot_source* src, earshot_vec3 forward) {
  static const char* kFn = "earshot_source_set_orientation";
  if (!alive(src)) return argError(nullptr, kFn, "source is not a live earshot_source");
  const std::string bad = checkVec3(forward, "forward");
  if (!bad.empty()) return argError(&src->env, kFn, bad);
  return guard(&src->env, kFn, [&]() -> earshot_status {
    return fromStatus(&src->env, kFn,
                      src->context->engine->setSourceOrientation(src->slot, {forward.x, forward.y, forward.z}));
  });
}
