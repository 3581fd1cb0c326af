#ifndef EARSHOT_EARSHOT_H
#define EARSHOT_EARSHOT_H
/** @file earshot's C API (C99; this header compiles on its own).
 *
 *  What it is: a game pushes geometry (meshes with acoustic materials, or a
 *  glTF file) into a scene, commits the scene, moves sources and a listener
 *  every frame, runs the simulation (reflections, on worker threads) a few
 *  times a second, and pulls binaural audio (left, right) from its audio
 *  thread in blocks of any size.
 *
 *  Objects. Every object is an opaque, reference-counted handle:
 *    earshot_context  the engine: HRTF, source slots, listener, worker
 *                     threads, the optional built-in simulation thread;
 *    earshot_scene    editable geometry and its acoustic materials; commit()
 *                     makes an immutable snapshot the simulation traces;
 *    earshot_mesh     triangles in their own frame with a transform and
 *                     materials; lives in at most one scene at a time;
 *    earshot_source   one sound source (a slot of its context).
 *  A create function returns a handle holding one reference; `_retain` adds
 *  one, `_release` drops one, and the object is destroyed when the last goes.
 *  A source holds a reference to its context; a scene holds references to
 *  its meshes; a context holds a reference to the scene given to
 *  earshot_context_set_scene. Nothing else holds references, so there are
 *  no cycles. Passing a handle after its last release is undefined.
 *
 *  Errors. Every function that can fail returns an earshot_status and never
 *  lets a C++ exception or an abort out. Invalid arguments (NULL pointers,
 *  NaN or infinite numbers, values out of the documented range, a settings
 *  struct whose struct_size is not the size of this header's struct, a
 *  handle of the wrong type) return EARSHOT_ERROR_INVALID_ARGUMENT and change
 *  nothing. The message explaining the last failure on the calling thread is
 *  earshot_last_error_message(); with EARSHOT_CONTEXT_VALIDATION set, argument
 *  errors are also logged (naming the function and the argument). Other
 *  errors (files, memory, limits) are always logged at EARSHOT_LOG_ERROR.
 *
 *  Threads. Three roles, as in a game engine:
 *    - the game thread: creates, edits and releases objects, sets poses and
 *      gains, commits scenes (one thread at a time per scene; the context's
 *      functions are safe to call from several threads);
 *    - the simulation thread: earshot_simulate(), or the context's built-in
 *      thread (earshot_context_start_simulation); it uses the context's
 *      worker threads;
 *    - the audio thread: earshot_process() only, which never allocates,
 *      locks, logs or waits.
 *  Every function says which of these may call it.
 *
 *  Units and conventions: metres, seconds, Hz, decibels; right-handed
 *  coordinates; the listener's default orientation is forward -Z, up +Y
 *  (glTF). Output channel 0 is the left ear, 1 the right. Audio is 32-bit
 *  float, non-interleaved. */

#include <stddef.h>
#include <stdint.h>

#if defined(_WIN32) && defined(EARSHOT_BUILDING_SHARED)
#define EARSHOT_API __declspec(dllexport)
#elif defined(__GNUC__)
#define EARSHOT_API __attribute__((visibility("default")))
#else
#define EARSHOT_API
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------- versions */

/* EARSHOT_VERSION_MAJOR, _MINOR, _PATCH and EARSHOT_VERSION_STRING, from
 * the project's version (generated at configure time, installed beside this
 * header). */
#include "earshot/earshot_version.h"
/** The version this header describes, as (major << 16) | (minor << 8) | patch. */
#define EARSHOT_VERSION ((EARSHOT_VERSION_MAJOR << 16) | (EARSHOT_VERSION_MINOR << 8) | EARSHOT_VERSION_PATCH)

/** The library's version, encoded as EARSHOT_VERSION. Any thread. */
EARSHOT_API uint32_t earshot_version(void);

/* ------------------------------------------------------------------ status */

typedef enum earshot_status {
  EARSHOT_OK = 0,
  EARSHOT_ERROR_INVALID_ARGUMENT = 1, /**< NULL, NaN, out of range, wrong struct_size or handle type */
  EARSHOT_ERROR_OUT_OF_MEMORY = 2,    /**< an allocation failed (the allocator callback or the C++ heap) */
  EARSHOT_ERROR_IO = 3,               /**< a file could not be read or written */
  EARSHOT_ERROR_NOT_FOUND = 4,        /**< a missing file, or an unknown name (material, glTF node) */
  EARSHOT_ERROR_PARSE = 5,            /**< a malformed file (JSON, glTF, SOFA) */
  EARSHOT_ERROR_UNSUPPORTED = 6,      /**< valid, but not handled (a format, an operation on this object) */
  EARSHOT_ERROR_OUT_OF_RANGE = 7,     /**< a size beyond the limits (e.g. every source slot in use) */
  EARSHOT_ERROR_INVALID_STATE = 8,    /**< not now (e.g. a mesh already in a scene, a thread already running) */
  EARSHOT_ERROR_INTERNAL = 9          /**< a bug in earshot: please report it with the log */
} earshot_status;

/** A static, human-readable name of `status` ("invalid argument", ...); an
 *  unknown value gives "unknown status". Never NULL. Any thread. */
EARSHOT_API const char* earshot_status_string(earshot_status status);

/** The message explaining the last failed call on the calling thread (one
 *  line, e.g. "earshot_scene_load_gltf: rooms.gltf: no node named \"door\""),
 *  or "" if none failed yet. Valid until the next earshot call on this thread.
 *  earshot_process() does not set it. Any thread but the audio thread. */
EARSHOT_API const char* earshot_last_error_message(void);

/* ----------------------------------------------------------- basic types */

typedef struct earshot_vec3 {
  float x, y, z;
} earshot_vec3;

/** Octave bands of material data: 125, 250, 500, 1000, 2000, 4000, 8000 Hz. */
#define EARSHOT_BAND_COUNT 7

typedef struct earshot_context earshot_context;
typedef struct earshot_scene earshot_scene;
typedef struct earshot_mesh earshot_mesh;
typedef struct earshot_source earshot_source;
typedef struct earshot_ir earshot_ir;

/* ------------------------------------------------------ log and allocator */

typedef enum earshot_log_level {
  EARSHOT_LOG_ERROR = 0,
  EARSHOT_LOG_WARNING = 1,
  EARSHOT_LOG_INFO = 2,
  EARSHOT_LOG_DEBUG = 3
} earshot_log_level;

