/* game_loop.c: earshot from plain C99, the way a game uses it.
 *
 * Loads the two-room glTF scene (z up; the `door` node movable), puts the
 * listener in room A facing the partition, and runs 10 s of game time at
 * 90 frames per second: a source circles the listener (2 m, one turn every
 * 5 s), the door swings open at 3 s and shut at 7 s, reflections are
 * simulated at 10 Hz (every 9th frame) and the audio "device" pulls 48 kHz
 * audio in 256-frame blocks as game time passes. The binaural result goes to
 * a 32-bit float stereo WAV.
 *
 *   earshot_game_loop [two_rooms.gltf [materials_map.json [out.wav]]]
 *
 * Defaults: samples/two_rooms/two_rooms.gltf, samples/two_rooms/materials_map.json
 * (relative to the working directory) and game_loop.wav. Exit status 0 on
 * success. A real game would run earshot_process() in its audio callback and
 * the simulation on earshot_context_start_simulation()'s thread; here all of
 * it runs in one loop so that the output is the same on every run. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "earshot/earshot.h"

#define SAMPLE_RATE 48000
#define BLOCK 256
#define GAME_HZ 90
#define SIMULATION_EVERY 9 /* frames: 10 Hz */
#define SECONDS 10
#define PI 3.14159265358979323846

/* Any failure: say which call and why, then quit. */
#define CHECK(call)                                                                     \
  do {                                                                                  \
    earshot_status check_status = (call);                                               \
    if (check_status != EARSHOT_OK) {                                                   \
      fprintf(stderr, "%s failed: %s (%s)\n", #call, earshot_status_string(check_status), \
              earshot_last_error_message());                                           \
      exit(1);                                                                          \
    }                                                                                   \
  } while (0)

static void on_log(void* user_data, earshot_log_level level, const char* message) {
  static const char* names[] = {"error", "warning", "info", "debug"};
  (void)user_data;
  fprintf(stderr, "earshot %s: %s\n", names[level], message);
}

/* ---- a minimal float WAV writer (RIFF, WAVE_FORMAT_IEEE_FLOAT) ---- */

static void put_u32(unsigned char* p, uint32_t v) {
  p[0] = (unsigned char)(v & 0xff);
  p[1] = (unsigned char)((v >> 8) & 0xff);
  p[2] = (unsigned char)((v >> 16) & 0xff);
  p[3] = (unsigned char)((v >> 24) & 0xff);
}

static void put_u16(unsigned char* p, uint16_t v) {
  p[0] = (unsigned char)(v & 0xff);
  p[1] = (unsigned char)((v >> 8) & 0xff);
}

/* The 44-byte header of a 2-channel float WAV holding `frames` frames. */
static void wav_header(unsigned char h[44], uint32_t frames) {
  const uint32_t data_bytes = frames * 2u * 4u;
  memcpy(h, "RIFF", 4);
  put_u32(h + 4, 36u + data_bytes);
  memcpy(h + 8, "WAVEfmt ", 8);
  put_u32(h + 16, 16);                 /* fmt chunk size */
  put_u16(h + 20, 3);                  /* WAVE_FORMAT_IEEE_FLOAT */
  put_u16(h + 22, 2);                  /* channels */
  put_u32(h + 24, SAMPLE_RATE);
  put_u32(h + 28, SAMPLE_RATE * 2u * 4u); /* bytes per second */
  put_u16(h + 32, 2u * 4u);           /* bytes per frame */
  put_u16(h + 34, 32);                 /* bits per sample */
  memcpy(h + 36, "data", 4);
  put_u32(h + 40, data_bytes);
}

/* Appends one block, interleaved little-endian. 0 on a write error. */
static int wav_write(FILE* f, const float* left, const float* right, size_t frames) {
  unsigned char buf[BLOCK * 8];
  size_t i;
  for (i = 0; i < frames; ++i) {
    uint32_t l, r;
    memcpy(&l, &left[i], 4);
    memcpy(&r, &right[i], 4);
    put_u32(buf + 8 * i, l);
    put_u32(buf + 8 * i + 4, r);
  }
  return fwrite(buf, 8, frames, f) == frames;
}

/* ---- the dry signal: a 220 Hz buzz with short noise bursts ---- */

