/* Uses an installed earshot from C: a box room, one source, one simulation,
 * 4096 frames of audio that must be finite and not silent. argv[1]: the
 * install prefix, which the default HRTF's path must lie under (found next to
 * the installed library), or "-" not to check. Prints "ok" and exits 0. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "earshot/earshot.h"

#define CHECK(call)                                                                                    \
  do {                                                                                                 \
    earshot_status s_ = (call);                                                                        \
    if (s_ != EARSHOT_OK) {                                                                            \
      fprintf(stderr, "%s: %s (%s)\n", #call, earshot_status_string(s_), earshot_last_error_message()); \
      return 1;                                                                                        \
    }                                                                                                  \
  } while (0)

int main(int argc, char** argv) {
  static const float v[24] = {0, 0, 0, 5, 0, 0, 5, 4, 0, 0, 4, 0, 0, 0, 3, 5, 0, 3, 5, 4, 3, 0, 4, 3};
  static const uint32_t idx[36] = {0, 1, 2, 0, 2, 3, 4, 6, 5, 4, 7, 6, 0, 4, 5, 0, 5, 1,
                                   3, 2, 6, 3, 6, 7, 0, 3, 7, 0, 7, 4, 1, 5, 6, 1, 6, 2};
  const char* materials[] = {"brick"};
  const earshot_vec3 listener = {2.5f, 2.0f, 1.5f}, forward = {0, 1, 0}, up = {0, 0, 1}, at = {1.0f, 3.0f, 1.5f};
  char path[4096];
  earshot_context_settings settings;
  earshot_mesh_settings mesh_settings;
  earshot_context* context = NULL;
  earshot_scene* scene = NULL;
  earshot_mesh* mesh = NULL;
  earshot_source* source = NULL;
  static float dry[4096], left[4096], right[4096];
  const float* inputs[1];
  double e = 0.0;
  size_t i;

  CHECK(earshot_hrtf_default_path(path, sizeof(path), NULL));
  if (argc > 1 && strcmp(argv[1], "-") != 0 && strncmp(path, argv[1], strlen(argv[1])) != 0) {
    fprintf(stderr, "default HRTF %s is not under %s\n", path, argv[1]);
    return 1;
  }
  CHECK(earshot_context_settings_init(&settings));
  settings.max_sources = 2;
  settings.rays = 1000;
  settings.max_ir_seconds = 0.5;
  CHECK(earshot_context_create(&settings, &context));
  CHECK(earshot_scene_create(context, NULL, &scene));
  CHECK(earshot_mesh_settings_init(&mesh_settings));
  mesh_settings.vertices = v;
  mesh_settings.vertex_count = 8;
  mesh_settings.indices = idx;
  mesh_settings.triangle_count = 12;
  mesh_settings.material_names = materials;
  mesh_settings.material_count = 1;
  CHECK(earshot_mesh_create(context, &mesh_settings, &mesh));
  CHECK(earshot_scene_add_mesh(scene, mesh));
  CHECK(earshot_scene_commit(scene));
  CHECK(earshot_context_set_scene(context, scene));
  CHECK(earshot_context_set_listener(context, listener, forward, up));
  CHECK(earshot_source_create(context, NULL, &source));
  CHECK(earshot_source_set_position(source, at));
  CHECK(earshot_simulate(context, 0));
  for (i = 0; i < 4096; i += 100) dry[i] = 1.0f;
  inputs[0] = dry;
  CHECK(earshot_process(context, inputs, 1, left, right, 4096));
  for (i = 0; i < 4096; ++i) {
    if (!isfinite(left[i]) || !isfinite(right[i])) return 1;
    e += left[i] * left[i] + right[i] * right[i];
  }
  if (!(e > 0.0)) {
    fprintf(stderr, "silent output\n");
    return 1;
  }
  CHECK(earshot_source_release(source));
  CHECK(earshot_mesh_release(mesh));
  CHECK(earshot_scene_release(scene));
  CHECK(earshot_context_release(context));
  printf("ok (HRTF %s)\n", path);
  return 0;
}