/** Receives log messages (one line, no trailing newline, valid only during
 *  the call). Called on the thread that made the failing or reporting call:
 *  the game thread, or the simulation thread (errors of the built-in
 *  simulation thread); never the audio thread. Must not call earshot. */
typedef void (*earshot_log_callback)(void* user_data, earshot_log_level level, const char* message);

/** Allocates `size` bytes aligned to `alignment` (a power of two, at most 64)
 *  or returns NULL. Called from the game thread (object creation) only. */
typedef void* (*earshot_allocate_callback)(void* user_data, size_t size, size_t alignment);
/** Frees what the allocate callback returned (never NULL). Called on the
 *  thread that drops an object's last reference (never the audio thread). */
typedef void (*earshot_free_callback)(void* user_data, void* pointer);

/* ----------------------------------------------------------------- context */

/** Flags for earshot_context_settings.flags. */
enum {
  /** Log every invalid argument (function, argument, value) at EARSHOT_LOG_ERROR. */
  EARSHOT_CONTEXT_VALIDATION = 1u << 0
};

/** What earshot_process_channels() writes (earshot_context_settings). */
typedef enum earshot_output_format {
  /** 2 channels: left, right (earshot_process or earshot_process_channels). */
  EARSHOT_OUTPUT_BINAURAL = 0,
  /** (ambisonic_order + 1)^2 channels, AmbiX: ACN channel order (W, Y, Z, X,
   *  V, T, R, S, U, Q, O, M, K, L, N, P), SN3D normalisation, in the
   *  listener's frame (x forward, y left, z up, from
   *  earshot_context_set_listener's forward and up); W is the omni pressure
   *  (1/r for the direct sound). Every source's reflections are rotated to
   *  the head and each direct sound encoded at its current direction; no
   *  HRTF. For a host that renders ambisonics itself (earshot_process_channels only). */
  EARSHOT_OUTPUT_AMBISONIC = 1
} earshot_output_format;

/** How a simulation step traces the reflections of its sources
 *  (earshot_context_settings). */
typedef enum earshot_trace_mode {
  /** EARSHOT_TRACE_SHARED for a step of 3 sources or more, else
   *  EARSHOT_TRACE_PER_SOURCE (from 3 the shared trace is measured cheaper
   *  in every scene tried; docs/performance.md). */
  EARSHOT_TRACE_AUTO = 0,
  /** One trace from the listener whose paths every source of the step
   *  detects (reciprocity: the same energies as a trace from each source);
   *  a step of 32 sources costs about a third of their 32 traces. */
  EARSHOT_TRACE_SHARED = 1,
  /** A trace from each source, one source per simulation thread. */
  EARSHOT_TRACE_PER_SOURCE = 2
} earshot_trace_mode;

typedef struct earshot_context_settings {
  uint32_t struct_size;        /**< sizeof(earshot_context_settings) */
  uint32_t flags;              /**< EARSHOT_CONTEXT_* flags; default 0 */
  double sample_rate_hz;       /**< audio rate, [8000, 192000] (the HRTF's range); default 48000 */
  /** The host's usual block (frames), [1, 65536]; default 256. The
   *  convolver's partition, and so the latency (earshot_context_info's
   *  latency_frames), is the smallest even 2^a 3^b 5^c number at least this
   *  and 8: 254 -> 256, 441 -> 450, 1 -> 8 (other prime factors would make
   *  the FFT allocate on the audio thread). earshot_process() accepts blocks
   *  of any size regardless. */
  uint32_t block_frames;
  uint32_t max_sources;        /**< source slots allocated up front, [1, 4096]; default 32 */
  double max_ir_seconds;       /**< reflections are cut here (10 ms fade), (0, 60]; default 3 (with ambisonic
                                    reflections the sources share one late tail from 0.15 s on; at 0.15
                                    or less each source's whole IR is its own) */
  uint32_t rays;               /**< rays traced per source and simulation, [1, 100000000]; default 16384;
                                    a count whose trace state (~150 bytes a ray) passes the memory limit
                                    (1 GiB) is refused (EARSHOT_ERROR_OUT_OF_RANGE) */
  uint32_t bounces;            /**< reflections per ray, [0, 100000]; default 12 */
  uint32_t image_source_order; /**< order of exact early reflections, [0, 4]; default 3 */
  uint32_t threads;            /**< simulation threads, [0, 256], 0 = the cores less one (the audio thread's); default 0. They run at a lower priority (nice + 5 on Linux), the built-in simulation thread too */
  uint64_t seed;               /**< random seed of the ray tracer; default 1 */
  double max_distance_meters;  /**< farthest source heard directly (delay line size), (0, 20000]; default 343 */
  /** SOFA HRTF file (UTF-8 path, copied), resampled to sample_rate_hz; NULL or
   *  "" = the default set shipped with earshot (see earshot_hrtf_default_path). */
  const char* hrtf_path;
  earshot_log_callback log;           /**< NULL: no logging */
  void* log_user_data;                /**< passed to `log` */
  earshot_log_level log_level;        /**< most verbose level passed to `log`; default EARSHOT_LOG_WARNING */
  /** Allocator for the API's own objects: the context, scene, mesh and source
   *  handles (and their small bookkeeping). Both NULL (default: malloc/free)
   *  or both set. Everything the engine allocates inside (HRTF, BVHs, IRs,
   *  convolution buffers, threads) uses the C++ global allocator. */
  earshot_allocate_callback allocate;
  earshot_free_callback free;
  void* allocator_user_data;          /**< passed to allocate and free */
  /** How the reflections reach the ears, [0, 3]; default 1.
   *  1-3: each source's reflections are simulated as a world-frame ambisonic
   *  IR of this order; the context sums all sources into one bus, rotates it
   *  to the head every audio block and decodes it to two ears once (with a
   *  decoder made from the HRTF set): a head turn is heard in the next block
   *  and never needs a simulation. The audio thread multiplies and adds
   *  (order+1)^2 channels per source (4 at order 1) instead of 2, and one
   *  decoder for all; the latency grows by one block and 2 ms
   *  (earshot_context_info's latency_frames). docs/ambisonics.md measures the
   *  orders against the exact binaural reflections.
   *  0: a binaural IR per source with each arrival through its own HRTF, the
   *  head's orientation baked in: a head turn is heard in the reflections
   *  only after the source's next simulation. */
  uint32_t ambisonic_order;
  /** EARSHOT_OUTPUT_BINAURAL (default) or EARSHOT_OUTPUT_AMBISONIC (needs
   *  ambisonic_order 1-3). */
  earshot_output_format output_format;
  /** EARSHOT_TRACE_AUTO (default), EARSHOT_TRACE_SHARED or
   *  EARSHOT_TRACE_PER_SOURCE. A step shares one trace among the sources it
   *  simulates: earshot_simulate's source_count (0: every source) or the
   *  built-in thread's. */
  earshot_trace_mode trace_mode;
} earshot_context_settings;