static float dry_sample(uint64_t n, uint32_t* noise_state) {
  const double t = (double)n / SAMPLE_RATE;
  double buzz = 0.0;
  int h;
  float noise;
  for (h = 1; h <= 6; ++h) buzz += sin(2.0 * PI * 220.0 * h * t) / h;
  *noise_state = *noise_state * 1664525u + 1013904223u; /* LCG */
  noise = (float)((*noise_state >> 8) * (1.0 / 16777216.0) * 2.0 - 1.0);
  /* a 60 ms burst every half second */
  return (float)(0.15 * buzz) + (fmod(t, 0.5) < 0.06 ? 0.5f * noise : 0.0f);
}

/* ---- the door: rotate its node about its own z axis (the hinge) ---- */

static void door_transform(const float initial[12], double radians, float out[12]) {
  /* out = initial * Rz(radians): turn in the node's frame, then place it. */
  const double c = cos(radians), s = sin(radians);
  const double rz[3][3] = {{c, -s, 0.0}, {s, c, 0.0}, {0.0, 0.0, 1.0}};
  int r, k, col;
  for (r = 0; r < 3; ++r) {
    for (col = 0; col < 3; ++col) {
      double v = 0.0;
      for (k = 0; k < 3; ++k) v += initial[r * 4 + k] * rz[k][col];
      out[r * 4 + col] = (float)v;
    }
    out[r * 4 + 3] = initial[r * 4 + 3];
  }
}

/* Door angle (radians) at game time t: opens over 3-4 s, closes over 7-8 s.
 * Negative: it swings into room B, away from the listener. */
static double door_angle(double t) {
  const double open = -0.5 * PI;
  if (t < 3.0) return 0.0;
  if (t < 4.0) return open * (t - 3.0);
  if (t < 7.0) return open;
  if (t < 8.0) return open * (8.0 - t);
  return 0.0;
}

