#pragma once
/** @file What one computed IR says about itself, as JSON text: the settings
 *  used, the direct path, early reflections, the trace's counts, the traced
 *  decay, the tail and the time of each stage. `earshot ir --json` and the
 *  Python package (`IR.params`, `IR.stats`, `IR.time_ms`) both report
 *  through this one function, so their fields and numbers are the same. */
#include <string>
#include <vector>

#include "earshot/ir/ir_pipeline.h"

namespace earshot {

/** A JSON object (text) with the keys settings, direct, early_reflections,
 *  rays_traced, rays_escaped, rays_cut_by_bounce_limit,
 *  rays_ended_by_roulette, segments_traced, tail_probe_segments,
 *  flutter_axes, flutter_cone_rays, rays_requested, estimated_error_db
 *  (when converging), shadow_rays, shadow_rays_skipped,
 *  specular_detections_left_to_image_sources, energy_escaped_fraction,
 *  receiver_radius_m, decay, tail, skipped, time_ms, ir_samples,
 *  ir_seconds, silent. `geometryTraced` false (free field): no ray was
 *  traced, and the counts say so. */
std::string irReportJson(const OmniIrResult& result, const OmniIrSettings& settings, bool geometryTraced);

/** What a computed IR says is probably not meant, one line each (`earshot
 *  ir` prints them, the Python package's IR.warnings holds them): the
 *  automatic length stopped at its cap before the reverberation had
 *  decayed (TailInfo::cappedAtSeconds). */
std::vector<std::string> irWarnings(const OmniIrResult& result);

struct ThirdOctaveIrResult;
/** irWarnings of each pass, each text once. */
std::vector<std::string> thirdOctaveIrWarnings(const ThirdOctaveIrResult& result);

/** A third-octave IR's report (third_octave.h): irReportJson of the
 *  unshifted pass, plus "bands": "third-octave" and "third_octave":
 *  {bands_hz (nominal), centers_hz, decay: {edt_s, t20_s, t30_s} (21 each,
 *  null where the energies do not span the metric), passes: [each pass's
 *  irReportJson with its shift_octaves], combine_ms}; the top level's
 *  ir_samples, ir_seconds and silent are the combined IR's, its time_ms
 *  each stage's sum over the passes plus "combine". */
std::string thirdOctaveReportJson(const ThirdOctaveIrResult& result, const OmniIrSettings& settings,
                                  bool geometryTraced);

}  // namespace earshot