/** Fills `settings` with the defaults above (and struct_size). Any thread. */
EARSHOT_API earshot_status earshot_context_settings_init(earshot_context_settings* settings);

/** Creates a context in a few milliseconds and about a megabyte: the shared
 *  buffers and worker threads only. The HRTF loads on a background thread
 *  (~0.5-0.7 s for the default set the first time on a machine, ~0.1 s
 *  once earshot's cache folder holds it: $EARSHOT_CACHE_DIR, else
 *  ~/.cache/earshot, "off" for none; README); a slot's state (~1.5 MB at 3 s IRs)
 *  is allocated when a source first uses it (earshot_source_create) and kept
 *  for the slot's later sources. `earshot bench context` measures all three.
 *  A missing or unreadable HRTF file is refused here; a file that fails to
 *  load as SOFA makes every later use of the HRTF (earshot_source_create, a
 *  binaural earshot_context_compute_ir) return the load's error.
 *  `settings` is only read (strings copied). On success *out holds one
 *  reference; on failure *out is set to NULL. Errors: INVALID_ARGUMENT,
 *  NOT_FOUND (HRTF file), OUT_OF_MEMORY. Game thread. */
EARSHOT_API earshot_status earshot_context_create(const earshot_context_settings* settings, earshot_context** out);
/** Adds a reference. Any thread but the audio thread. */
EARSHOT_API earshot_status earshot_context_retain(earshot_context* context);
/** Drops a reference; the last one stops the built-in simulation thread
 *  (waiting for a running step to end), releases the scene and frees
 *  everything. Sources hold references, so the context outlives them. Must
 *  not race with earshot_process() on the same context. Game thread. */
EARSHOT_API earshot_status earshot_context_release(earshot_context* context);

typedef struct earshot_context_info {
  uint32_t struct_size;     /**< set by the caller: sizeof(earshot_context_info) */
  double sample_rate_hz;
  uint32_t block_frames;
  uint32_t max_sources;
  uint32_t latency_frames;  /**< output lags input by this many frames (the convolver's block) */
  uint32_t active_sources;  /**< sources created and not yet released */
  uint32_t simulation_thread_running; /**< 1 while the built-in simulation thread runs */
  uint32_t last_simulation_sources;   /**< sources simulated by the last simulation step */
  double last_simulation_ms;          /**< wall time of the last simulation step */
  /** Audio-path containment since creation: source blocks (of at most 256
   *  frames) muted because an input sample was NaN, infinite or beyond 1e6
   *  (the source is silent for that block; nothing of it enters any state),
   *  and output blocks zeroed with every source's state cleared because the
   *  output was not finite (an overflow). A source is never left poisoned. */
  uint64_t muted_source_blocks;
  uint64_t cleared_output_blocks;
  uint32_t ambisonic_order;             /**< the settings': 0 binaural reflections, 1-3 the ambisonic bus */
  earshot_output_format output_format;  /**< the settings' */
  uint32_t output_channels;             /**< channels earshot_process_channels writes: 2 or (order+1)^2 */
  earshot_trace_mode trace_mode;        /**< the settings' */
} earshot_context_info;

/** Reads the context's settings and state into *info (info->struct_size
 *  must be set). Any thread but the audio thread. */
EARSHOT_API earshot_status earshot_context_get_info(earshot_context* context, earshot_context_info* info);

/** Sets the listener's pose: `position` (metres, finite), `forward` and `up`
 *  (finite, non-zero, not parallel; need not be unit length; up is made
 *  orthogonal to forward). The direct sound follows a turn within the next
 *  audio block, and a move as it follows a source's
 *  (earshot_source_set_position); the reflections at the next simulation
 *  of each source. Game thread (any thread but the audio thread). */
EARSHOT_API earshot_status earshot_context_set_listener(earshot_context* context, earshot_vec3 position,
                                                        earshot_vec3 forward, earshot_vec3 up);

/** Makes `scene` (or NULL: free field, no geometry) the one the context
 *  simulates. The context keeps a reference and follows the scene: each
 *  earshot_scene_commit() is picked up by the next simulation step. Until
 *  the scene's first commit the context simulates a free field. Game thread. */
EARSHOT_API earshot_status earshot_context_set_scene(earshot_context* context, earshot_scene* scene);

/** Runs one simulation step: picks up the scene's latest commit, then
 *  traces, synthesises and posts the reflections of `source_count` active
 *  sources (0 or more than active: all of them) and updates their direct
 *  paths' occlusion, from the poses set so far. Which sources: higher
 *  `priority` first; then sources never simulated; then any not simulated
 *  for twice a round (2 ceil(active / source_count) steps: a source standing
 *  still is still updated, e.g. after a door opened); then those that moved
 *  most (with the listener) since their last simulation; round robin among
 *  equals. Takes
 *  time (milliseconds per source; see earshot_context_get_info) on the
 *  context's worker threads. A new source's direct sound plays from its
 *  first audio block (EARSHOT_DIRECT_PER_BLOCK; unoccluded until its first
 *  simulation has traced the path); its reflections join when its first
 *  simulation lands, and bring those of what it played meanwhile (its
 *  input feeds its convolution from its first block, and the shared late
 *  tail at the late level of the simulated source nearest to it: a
 *  one-shot is not heard dry, only its first reflections are missed). A
 *  step goes through its sources in groups of 8 and posts each group's
 *  reflections as soon as it is done; a source created while a step runs
 *  joins the step's next group (a one-shot waits for a group, not for the
 *  whole step: 0.08 s against 0.39 s with 32 sources in the furnished
 *  sample room). Errors: INVALID_ARGUMENT, INVALID_STATE
 *  (the built-in simulation thread is running), OUT_OF_MEMORY, INTERNAL.
 *  Simulation thread (any thread but the audio thread; one at a time). */
EARSHOT_API earshot_status earshot_simulate(earshot_context* context, uint32_t source_count);

/** Starts the built-in simulation thread: it calls earshot_simulate(context,
 *  sources_per_step) every 1 / rate_hz seconds of wall time (a step that
 *  overruns delays the next rather than queueing steps). rate_hz in
 *  [0.001, 1000]; sources_per_step 0 = all (round robin otherwise, e.g. 32
 *  sources at 10 Hz and 4 per step update each source at 1.25 Hz). Errors of
 *  a step are logged and the thread goes on. Errors: INVALID_ARGUMENT,
 *  INVALID_STATE (already running), OUT_OF_MEMORY (no thread). Game thread. */
