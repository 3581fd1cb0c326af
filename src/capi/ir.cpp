// The C API's impulse responses: a source's latest IR and IRs computed on
// demand (earshot_ir handles).
#include <algorithm>
#include <cstring>

#include "capi_internal.h"
#include "earshot/core/math.h"
#include "earshot/core/thread_pool.h"
#include "earshot/ir/ir_pipeline.h"
#include "earshot/scene/ray_tracer.h"

using namespace earshot;
using namespace earshot::capi;

namespace {

void releaseIr(earshot_ir* ir) {
  if (ir->refs.fetch_sub(1, std::memory_order_acq_rel) == 1) destroy(ir);
}

Vec3d vec(const earshot_vec3& v) { return {double(v.x), double(v.y), double(v.z)}; }

}  // namespace

earshot_status earshot_source_get_ir(earshot_source* s, earshot_ir** out) {
  static const char* kFn = "earshot_source_get_ir";
  if (out) *out = nullptr;
  if (!alive(s)) return argError(nullptr, kFn, "source is not a live earshot_source");
  if (!out) return argError(&s->env, kFn, "out is NULL");
  return guard(&s->env, kFn, [&]() -> earshot_status {
    runtime::SourceIr latest = s->context->engine->sourceIr(s->slot);
    if (!latest.ir)
      return fail(&s->env, kFn, EARSHOT_ERROR_NOT_FOUND, "source " + std::to_string(s->slot) + " has not been simulated yet");
    earshot_ir* ir = create<earshot_ir>(s->env);
    ir->ir = std::move(latest.ir);
    ir->includesDirect = latest.includesDirect;
    ir->simulation = latest.simulations;
    ir->posed = latest.posed;
    *out = ir;
    return EARSHOT_OK;
  });
}

earshot_status earshot_ir_request_init(earshot_ir_request* r) {
  if (!r) return argError(nullptr, "earshot_ir_request_init", "request is NULL");
  std::memset(r, 0, sizeof(*r));
  r->struct_size = sizeof(earshot_ir_request);
  r->source = {0.0f, 0.0f, -1.0f};
  r->listener = {0.0f, 0.0f, 0.0f};
  r->forward = {0.0f, 0.0f, -1.0f};
  r->up = {0.0f, 1.0f, 0.0f};
  r->receiver = EARSHOT_RECEIVER_BINAURAL;
  r->seed = 0;
  r->ambisonic_order = 1;
  return EARSHOT_OK;
}

earshot_status earshot_context_compute_ir(earshot_context* c, const earshot_ir_request* request, earshot_ir** out) {
  static const char* kFn = "earshot_context_compute_ir";
  if (out) *out = nullptr;
  if (!alive(c)) return argError(nullptr, kFn, "context is not a live earshot_context");
  if (!request) return argError(&c->env, kFn, "request is NULL");
  if (!out) return argError(&c->env, kFn, "out is NULL");
  return guard(&c->env, kFn, [&]() -> earshot_status {
    const std::string badSize = checkStructSize(request->struct_size, sizeof(earshot_ir_request), "request");
    if (!badSize.empty()) return argError(&c->env, kFn, badSize);
    for (auto [v, name] : {std::pair{&request->source, "request->source"}, {&request->listener, "request->listener"},
                           {&request->forward, "request->forward"}, {&request->up, "request->up"}}) {
      const std::string bad = checkVec3(*v, name);
      if (!bad.empty()) return argError(&c->env, kFn, bad);
    }
    const int64_t receiver = rawEnum(request->receiver);
    if (receiver != EARSHOT_RECEIVER_BINAURAL && receiver != EARSHOT_RECEIVER_OMNI &&
        receiver != EARSHOT_RECEIVER_AMBISONIC)
      return argError(&c->env, kFn, "request->receiver " + std::to_string(receiver) + " is not an earshot_receiver");
    if (receiver == EARSHOT_RECEIVER_AMBISONIC &&
        (request->ambisonic_order < 1 || request->ambisonic_order > uint32_t(kMaxAmbisonicOrder)))
      return argError(&c->env, kFn,
                      "request->ambisonic_order " + std::to_string(request->ambisonic_order) + " is outside [1, 3]");
    // The scene as the context's next simulation would see it.
    std::shared_ptr<const RayTracer> tracer;
    std::shared_ptr<const MaterialTable> materials;
    {
      std::lock_guard<std::mutex> lock(c->sceneMutex);
      if (c->scene) {
        std::lock_guard<std::mutex> publish(c->scene->publishMutex);
        tracer = c->scene->snapshot;
        materials = c->scene->snapshotMaterials;
      }
    }
    if (!tracer) {
      auto empty = RayTracer::create(TriangleMesh{});
      if (!empty.isOk()) return fromStatus(&c->env, kFn, empty.status());
      tracer = std::move(empty.value());
    }
    if (!materials) materials = std::make_shared<const MaterialTable>(defaultMaterials());
    const runtime::EngineSettings& es = c->engine->settings();
    OmniIrSettings settings = es.simulation;
    settings.sampleRateHz = es.sampleRateHz;
    settings.maxLengthSeconds = 0;  // the complete IR: not the engine's cut (max_ir_seconds)
    settings.includeDirect = true;
    if (request->seed != 0) settings.seed = request->seed;
    BinauralReceiver binaural;
    if (receiver == EARSHOT_RECEIVER_BINAURAL) {
      auto model = c->engine->model();  // waits while the HRTF is still loading
      if (!model.isOk()) return fromStatus(&c->env, kFn, model.status());
      binaural.model = *model;
      binaural.orientation.forward = vec(request->forward);
      binaural.orientation.up = vec(request->up);
      Status v = validate(binaural.orientation);
      if (!v.isOk()) return fromStatus(&c->env, kFn, v);
    }
    AmbisonicReceiver ambisonic;
    if (receiver == EARSHOT_RECEIVER_AMBISONIC) {
      ListenerOrientation o{vec(request->forward), vec(request->up)};
      Status v = validate(o);
      if (!v.isOk()) return fromStatus(&c->env, kFn, v);
      ambisonic.order = int(request->ambisonic_order);
      ambisonic.frame.worldToFrame = worldToAmbisonicFrame(o.forward, o.up);
    }
    ThreadPool pool(es.threads);
    auto r = computeIr(*tracer, *materials, vec(request->source), vec(request->listener), settings, pool,
                       receiver == EARSHOT_RECEIVER_BINAURAL ? &binaural : nullptr,
                       receiver == EARSHOT_RECEIVER_AMBISONIC ? &ambisonic : nullptr);
    if (!r.isOk()) return fromStatus(&c->env, kFn, r.status());
    earshot_ir* ir = create<earshot_ir>(c->env);
    ir->ir = std::make_shared<const AudioBuffer>(std::move(r->ir));
    ir->includesDirect = true;
    *out = ir;
    return EARSHOT_OK;
  });
}

