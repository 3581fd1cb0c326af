// The C API's shared pieces: versions, status names, the last error, the
// allocator and the log (capi_internal.h).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "capi_internal.h"
#include "earshot/io/input_file.h"
#include "earshot/hrtf/hrtf_set.h"

namespace earshot::capi {

namespace {
thread_local std::string tLastError;
}  // namespace

void* Env::allocateBytes(size_t size, size_t alignment) const {
  if (allocate) return allocate(allocUser, size, alignment);
  if (alignment <= alignof(std::max_align_t)) return std::malloc(size);
  return std::aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
}

void Env::freeBytes(void* p) const {
  if (!p) return;
  if (free) {
    free(allocUser, p);
  } else {
    std::free(p);
  }
}

void Env::logMessage(earshot_log_level messageLevel, const std::string& message) const noexcept {
  if (!log || int(messageLevel) > int(level)) return;
  log(logUser, messageLevel, message.c_str());
}

earshot_status fail(const Env* env, const char* fn, earshot_status code, const std::string& message) noexcept {
  try {
    tLastError = std::string(fn) + ": " + message;
    if (env && code != EARSHOT_ERROR_INVALID_ARGUMENT) env->logMessage(EARSHOT_LOG_ERROR, tLastError);
  } catch (...) {
    // Out of memory while reporting: the status still says what happened.
  }
  return code;
}

earshot_status argError(const Env* env, const char* fn, const std::string& message) noexcept {
  try {
    tLastError = std::string(fn) + ": " + message;
    if (env && env->validation) env->logMessage(EARSHOT_LOG_ERROR, tLastError);
  } catch (...) {
  }
  return EARSHOT_ERROR_INVALID_ARGUMENT;
}

earshot_status argError(const Env* env, const char* fn, const char* message) noexcept {
  try {
    return argError(env, fn, std::string(message));
  } catch (...) {
    return EARSHOT_ERROR_INVALID_ARGUMENT;
  }
}

earshot_status toCode(StatusCode code) {
  switch (code) {
    case StatusCode::kOk: return EARSHOT_OK;
    case StatusCode::kInvalidArgument: return EARSHOT_ERROR_INVALID_ARGUMENT;
    case StatusCode::kNotFound: return EARSHOT_ERROR_NOT_FOUND;
    case StatusCode::kIoError: return EARSHOT_ERROR_IO;
    case StatusCode::kParseError: return EARSHOT_ERROR_PARSE;
    case StatusCode::kUnsupported: return EARSHOT_ERROR_UNSUPPORTED;
    case StatusCode::kOutOfRange: return EARSHOT_ERROR_OUT_OF_RANGE;
    case StatusCode::kInternal: return EARSHOT_ERROR_INTERNAL;
  }
  return EARSHOT_ERROR_INTERNAL;
}

earshot_status fromStatus(const Env* env, const char* fn, const Status& status) noexcept {
  if (status.isOk()) return EARSHOT_OK;
  const earshot_status code = toCode(status.code());
  // The engine names the memory limit by the CLI's option; a C caller sets it
  // with earshot_set_memory_limit.
  std::string message;
  try {
    message = renamedMemoryLimit(status.message(), "earshot_set_memory_limit");
  } catch (...) {
    return EARSHOT_ERROR_OUT_OF_MEMORY;
  }
  if (code == EARSHOT_ERROR_INVALID_ARGUMENT) return argError(env, fn, message);
  return fail(env, fn, code, message);
}

std::string checkStructSize(uint32_t got, size_t expected, const char* name) {
  if (got == expected) return "";
  return std::string(name) + "->struct_size " + std::to_string(got) + " is not " + std::to_string(expected) +
         " (header and library differ?)";
}

std::string describe(double v) {
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%g", v);
  return buf;
}

std::string checkFinite(double v, const char* name) {
  if (std::isfinite(v)) return "";
  return std::string(name) + " is " + describe(v) + " (must be finite)";
}

std::string checkVec3(const earshot_vec3& v, const char* name) {
  const float c[3] = {v.x, v.y, v.z};
  const char* axis[3] = {".x", ".y", ".z"};
  for (int i = 0; i < 3; ++i) {
    std::string e = checkFinite(c[i], (std::string(name) + axis[i]).c_str());
    if (!e.empty()) return e;
  }
  return "";
}

}  // namespace earshot::capi

using namespace earshot::capi;

extern "C" {

uint32_t earshot_version(void) { return EARSHOT_VERSION; }

const char* earshot_status_string(earshot_status status) {
  switch (rawEnum(status)) {
    case EARSHOT_OK: return "ok";
    case EARSHOT_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case EARSHOT_ERROR_OUT_OF_MEMORY: return "out of memory";
    case EARSHOT_ERROR_IO: return "input/output error";
    case EARSHOT_ERROR_NOT_FOUND: return "not found";
    case EARSHOT_ERROR_PARSE: return "parse error";
    case EARSHOT_ERROR_UNSUPPORTED: return "unsupported";
    case EARSHOT_ERROR_OUT_OF_RANGE: return "out of range";
    case EARSHOT_ERROR_INVALID_STATE: return "invalid state";
    case EARSHOT_ERROR_INTERNAL: return "internal error";
  }
  return "unknown status";
}

const char* earshot_last_error_message(void) {
  try {
    return tLastError.c_str();
  } catch (...) {
    return "";
  }
}

earshot_status earshot_hrtf_default_path(char* buffer, size_t capacity, size_t* length) {
  static const char* kFn = "earshot_hrtf_default_path";
  return guard(nullptr, kFn, [&]() -> earshot_status {
    if (!buffer && capacity > 0) return argError(nullptr, kFn, "buffer is NULL with a non-zero capacity");
    auto path = earshot::hrtf::defaultHrtfPath();
    if (!path.isOk()) return fromStatus(nullptr, kFn, path.status());
    if (length) *length = path->size();
    if (path->size() + 1 > capacity)
      return fail(nullptr, kFn, EARSHOT_ERROR_OUT_OF_RANGE,
                  "the path needs " + std::to_string(path->size() + 1) + " bytes, buffer has " +
                      std::to_string(capacity));
    std::memcpy(buffer, path->c_str(), path->size() + 1);
    return EARSHOT_OK;
  });
}

earshot_status earshot_set_memory_limit(uint64_t bytes) {
  static const char* kFn = "earshot_set_memory_limit";
  return guard(nullptr, kFn, [&]() -> earshot_status {
    earshot::setDefaultMaxMemoryBytes(bytes);
    return EARSHOT_OK;
  });
}

earshot_status earshot_get_memory_limit(uint64_t* bytes) {
  static const char* kFn = "earshot_get_memory_limit";
  return guard(nullptr, kFn, [&]() -> earshot_status {
    if (!bytes) return argError(nullptr, kFn, "bytes is NULL");
    *bytes = earshot::defaultInputLimits().maxMemoryBytes;
    return EARSHOT_OK;
  });
}

}  // extern "C"