EARSHOT_API earshot_status earshot_context_start_simulation(earshot_context* context, double rate_hz,
                                                            uint32_t sources_per_step);
/** Stops the built-in simulation thread and waits for it (at most one step);
 *  OK if it was not running. Game thread. */
EARSHOT_API earshot_status earshot_context_stop_simulation(earshot_context* context);

/** Renders `frames` frames of binaural output (a context with
 *  EARSHOT_OUTPUT_BINAURAL; INVALID_STATE otherwise): inputs[i] is the dry mono
 *  signal (`frames` floats) of the source whose index
 *  (earshot_source_get_index) is i, for i < input_count; a NULL entry, an
 *  index with no source and every index >= input_count play silence (what
 *  a source played before still arrives: its direct sound in flight, its
 *  reverberation).
 *  `inputs` may be NULL when input_count is 0. input_count is at most
 *  max_sources. `left` and `right` (`frames` floats each, distinct) are
 *  overwritten; an input may be one of them (processing in place: the
 *  source's samples in the buffer its output replaces), and may not
 *  overlap them otherwise (INVALID_ARGUMENT); frames may be any number, 0
 *  included. The output lags the
 *  input by latency_frames. No allocation, lock, log or system call;
 *  arguments are checked but not logged. Audio thread (one thread at a
 *  time per context). */
EARSHOT_API earshot_status earshot_process(earshot_context* context, const float* const* inputs,
                                           size_t input_count, float* left, float* right, size_t frames);

/** As earshot_process, into `output_count` channels (`frames` floats each,
 *  distinct, overwritten): output_count must be earshot_context_info's
 *  output_channels (2 for binaural output: left, right; (order+1)^2 for
 *  EARSHOT_OUTPUT_AMBISONIC, in ACN order). The only way to render an
 *  ambisonic context (earshot_process refuses it: INVALID_STATE). Audio
 *  thread; no allocation, lock, log or system call. */
EARSHOT_API earshot_status earshot_process_channels(earshot_context* context, const float* const* inputs,
                                                    size_t input_count, float* const* outputs, size_t output_count,
                                                    size_t frames);

/** Copies the path of the default HRTF (the SOFA file a context loads when
 *  hrtf_path is NULL) into `buffer` (`capacity` bytes, NUL-terminated) and
 *  stores its length (without the NUL) in *length if `length` is not NULL.
 *  The file is looked up in $EARSHOT_HRTF_DIR, then in share/earshot/hrtf
 *  next to the installed library, then in the source tree it was built from.
 *  Errors: NOT_FOUND (no default HRTF), OUT_OF_RANGE (buffer too small;
 *  *length says how much is needed). Any thread but the audio thread. */
EARSHOT_API earshot_status earshot_hrtf_default_path(char* buffer, size_t capacity, size_t* length);

/** The process's memory limit (bytes; default 1 GiB, the CLI's --max-memory):
 *  what an input file, a ray count (a trace's state, ~150 bytes a ray), an
 *  IR's length and channels (its synthesis) or a context's sources (each
 *  slot in use with the IRs it may hold: 1.2 MB at the defaults, 64 bytes
 *  per frame of max_ir_seconds with binaural reflections, ambisonic_order
 *  0: 185 MB for 60 s at 48 kHz) may make earshot
 *  allocate, estimated before allocating and refused past it
 *  (OUT_OF_RANGE). 0 sets
 *  the default back. Applies to every context from the next call on (a
 *  context created before checks its rays against the limit it saw).
 *  Any thread but the audio thread. */
EARSHOT_API earshot_status earshot_set_memory_limit(uint64_t bytes);
/** Stores the process's memory limit (bytes) in *bytes. */
EARSHOT_API earshot_status earshot_get_memory_limit(uint64_t* bytes);

/* ------------------------------------------------------------------- scene */

typedef struct earshot_scene_settings {
  uint32_t struct_size;        /**< sizeof(earshot_scene_settings) */
  /** Acoustic materials JSON file (format: docs/design.md "Materials file");
   *  NULL = earshot's default set (materials/default.json). */
  const char* materials_path;
} earshot_scene_settings;

/** Fills `settings` with the defaults (and struct_size). Any thread. */
EARSHOT_API earshot_status earshot_scene_settings_init(earshot_scene_settings* settings);

/** Creates an empty scene with the materials of `settings` (NULL: defaults).
 *  The scene uses the context's log, allocator and validation flag but does
 *  not keep it alive, and may serve several contexts. *out holds one
 *  reference (NULL on failure). Errors: INVALID_ARGUMENT, NOT_FOUND / PARSE
 *  (materials file), INTERNAL (no Embree device). Game thread. */
EARSHOT_API earshot_status earshot_scene_create(earshot_context* context, const earshot_scene_settings* settings,
                                                earshot_scene** out);
/** Adds a reference. Game thread. */
EARSHOT_API earshot_status earshot_scene_retain(earshot_scene* scene);
/** Drops a reference; the last one removes every mesh from the scene
 *  (meshes still referenced elsewhere survive, in no scene). Snapshots
 *  already committed stay valid for the contexts using them. Game thread. */
EARSHOT_API earshot_status earshot_scene_release(earshot_scene* scene);

typedef struct earshot_material {
  uint32_t struct_size;                       /**< sizeof(earshot_material) */
  const char* name;                           /**< non-empty; replaces a material of the same name */
  float absorption[EARSHOT_BAND_COUNT];       /**< energy fraction absorbed per reflection, [0, 1] */
  float scattering[EARSHOT_BAND_COUNT];       /**< fraction of reflected energy scattered diffusely, [0, 1] */
  float transmission[EARSHOT_BAND_COUNT];     /**< energy fraction passing through, [0, absorption] */
} earshot_material;

/** Adds (or replaces, by name) an acoustic material of the scene, usable by
 *  meshes added or re-materialled afterwards; it reaches the simulation with
 *  the next commit. Game thread. */
EARSHOT_API earshot_status earshot_scene_add_material(earshot_scene* scene, const earshot_material* material);

/** Adds `mesh` to the scene (the scene takes a reference), resolving its
 *  material names against the scene's materials; takes effect at the next
 *  commit. Errors: INVALID_STATE (already in a scene, or a glTF mesh removed
 *  from its scene: its triangles are not kept), NOT_FOUND (a material name
 *  the scene does not know), INVALID_ARGUMENT. Game thread. */
