#!/usr/bin/env bash
# Installs what is missing, builds plantview (Release) and runs its main job on an embedded
# default. Until the renderer lands, the main job is the tessellation of every primitive kind:
# for a 0.2 m pipe part, the triangles and geometric error of each level of detail.
# Idempotent: re-running rebuilds only what changed.
set -euo pipefail
cd "$(dirname "$0")/.."

scripts/deps.sh
cmake -S . -B build-release -G Ninja -DCMAKE_BUILD_TYPE=Release -DPLANTVIEW_BUILD_TESTS=OFF \
  -DPLANTVIEW_BUILD_BENCH=OFF >/dev/null
cmake --build build-release -j "$(nproc 2>/dev/null || echo 2)" --target plantview >/dev/null

./build-release/service/plantview --version
./build-release/service/plantview primitives --diameter 0.2
