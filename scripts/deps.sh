#!/usr/bin/env bash
# Installs the Debian packages plantview needs to build, test and run.
# Idempotent: quiet and quick when everything is present. Runs as root or via sudo.
set -euo pipefail

# The one list of build and run dependencies.
PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  clang libclang-rt-dev            # sanitizer passes of scripts/test.sh, scripts/fuzz.sh
  libglm-dev                       # vector maths (core)
  liblmdb-dev libzstd-dev          # the store (storage)
  libegl-dev libegl-mesa0 libgl1-mesa-dri libepoxy-dev   # headless GL (render)
  libopenimageio-dev               # image encoding and comparison (render)
  libuv1-dev libhttp-parser-dev    # the service
  libpugixml-dev nlohmann-json3-dev libcli11-dev        # XML, JSON, command line
  libgtest-dev libgmock-dev libbenchmark-dev            # tests and benchmarks
  chromium chromium-driver python3                      # the browser test (tests/browser)
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "deps: installing ${missing[*]}" >&2
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq >/dev/null
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "deps: done" >&2
