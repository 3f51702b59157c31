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
  libtinygltf-dev libmeshoptimizer-dev                  # glTF export (render)
  glslang-tools                                         # shaders checked by the reference compiler (CI)
  nodejs                                                # the Khronos glTF validator (npm, below)
  f3d xvfb xauth                                        # the glTF viewer test (renders a GLB headless)
  slurm-wlm munge                                       # the render-farm test (a one-node Slurm)
  haproxy                                               # the replicas test (a real load balancer)
  python3-prometheus-client                             # the metrics test (text-format parser)
  fonts-dejavu-core                                     # caption strips of review images
  libfcl-dev                                            # distances between primitives (measure, clash)
  libzip-dev                                            # BCF files (zip archives of viewpoints)
  libxml2-utils                                         # xmllint: the BCF test checks files against the BCF 2.1 XSDs
  libxxhash-dev                                         # content hashes of objects (store revisions)
  libavcodec-dev libavutil-dev libswscale-dev           # video coding of streamed frames (H.264, VP8)
  python3-websockets                                    # an independent WebSocket client (stream tests)
  iproute2                                              # tc and network namespaces (bench_stream's slow link)
)

# npm tools, installed into an ignored folder of the repository (not system-wide).
NPM_DIR="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/.tools/npm"
NPM_PACKAGES=(gltf-validator@2.0.0-dev.3.10 @parametricos/bcf-js@0.2.6 ws@8.18.0)   # glTF validator; an independent BCF reader; a WebSocket client

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
if [ ${#missing[@]} -gt 0 ]; then
  echo "deps: installing ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq >/dev/null
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  echo "deps: done" >&2
fi

# Debian's nodejs leaves npm to a package of its own; NodeSource's bundles it (and conflicts with it).
if ! command -v npm >/dev/null 2>&1; then
  ${SUDO:-} apt-get install -y -qq --no-install-recommends npm >/dev/null 2>&1 || true
fi

# The npm tools: quick when present. A machine without the registry keeps going (the tests that
# need them skip with a message saying so).
if [ ! -f "$NPM_DIR/.installed" ] || [ "$(cat "$NPM_DIR/.installed")" != "${NPM_PACKAGES[*]}" ]; then
  echo "deps: installing ${NPM_PACKAGES[*]} into $NPM_DIR" >&2
  mkdir -p "$NPM_DIR"
  if npm install --silent --no-audit --no-fund --prefix "$NPM_DIR" "${NPM_PACKAGES[@]}" >/dev/null 2>&1; then
    echo "${NPM_PACKAGES[*]}" > "$NPM_DIR/.installed"
  else
    echo "deps: npm install failed; the glTF validator and BCF reader tests will skip" >&2
  fi
fi
