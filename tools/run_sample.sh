#!/usr/bin/env bash
# The main job of the README's set-up command: compute the impulse response of
# the sample furnished room (24k triangles) into out/, and print its ISO 3382-1
# parameters. Usage: bash tools/run_sample.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR="${1:-build}"
EARSHOT="$BUILD_DIR/tools/earshot"
mkdir -p out
"$EARSHOT" ir samples/furnished_room/furnished_room.glb \
  --material-map samples/furnished_room/materials_map.json \
  --source 2,3.5,1.5 --listener 7,3.5,1.5 --receiver omni \
  -o out/furnished_room_ir.wav --json out/furnished_room_ir.json
echo "wrote out/furnished_room_ir.wav (statistics: out/furnished_room_ir.json)"
if "$EARSHOT" --help | grep -qw analyze; then
  "$EARSHOT" analyze out/furnished_room_ir.wav
fi