earshot_status earshot_ir_get_info(const earshot_ir* ir, earshot_ir_info* info) {
  static const char* kFn = "earshot_ir_get_info";
  if (!alive(ir)) return argError(nullptr, kFn, "ir is not a live earshot_ir");
  if (!info) return argError(&ir->env, kFn, "info is NULL");
  return guard(&ir->env, kFn, [&]() -> earshot_status {
    const std::string badSize = checkStructSize(info->struct_size, sizeof(earshot_ir_info), "info");
    if (!badSize.empty()) return argError(&ir->env, kFn, badSize);
    info->channels = uint32_t(ir->ir->channelCount());
    info->frames = ir->ir->frameCount();
    info->sample_rate_hz = ir->ir->sampleRateHz;
    info->includes_direct = ir->includesDirect ? 1u : 0u;
    info->simulation = ir->simulation;
    info->age_seconds =
        ir->simulation > 0
            ? std::chrono::duration<double>(std::chrono::steady_clock::now() - ir->posed).count()
            : 0.0;
    return EARSHOT_OK;
  });
}

earshot_status earshot_ir_copy_channel(const earshot_ir* ir, uint32_t channel, float* buffer,
                                       uint64_t capacityFrames) {
  static const char* kFn = "earshot_ir_copy_channel";
  if (!alive(ir)) return argError(nullptr, kFn, "ir is not a live earshot_ir");
  return guard(&ir->env, kFn, [&]() -> earshot_status {
    if (channel >= ir->ir->channelCount())
      return argError(&ir->env, kFn, "channel " + std::to_string(channel) + " does not exist (the IR has " +
                                         std::to_string(ir->ir->channelCount()) + ")");
    if (!buffer) return argError(&ir->env, kFn, "buffer is NULL");
    const auto& ch = ir->ir->channels[channel];
    if (capacityFrames < ch.size())
      return fail(&ir->env, kFn, EARSHOT_ERROR_OUT_OF_RANGE,
                  "capacity_frames " + std::to_string(capacityFrames) + " < the IR's " + std::to_string(ch.size()) +
                      " frames");
    std::copy(ch.begin(), ch.end(), buffer);
    return EARSHOT_OK;
  });
}

earshot_status earshot_ir_retain(earshot_ir* ir) { return retainHandle(ir, "earshot_ir_retain", "ir"); }

earshot_status earshot_ir_release(earshot_ir* ir) {
  return releaseHandle(ir, "earshot_ir_release", "ir", releaseIr);
}