EARSHOT_API earshot_status earshot_scene_add_mesh(earshot_scene* scene, earshot_mesh* mesh);
/** Removes `mesh` from the scene (dropping the scene's reference); takes
 *  effect at the next commit. INVALID_STATE if it is not in this scene. Game thread. */
EARSHOT_API earshot_status earshot_scene_remove_mesh(earshot_scene* scene, earshot_mesh* mesh);

/** Builds an immutable snapshot of the scene as edited so far and publishes
 *  it to every context using the scene (picked up at their next simulation
 *  step; the previous snapshot keeps serving until then). Moving a movable
 *  mesh rebuilds only a small top-level BVH; adding, removing or moving a
 *  static mesh rebuilds the static BVH. Without edits it is nearly free.
 *  Game thread. */
EARSHOT_API earshot_status earshot_scene_commit(earshot_scene* scene);

typedef struct earshot_gltf_settings {
  uint32_t struct_size;                      /**< sizeof(earshot_gltf_settings) */
  const char* path;                          /**< .gltf or .glb file (UTF-8 path); required */
  /** JSON object {"glTF material name": "acoustic material name"}; NULL: none
   *  (then each glTF material's extras.acoustic_material, then its name). */
  const char* material_map_path;
  /** Names of glTF nodes that become movable meshes (each in its node's own
   *  frame, placed by the node's world transform: rotating it about its
   *  origin swings it as the file's hierarchy would). May be NULL if the
   *  count is 0. Every other node joins one static mesh. */
  const char* const* movable_node_names;
  size_t movable_node_count;                 /**< [0, 65536] */
  /** 0 (default): the file's buffer and image URIs must resolve inside its
   *  folder (symlinks resolved first; absolute paths and .. that climb out
   *  are refused: files from mods or users read only their own folder).
   *  1: any path the process can read. */
  int allow_outside_paths;
  /** Most memory the file may make the engine allocate, estimated before
   *  loading (triangles after instancing, buffers); 0: the default, 1 GiB.
   *  A file past it is refused with EARSHOT_ERROR_OUT_OF_RANGE. */
  uint64_t max_memory_bytes;
} earshot_gltf_settings;

/** Fills `settings` with the defaults (and struct_size). Any thread. */
EARSHOT_API earshot_status earshot_gltf_settings_init(earshot_gltf_settings* settings);

/** Loads a glTF 2.0 file into the scene: its static part as one static mesh
 *  named after the path, each movable node as a movable mesh named after
 *  the node (find them with earshot_scene_find_mesh). Positions are metres
 *  in the file's axes (no axis conversion). Unmapped glTF materials get the
 *  default material and a warning in the log. `settings` and its strings
 *  are only read during the call. All or nothing. Errors:
 *  NOT_FOUND (file, or a movable name that is no node with a mesh), PARSE,
 *  INVALID_ARGUMENT (bad content, named in the message). Game thread. */
EARSHOT_API earshot_status earshot_scene_load_gltf(earshot_scene* scene, const earshot_gltf_settings* settings);

/** Finds the first mesh in the scene (in the order added) named `name`;
 *  *out gets a new reference (release it), NULL with NOT_FOUND if none. Game thread. */
EARSHOT_API earshot_status earshot_scene_find_mesh(earshot_scene* scene, const char* name, earshot_mesh** out);

typedef struct earshot_scene_stats {
  uint32_t struct_size;       /**< set by the caller: sizeof(earshot_scene_stats) */
  uint32_t mesh_count;        /**< meshes in the scene */
  uint64_t commits;           /**< commits that built a new snapshot */
  uint64_t static_bvh_builds; /**< builds of the BVH over all static meshes */
  uint64_t top_level_builds;  /**< builds of a snapshot's BVH over movable meshes */
  double last_commit_ms;      /**< wall time of the last commit that built a snapshot */
} earshot_scene_stats;

/** Reads the scene's counters into *stats (stats->struct_size must be set). Game thread. */
EARSHOT_API earshot_status earshot_scene_get_stats(earshot_scene* scene, earshot_scene_stats* stats);

/* -------------------------------------------------------------------- mesh */

typedef enum earshot_mesh_motion {
  EARSHOT_MESH_STATIC = 0,  /**< baked into the scene's static BVH (walls, floors) */
  EARSHOT_MESH_MOVABLE = 1  /**< its own BVH, instanced: moving it is cheap (doors, vehicles) */
} earshot_mesh_motion;

typedef struct earshot_mesh_settings {
  uint32_t struct_size;          /**< sizeof(earshot_mesh_settings) */
  const char* name;              /**< label for errors and earshot_scene_find_mesh; NULL = "" */
  const float* vertices;         /**< vertex_count * 3 floats (x, y, z; metres; finite), copied */
  size_t vertex_count;           /**< [1, 2^31] */
  const uint32_t* indices;       /**< triangle_count * 3 vertex indices (< vertex_count), copied */
  size_t triangle_count;         /**< [1, 2^31] */
  /** Acoustic material names (of the scene's materials; resolved when the
   *  mesh is added to a scene), material_count >= 1. */
  const char* const* material_names;
  size_t material_count;         /**< [1, 65536] */
  /** Per triangle, an index into material_names; NULL: every triangle uses material_names[0]. */
  const uint32_t* triangle_materials;
  earshot_mesh_motion motion;    /**< default EARSHOT_MESH_STATIC */
  /** Initial transform (mesh frame -> world), row-major 3x4 (element [r * 4 + c];
   *  column 3 is the translation in metres); NULL = identity. Finite, invertible. */
  const float* transform;
} earshot_mesh_settings;

/** Fills `settings` with the defaults (and struct_size). Any thread. */
EARSHOT_API earshot_status earshot_mesh_settings_init(earshot_mesh_settings* settings);

/** Creates a mesh from vertex and index arrays (copied). It is in no scene
 *  until earshot_scene_add_mesh. *out holds one reference (NULL on failure).
 *  Errors: INVALID_ARGUMENT (naming the bad vertex, index or material
 *  index), OUT_OF_MEMORY. Game thread. */
EARSHOT_API earshot_status earshot_mesh_create(earshot_context* context, const earshot_mesh_settings* settings,
                                               earshot_mesh** out);
/** Adds a reference. Game thread. */
EARSHOT_API earshot_status earshot_mesh_retain(earshot_mesh* mesh);
/** Drops a reference. A mesh in a scene stays there (the scene holds a
 *  reference) until removed. Game thread. */
