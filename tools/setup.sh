#!/usr/bin/env bash
# Set up earshot on a fresh Debian 12 machine: install the Debian packages it
# needs (as root, or through sudo), configure and build in Release, then run
# the main job: compute the sample scene's impulse response and render it to
# a WAV in out/.
#
#   bash tools/setup.sh            # everything
#   EARSHOT_SKIP_APT=1 bash tools/setup.sh   # build and run only
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libembree-dev libtbb-dev libeigen3-dev libkissfft-dev libsndfile1-dev
  libtinygltf-dev libmysofa-dev nlohmann-json3-dev libcli11-dev libqhull-dev libsoxr-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  python3 python3-dev python3-numpy python3-matplotlib pybind11-dev
  python3-pytest python3-h5py python3-distributed
  clang libclang-rt-14-dev
)

if [ -z "${EARSHOT_SKIP_APT:-}" ]; then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  missing=()
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing ${missing[*]}"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
  fi
fi

BUILD_DIR="${EARSHOT_BUILD_DIR:-build}"
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$BUILD_DIR" -j "$(nproc)"

# The Python package (build/python): Debian's python3 finds it through a .pth
# file in its site-packages (root or sudo; otherwise say the one export).
PY=/usr/bin/python3
if [ -x "$PY" ] && [ -d "$BUILD_DIR/python/earshot" ]; then
  PYDIR="$(cd "$BUILD_DIR/python" && pwd)"
  SITE="$("$PY" -c 'import site; print(site.getsitepackages()[0])')"
  SUDO=""
  if [ "$(id -u)" -ne 0 ] && command -v sudo >/dev/null; then SUDO="sudo"; fi
  if { $SUDO mkdir -p "$SITE" && echo "$PYDIR" | $SUDO tee "$SITE/earshot.pth" >/dev/null; } 2>/dev/null; then
    "$PY" -c "import earshot" && echo "setup: import earshot works (python3 finds $PYDIR through $SITE/earshot.pth)"
  else
    echo "setup: could not write $SITE/earshot.pth; use: export PYTHONPATH=$PYDIR"
  fi
fi

# The main job.
mkdir -p out
bash tools/run_sample.sh "$BUILD_DIR"
