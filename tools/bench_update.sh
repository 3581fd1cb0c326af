#!/usr/bin/env bash
# The IR-update figures of issue 16, measured side by side in one run on the
# machine at hand (docs/performance.md): per scene, the tracer beside the
# Embree limit of the same queries, the synthesis of a 2 s IR (binaural and
# omni), and `earshot ir`'s stage times for a binaural IR (a first run's,
# without the cache folder, and with it warm); then one shared
# trace for 32 sources beside a trace from each, the render benchmark
# (three runs), and the runtime with 32 moving sources in the furnished
# room, shared trace and per source (and, for information, shared with the
# simulation on every core), then issue 16's criteria as a table
# (tools/bench_update_summary.py). Usage (from the repository
# root, after the build): bash tools/bench_update.sh [build-dir]
set -euo pipefail
cd "$(dirname "$0")/.."
bin="${1:-build}/tools/earshot"
[ -x "$bin" ] || { echo "bench_update: no $bin (build first)" >&2; exit 2; }
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
run_all() {
echo "# $(date -u +%FT%TZ) $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
for scene in shoebox/shoebox.gltf furnished_room/furnished_room.glb; do
  dir="samples/$(dirname "$scene")"
  map="$dir/materials_map.json"
  echo "## $scene"
  "$bin" bench trace "samples/$scene" --material-map "$map" --runs 9
  "$bin" bench synth "samples/$scene" --material-map "$map" --runs 9
  # One-shot processes, without the cache folder (what a first run pays:
  # the HRTF set's preparation, the late noises) and with it warm.
  for cache in off warm; do
    if [ "$cache" = off ]; then dir_cache=off; else dir_cache="$tmp/cache"; fi
    if [ "$cache" = warm ]; then
      EARSHOT_CACHE_DIR="$dir_cache" "$bin" ir "samples/$scene" --material-map "$map" --source 2,3.5,1.5 \
        --listener 5,3,1.6 --receiver binaural -o "$tmp/warm.wav" >/dev/null 2>&1
    fi
    for i in 1 2 3; do
      TIMEFORMAT=%R
      { time EARSHOT_CACHE_DIR="$dir_cache" "$bin" ir "samples/$scene" --material-map "$map" --source 2,3.5,1.5 \
          --listener 5,3,1.6 --receiver binaural -o "$tmp/ir$i.wav" --json "$tmp/ir$i.json" >/dev/null 2>&1; } \
        2> "$tmp/wall$i"
    done
    /usr/bin/python3 - "$tmp" "$cache" <<'PY'
import json, statistics, sys
runs = [json.load(open(f"{sys.argv[1]}/ir{i}.json"))["time_ms"] for i in (1, 2, 3)]
walls = [float(open(f"{sys.argv[1]}/wall{i}").read()) for i in (1, 2, 3)]
keys = ["trace", "early_reflections", "tail", "synthesis", "pipeline"]
print(f"earshot ir (binaural, one-shot process, cache {sys.argv[2]}, median of 3): " +
      " ".join(f"{k}_ms={statistics.median(r[k] for r in runs):.1f}" for k in keys) +
      f" process_s={statistics.median(walls):.2f}")
PY
  done
done
echo "## one trace for 32 sources (furnished room)"
"$bin" bench trace samples/furnished_room/furnished_room.glb \
  --material-map samples/furnished_room/materials_map.json --listener 5,3.5,1.2 --shared-sources 32 --runs 5
echo "## render benchmark (tools/make_render_bench.py: 60 s, two sources circling, furnished room)"
/usr/bin/python3 tools/make_render_bench.py "$tmp/render" >/dev/null
for i in 1 2 3; do
  TIMEFORMAT=%R
  { time "$bin" render "$tmp/render/scene.json" -o "$tmp/render/out$i.wav" >/dev/null 2>&1; } 2> "$tmp/render/wall$i"
done
/usr/bin/python3 - "$tmp/render" <<'PY'
import statistics, sys
walls = [float(open(f"{sys.argv[1]}/wall{i}").read()) for i in (1, 2, 3)]
print("render wall_s=" + ",".join(f"{w:.2f}" for w in walls) + f" median_s={statistics.median(walls):.2f}")
PY
for trace in shared per-source; do
  echo "## runtime, trace $trace"
  "$bin" bench runtime samples/furnished_room/furnished_room.glb \
    --material-map samples/furnished_room/materials_map.json --sources 32 --seconds 10 --ir-seconds 2 --trace "$trace"
done
# For information (the criterion is the engine's default, the cores less
# one): the shared trace with the simulation on every core, at nice +5
# below the real-time audio thread.
echo "## runtime, trace shared, simulation on all $(nproc) cores"
"$bin" bench runtime samples/furnished_room/furnished_room.glb \
  --material-map samples/furnished_room/materials_map.json --sources 32 --seconds 10 --ir-seconds 2 --trace shared \
  --threads "$(nproc)"
}
# Everything above, then issue 16's criteria from it (tools/bench_update_summary.py).
run_all | tee "$tmp/update.log"
echo "## issue 16's criteria, from this run"
/usr/bin/python3 tools/bench_update_summary.py "$tmp/update.log"