EARSHOT_API earshot_status earshot_mesh_release(earshot_mesh* mesh);

/** Places the mesh (its frame -> world): a row-major 3x4 matrix (element
 *  [r * 4 + c], column 3 the translation in metres), finite and invertible
 *  (rigid motions are what the acoustics expect). In a scene it takes effect
 *  at the next commit. Game thread (the thread that edits its scene). */
EARSHOT_API earshot_status earshot_mesh_set_transform(earshot_mesh* mesh, const float* matrix3x4);
/** As earshot_mesh_set_transform, from a column-major 4x4 matrix (glTF,
 *  OpenGL; element [c * 4 + r]); the last row is ignored. Game thread. */
EARSHOT_API earshot_status earshot_mesh_set_transform_4x4(earshot_mesh* mesh, const float* matrix4x4);
/** Writes the mesh's current transform (row-major 3x4, 12 floats) to
 *  `matrix3x4`: for a glTF movable node, its world transform in the file
 *  until changed. Game thread. */
EARSHOT_API earshot_status earshot_mesh_get_transform(earshot_mesh* mesh, float* matrix3x4);
/** Gives every triangle of the mesh the acoustic material `name`. In a
 *  scene it must be one of the scene's materials (NOT_FOUND otherwise) and
 *  takes effect at the next commit without rebuilding a BVH; outside a
 *  scene it is resolved when the mesh is added. Game thread. */
EARSHOT_API earshot_status earshot_mesh_set_material(earshot_mesh* mesh, const char* name);

/* ------------------------------------------------------------------ source */

typedef enum earshot_direct_mode {
  /** The direct sound is rendered every audio block from the latest poses
   *  (delay with Doppler, distance, HRTF of the current head direction):
   *  for moving sources. Default. */
  EARSHOT_DIRECT_PER_BLOCK = 0,
  /** The direct sound is part of the convolved IR, exactly as `earshot ir`
   *  computes it, updated only when simulated: for static sources. */
  EARSHOT_DIRECT_IN_IMPULSE_RESPONSE = 1
} earshot_direct_mode;

/** How the per-block direct sound falls off with distance d (pressure
 *  gain); the reflections stay physical whatever the curve. D is d clamped
 *  to [min_distance, max_distance]. */
typedef enum earshot_distance_model {
  EARSHOT_DISTANCE_PHYSICAL = 0,    /**< 1 / max(d, 0.1 m): the physics (default) */
  EARSHOT_DISTANCE_INVERSE = 1,     /**< min / (min + rolloff (D - min)) */
  EARSHOT_DISTANCE_LINEAR = 2,      /**< 1 - rolloff (D - min) / (max - min), at least 0 */
  EARSHOT_DISTANCE_EXPONENTIAL = 3, /**< (D / min)^-rolloff */
  EARSHOT_DISTANCE_TABLE = 4        /**< distance_table: linear between its points, flat beyond its ends */
} earshot_distance_model;

/** Points of EARSHOT_DISTANCE_TABLE, at most this many. */
#define EARSHOT_DISTANCE_TABLE_POINTS 16

/** How geometry between source and listener occludes the direct sound. */
typedef enum earshot_occlusion_mode {
  EARSHOT_OCCLUSION_RAY = 0,        /**< one ray from the source's centre (default) */
  EARSHOT_OCCLUSION_OFF = 1,        /**< never occluded */
  EARSHOT_OCCLUSION_VOLUMETRIC = 2  /**< energy average of 16 rays to points on a sphere of `radius` m */
} earshot_occlusion_mode;

typedef struct earshot_source_settings {
  uint32_t struct_size;           /**< sizeof(earshot_source_settings) */
  float gain_db;                  /**< the whole source, [-120, 40]; default 0 */
  earshot_direct_mode direct;     /**< default EARSHOT_DIRECT_PER_BLOCK; fixed at creation */
  float direct_gain_db;           /**< the per-block direct sound, [-120, 40]; default 0 */
  float reflections_gain_db;      /**< the reflections and reverberation, [-120, 40]; default 0 */
  earshot_distance_model distance_model; /**< the direct sound's fall-off; default PHYSICAL */
  float min_distance;             /**< metres, (0, 1e6]; default 1 */
  float max_distance;             /**< metres, [min_distance, 1e6]; default 100 */
  float rolloff;                  /**< [0, 100]; default 1 */
  /** EARSHOT_DISTANCE_TABLE: distance_table_count points (1 ..
   *  EARSHOT_DISTANCE_TABLE_POINTS), distances (m) ascending in [0, 1e6],
   *  pressure gains in [0, 10]. */
  uint32_t distance_table_count;
  float distance_table_distance[EARSHOT_DISTANCE_TABLE_POINTS];
  float distance_table_gain[EARSHOT_DISTANCE_TABLE_POINTS];
  earshot_occlusion_mode occlusion; /**< default EARSHOT_OCCLUSION_RAY */
  float radius;                   /**< VOLUMETRIC's sphere, metres, (0, 100]; default 0.5 */
  /** 1 (default): an occluded direct path passes through the surfaces,
   *  filtered by their materials' transmission; 0: it is silent. */
  int32_t transmission;
  /** Higher first when a simulation step cannot take every source
   *  (earshot_simulate's source_count); default 0. */
  int32_t priority;
  /** Directivity about the source's forward vector (earshot_source_set_orientation):
   *  g(theta) = |(1 - alpha) + alpha cos(theta)|^sharpness; alpha [0, 1]
   *  (0 omni, default; 0.5 cardioid; 1 figure-8), sharpness [1, 16]
   *  (default 1). Power-normalised: the source radiates an omni source's
   *  power, so its reverberation does not depend on where it faces, and on
   *  its axis it is louder by its directivity index (cardioid 4.8 dB). The
   *  direct sound follows the pattern every block; the reflections leave
   *  along each ray's and image source's own direction (a source facing a
   *  wall still fills the room), updated at the next simulation. */
  float directivity_alpha;
  float directivity_sharpness;
  /** 1: directivity_band_alpha (one alpha per band, 125 Hz .. 8 kHz) instead
   *  of directivity_alpha, e.g. a loudspeaker omni at 125 Hz and cardioid at
   *  4 kHz. Default 0. */
  int32_t directivity_per_band;
  float directivity_band_alpha[EARSHOT_BAND_COUNT];
} earshot_source_settings;

/** Fills `settings` with the defaults (and struct_size). Any thread. */
EARSHOT_API earshot_status earshot_source_settings_init(earshot_source_settings* settings);

