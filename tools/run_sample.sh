#!/usr/bin/env bash
# The main job of the README's set-up command: render the sample scene
# samples/two_rooms/walk_through_door.json (a talker walks from one room into
# the next; the listener stays behind) to a binaural WAV in out/.
# Usage: bash tools/run_sample.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR="${1:-build}"
EARSHOT="$BUILD_DIR/tools/earshot"
mkdir -p out
"$EARSHOT" render samples/two_rooms/walk_through_door.json -o out/walk_through_door.wav
echo "wrote out/walk_through_door.wav (binaural, 48 kHz float; listen on headphones)"