int main(int argc, char** argv) {
  const char* gltf_path = argc > 1 ? argv[1] : "samples/two_rooms/two_rooms.gltf";
  const char* map_path = argc > 2 ? argv[2] : "samples/two_rooms/materials_map.json";
  const char* out_path = argc > 3 ? argv[3] : "game_loop.wav";
  const char* movable[] = {"door"};
  const earshot_vec3 listener = {3.0f, 2.5f, 1.7f};
  const earshot_vec3 forward = {1.0f, 0.0f, 0.0f}; /* facing the partition (+x) */
  const earshot_vec3 up = {0.0f, 0.0f, 1.0f};      /* the samples are z-up */
  const earshot_vec3 toward_listener = {-1.0f, 0.0f, 0.0f};
  earshot_vec3 start;
  earshot_context_settings settings;
  earshot_gltf_settings gltf;
  earshot_context* context = NULL;
  earshot_scene* scene = NULL;
  earshot_mesh* door = NULL;
  earshot_source* source = NULL;
  earshot_source_settings source_settings;
  double peak = 0.0;
  float door_initial[12], door_now[12];
  double door_applied = 0.0;
  float dry[BLOCK], left[BLOCK], right[BLOCK];
  const float* inputs[1];
  uint32_t index, noise_state = 1;
  uint64_t audio_frames = 0, dry_frames = 0;
  char tmp_path[4096];
  unsigned char header[44];
  FILE* wav;
  int frame;

  /* The context: 48 kHz, 256-frame convolver blocks, the default HRTF. */
  CHECK(earshot_context_settings_init(&settings));
  settings.sample_rate_hz = SAMPLE_RATE;
  settings.block_frames = BLOCK;
  settings.max_sources = 1;
  settings.max_ir_seconds = 1.5;
  settings.rays = 4096;
  settings.image_source_order = 2;
  settings.flags = EARSHOT_CONTEXT_VALIDATION;
  settings.log = on_log;
  CHECK(earshot_context_create(&settings, &context));

  /* The scene: glTF with the door movable, then its first snapshot. */
  CHECK(earshot_scene_create(context, NULL, &scene));
  CHECK(earshot_gltf_settings_init(&gltf));
  gltf.path = gltf_path;
  gltf.material_map_path = map_path;
  gltf.movable_node_names = movable;
  gltf.movable_node_count = 1;
  CHECK(earshot_scene_load_gltf(scene, &gltf));
  CHECK(earshot_scene_find_mesh(scene, "door", &door));
  CHECK(earshot_mesh_get_transform(door, door_initial));
  CHECK(earshot_scene_commit(scene));
  CHECK(earshot_context_set_scene(context, scene));

  /* The talker's level: at 2 m with the rooms' reflections and the HRTF's
   * gain toward the near ear the output peaked at +5.9 dBFS at 0 dB; -12 dB
   * keeps it below full scale (the sample prints the peak). */
  earshot_source_settings_init(&source_settings);
  source_settings.gain_db = -12.0f;
  /* Created where it starts (2 m ahead, facing the listener): a source
   * created and then moved may play its first audio block from where it was
   * created, if the audio thread runs between the two calls. */
  start.x = listener.x + 2.0f;
  start.y = listener.y;
  start.z = listener.z;
  CHECK(earshot_source_create_at(context, &source_settings, start, toward_listener, &source));
  CHECK(earshot_source_get_index(source, &index));
  if (index != 0) {
    fprintf(stderr, "unexpected source index %u\n", (unsigned)index);
    return 1;
  }

  if (strlen(out_path) + 5 > sizeof(tmp_path)) {
    fprintf(stderr, "output path too long\n");
    return 1;
  }
  sprintf(tmp_path, "%s.tmp", out_path);
  wav = fopen(tmp_path, "wb");
  if (!wav) {
    fprintf(stderr, "cannot write %s\n", tmp_path);
    return 1;
  }
  memset(header, 0, sizeof(header));
  if (fwrite(header, 1, sizeof(header), wav) != sizeof(header)) return 1;

  for (frame = 0; frame < GAME_HZ * SECONDS; ++frame) {
    const double t = (double)frame / GAME_HZ;
    const double angle = 2.0 * PI * t / 5.0; /* starts ahead, turns left */
    const double door_target = door_angle(t);
    earshot_vec3 position;
    const uint64_t audio_due = (uint64_t)(frame + 1) * SAMPLE_RATE / GAME_HZ;

    /* Game thread: poses and scene edits. */
    position.x = listener.x + (float)(2.0 * cos(angle));
    position.y = listener.y + (float)(2.0 * sin(angle));
    position.z = listener.z;
    CHECK(earshot_source_set_position(source, position));
    CHECK(earshot_context_set_listener(context, listener, forward, up));
    if (door_target != door_applied) {
      door_transform(door_initial, door_target, door_now);
      CHECK(earshot_mesh_set_transform(door, door_now));
      CHECK(earshot_scene_commit(scene)); /* instanced: no rebuild of the rooms */
      door_applied = door_target;
    }

    /* Simulation thread: reflections at 10 Hz. */
    if (frame % SIMULATION_EVERY == 0) CHECK(earshot_simulate(context, 0));

    /* Audio thread: the blocks that fall due during this frame. */
    while (audio_frames + BLOCK <= audio_due) {
      int i;
      for (i = 0; i < BLOCK; ++i) dry[i] = dry_sample(dry_frames++, &noise_state);
      inputs[0] = dry;
      CHECK(earshot_process(context, inputs, 1, left, right, BLOCK));
      for (i = 0; i < BLOCK; ++i) {
        if (fabs(left[i]) > peak) peak = fabs(left[i]);
        if (fabs(right[i]) > peak) peak = fabs(right[i]);
      }
      if (!wav_write(wav, left, right, BLOCK)) {
        fprintf(stderr, "write error on %s\n", tmp_path);
        return 1;
      }
      audio_frames += BLOCK;
    }
  }

  wav_header(header, (uint32_t)audio_frames);
  if (fseek(wav, 0, SEEK_SET) != 0 || fwrite(header, 1, sizeof(header), wav) != sizeof(header) || fclose(wav) != 0 ||
      rename(tmp_path, out_path) != 0) {
    fprintf(stderr, "cannot finish %s\n", out_path);
    return 1;
  }
  printf("wrote %s: %.2f s of binaural audio, peak %.1f dBFS\n", out_path, (double)audio_frames / SAMPLE_RATE,
         20.0 * log10(peak > 1e-30 ? peak : 1e-30));

  CHECK(earshot_source_release(source));
  CHECK(earshot_mesh_release(door));
  CHECK(earshot_scene_release(scene));
  CHECK(earshot_context_release(context));
  return 0;
}