/** Creates a source in one of the context's slots (settings NULL: defaults),
 *  at the origin facing (0, 0, -1) (earshot_source_create_at: where it is).
 *  Its direct sound plays from the next audio block
 *  (EARSHOT_DIRECT_PER_BLOCK, the default), its reflections once simulated;
 *  a source with EARSHOT_DIRECT_IN_IMPULSE_RESPONSE is heard once simulated
 *  (its direct sound is part of its IR). The source holds a
 *  reference to the context. *out holds one reference (NULL on failure).
 *  The first source waits for the context's HRTF to finish loading; a slot's
 *  first source allocates its state (~0.2 ms). Errors: INVALID_ARGUMENT,
 *  OUT_OF_RANGE (all max_sources slots in use, or a new slot's state would
 *  take the slots in use past the memory limit: earshot_set_memory_limit),
 *  PARSE / NOT_FOUND (the HRTF failed to load), OUT_OF_MEMORY. Game thread. */
EARSHOT_API earshot_status earshot_source_create(earshot_context* context, const earshot_source_settings* settings,
                                                 earshot_source** out);
/** earshot_source_create, with the source already at `position` (metres,
 *  finite, within 1e6 m of the origin) facing `forward` (finite,
 *  non-zero; earshot_source_set_orientation). Created then moved, a source
 *  may have its first audio block played from where it was created (the
 *  origin) if the audio thread runs in between, and glide from there; a
 *  source created where it is plays from there from its first block, and
 *  its first simulation traces from there. For one-shots and any source
 *  that plays as soon as it is created. Errors: those of
 *  earshot_source_create; INVALID_ARGUMENT for a non-finite position or a
 *  zero or non-finite forward, OUT_OF_RANGE for a position farther than
 *  1e6 m (no source is created). Game thread. */
EARSHOT_API earshot_status earshot_source_create_at(earshot_context* context, const earshot_source_settings* settings,
                                                    earshot_vec3 position, earshot_vec3 forward,
                                                    earshot_source** out);
/** Adds a reference. Game thread. */
EARSHOT_API earshot_status earshot_source_retain(earshot_source* source);
/** Drops a reference; the last one frees the slot: the source plays no
 *  more from the next audio block, and what it already played still
 *  arrives: its direct sound in flight (a source 34 m away is heard 0.1 s
 *  after it plays) and its reverberation, which rings out through its IR
 *  over up to max_ir_seconds. So a one-shot may be released as soon as its
 *  last sample has been passed to earshot_process, also before its first
 *  simulation: the next earshot_simulate still makes its first IR (where
 *  it was), and what it played is heard through it. The index may be reused
 *  by a later source: earshot_source_create gives a new source a slot
 *  whose last source has rung out (or never played), else a slot never
 *  used, and only when neither is free the one whose ring-out ends first
 *  (the new source then cuts that direct sound, and the reverberation
 *  fades out; nothing of it goes through the new source's IR unless that
 *  IR lands before the fade ends). Game thread. */
EARSHOT_API earshot_status earshot_source_release(earshot_source* source);

/** The source's slot index in [0, max_sources): its position in the
 *  `inputs` array of earshot_process(). Fixed for the source's life. Any thread. */
EARSHOT_API earshot_status earshot_source_get_index(earshot_source* source, uint32_t* index);
/** Moves the source (metres, finite). The direct sound follows from the
 *  next audio block (with Doppler): a game that moves it every frame is
 *  followed at the speed its positions give, the change spread over the
 *  interval between its updates (a 60 Hz game's motion is steady Doppler,
 *  not a staircase of delays; the direct sound runs one to two of the
 *  game's frames behind). The first move after 0.1 s without one, and one
 *  faster than half the speed of sound (a teleport, crossfaded), are
 *  heard within the next block. The reflections follow at the source's
 *  next simulation. Game thread (any thread but the audio thread). */
EARSHOT_API earshot_status earshot_source_set_position(earshot_source* source, earshot_vec3 position);
/** Sets the source's gain in dB, [-120, 40]; ramped over the next audio
 *  block, or, set once a game frame (a fade), glided over the interval
 *  between the game's updates as positions are (a smooth fade, not a
 *  staircase). Game thread (any thread but the audio thread). */
EARSHOT_API earshot_status earshot_source_set_gain_db(earshot_source* source, float gain_db);
/** Turns the source: `forward` (world frame, finite, non-zero) is the axis
 *  of its directivity. Default (0, 0, -1). The direct sound follows from
 *  the next audio block, a turn set once a game frame glided as positions
 *  are (a smooth turn, not a staircase of levels); the reflections at the
 *  next simulation. Game thread. */
EARSHOT_API earshot_status earshot_source_set_orientation(earshot_source* source, earshot_vec3 forward);
/** Replaces the source's controls with `settings` (all fields but `direct`,
 *  which must equal the source's: it is fixed at creation), all at once:
 *  the audio thread never hears some of one call's controls with the rest
 *  of another's (nor with another thread's set_gain_db). Gains glide as
 *  earshot_source_set_gain_db's does; the distance curve ramps over the
 *  next audio block (no clicks); EARSHOT_OCCLUSION_OFF applies from the
 *  next block, the other occlusion modes, `radius` and `transmission` at
 *  the source's next simulation.
 *  Errors: INVALID_ARGUMENT (naming the field). Game thread. */
EARSHOT_API earshot_status earshot_source_set_settings(earshot_source* source,
                                                       const earshot_source_settings* settings);
/** The source's current controls (settings->struct_size set by the caller).
 *  Game thread. */
EARSHOT_API earshot_status earshot_source_get_settings(earshot_source* source, earshot_source_settings* settings);

/** The source's direct path as its last simulation found it: how much of
 *  each band gets through the geometry between source and listener, what
 *  the direct sound is filtered with (EARSHOT_OCCLUSION_OFF: found the way
 *  EARSHOT_OCCLUSION_RAY finds it, not applied). For a game's own use: an
 *  AI's hearing, a voice chat muffled through a wall. */
typedef struct earshot_source_occlusion {
  uint32_t struct_size; /**< sizeof(earshot_source_occlusion), set by the caller */
  /** Pressure factor per band (EARSHOT_BAND_COUNT, 125 Hz .. 8 kHz) through
   *  occluders, air absorption not included: 1 clear, 0 blocked
   *  (EARSHOT_OCCLUSION_VOLUMETRIC: the energy average over rays spread
   *  across the source's radius). */
  float transmission[EARSHOT_BAND_COUNT];
  uint32_t audible;   /**< 0: no band gets through (or transmission off and a surface in the way) */
  uint32_t simulated; /**< 0: not simulated since the source was created (then transmission all 1) */
} earshot_source_occlusion;

/** The occlusion of the source's last simulation (occlusion->struct_size
 *  set by the caller), whole: never some bands of one simulation with the
 *  rest of another's. Game thread or any thread but the audio thread (takes
 *  a lock a simulation's write takes, briefly). */
EARSHOT_API earshot_status earshot_source_get_occlusion(earshot_source* source, earshot_source_occlusion* occlusion);

/* ---------------------------------------------------------------------- IR */

/* An impulse response, for baking, editor previews or a game's own
 * convolution: immutable once made, so any thread may read it; released by
 * its last reference. Layout: `channels` planar float channels (binaural:
 * 0 left, 1 right; omni: 1) of `frames` samples at `sample_rate_hz`; time 0
 * is the emission; amplitude is pressure with 1/r spreading (a source 1 m
 * away has a direct sound of 1.0); never normalised. */

typedef enum earshot_receiver {
  EARSHOT_RECEIVER_BINAURAL = 0, /**< 2 channels through the context's HRTF */
  EARSHOT_RECEIVER_OMNI = 1,     /**< 1 channel */
  /** (ambisonic_order+1)^2 AmbiX channels (ACN, SN3D) in the listener's
   *  frame (x forward, y left, z up, from the request's forward and up),
   *  the direct sound included, W the omni IR: `earshot ir --receiver
   *  ambisonic --order N`. */
  EARSHOT_RECEIVER_AMBISONIC = 2
} earshot_receiver;

typedef struct earshot_ir_info {
  uint32_t struct_size;     /**< sizeof(earshot_ir_info), set by the caller */
  uint32_t channels;        /**< 1 (omni), 2 (binaural: left, right) or (order+1)^2 (ambisonic, ACN) */
  uint64_t frames;          /**< samples per channel */
  double sample_rate_hz;    /**< the context's rate */
  uint32_t includes_direct; /**< 1 if the direct sound is in the IR */
  uint64_t simulation;      /**< a source's IR: its number (1 = the source's first); 0 for a computed IR */
  /** A source's IR: seconds from when the simulation read the poses it
   *  was computed from to this call (how far behind the scene its
   *  reflections are); 0 for a computed IR. */
  double age_seconds;
} earshot_ir_info;

/** The IR the source's last simulation made and its reflections are being
 *  convolved with (a shared, immutable copy: later simulations do not change
 *  it): binaural with ambisonic_order 0; with ambisonic_order 1-3 the
 *  world-frame AmbiX IR of that order (ACN, SN3D; its frame: x = world -Z,
 *  y = world -X, z = world +Y, the glTF default listener's). With
 *  EARSHOT_DIRECT_IN_IMPULSE_RESPONSE it holds the
 *  direct sound (then, with ambisonic_order 0, it is the IR `earshot ir`
 *  computes for the same positions and settings, if that IR ends within
 *  max_ir_seconds), with EARSHOT_DIRECT_PER_BLOCK the reflections
 *  only; cut at max_ir_seconds with a 10 ms fade (the engine simulates no
 *  further: a longer IR is the same room's energies up to the cut, another
 *  realisation of the noise than `earshot ir`'s). With a shared tail the
 *  engine may have synthesised only the start of it (the tail of another
 *  source stood for its own): a call then makes the whole IR (a few
 *  milliseconds; the same bits), and the context keeps the last one made
 *  (one, not one a source). *out holds one reference.
 *  Errors: NOT_FOUND (the source has not been simulated yet). Game thread or
 *  any thread but the audio thread (takes a lock the simulation also takes,
 *  briefly). */
EARSHOT_API earshot_status earshot_source_get_ir(earshot_source* source, earshot_ir** out);

typedef struct earshot_ir_request {
  uint32_t struct_size;       /**< sizeof(earshot_ir_request) */
  earshot_vec3 source;        /**< metres, finite; default (0, 0, -1) */
  earshot_vec3 listener;      /**< metres, finite; default origin */
  earshot_vec3 forward;       /**< listener's forward; default (0, 0, -1) */
  earshot_vec3 up;            /**< listener's up; default (0, 1, 0) */
  earshot_receiver receiver;  /**< default EARSHOT_RECEIVER_BINAURAL */
  uint64_t seed;              /**< default 0: the context's seed */
  uint32_t ambisonic_order;   /**< EARSHOT_RECEIVER_AMBISONIC's order, [1, 3]; default 1 */
} earshot_ir_request;

/** Fills `request` with the defaults above (and struct_size). Any thread. */
EARSHOT_API earshot_status earshot_ir_request_init(earshot_ir_request* request);
/** Computes the complete IR (direct sound included, not cut) of one
 *  source/listener pair in the scene the context follows (its latest
 *  commit; no scene: free field) with the context's simulation settings
 *  (rays, bounces, image-source order, seed, HRTF, rate): the IR `earshot
 *  ir` computes for the same inputs. Takes as long as a simulation (tens to
 *  hundreds of ms) on the context's worker threads. *out holds one
 *  reference. Errors: INVALID_ARGUMENT (non-finite or parallel vectors,
 *  unknown receiver), OUT_OF_RANGE (positions beyond 1e6 m). Any thread but
 *  the audio thread. */
EARSHOT_API earshot_status earshot_context_compute_ir(earshot_context* context, const earshot_ir_request* request,
                                                      earshot_ir** out);

/** Its layout (info->struct_size set by the caller). Any thread. */
EARSHOT_API earshot_status earshot_ir_get_info(const earshot_ir* ir, earshot_ir_info* info);
/** Copies channel `channel` (all `frames` samples) into `buffer`, which
 *  holds `capacity_frames` floats. Errors: INVALID_ARGUMENT (no such
 *  channel, NULL buffer), OUT_OF_RANGE (capacity_frames < frames: nothing
 *  copied). Any thread. */
EARSHOT_API earshot_status earshot_ir_copy_channel(const earshot_ir* ir, uint32_t channel, float* buffer,
                                                   uint64_t capacity_frames);
/** Adds a reference. Any thread. */
EARSHOT_API earshot_status earshot_ir_retain(earshot_ir* ir);
/** Drops a reference; the last one frees it. Any thread but the audio thread. */
EARSHOT_API earshot_status earshot_ir_release(earshot_ir* ir);

#ifdef __cplusplus
}  /* extern "C" */
#endif

#endif /* EARSHOT_EARSHOT_H */
