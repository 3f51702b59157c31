#!/usr/bin/env bash
# Installs what is missing, builds plantview (Release), generates the preset c plant into a store
# under var/ (once), renders one review image of it, and serves it on http://127.0.0.1:8080/
# for a browser until Ctrl-C.
# Idempotent: re-running rebuilds only what changed and reuses the store.
# The first run compiles the whole program (minutes): on a terminal the build shows its progress
# ([done/total] steps); in a pipe or a log it prints a line at every tenth of the build naming
# the step that runs, keeps the build's output in build-release/build.log and prints its end
# when it fails.
# Environment: PLANTVIEW_LISTEN (default 127.0.0.1:8080); PLANTVIEW_DEMO_NO_SERVE=1 stops after
# the review image (for scripted runs).
set -euo pipefail
cd "$(dirname "$0")/.."

scripts/deps.sh
jobs=$(nproc 2>/dev/null || echo 2)
echo "demo: building plantview (Release, $jobs jobs) in build-release/; the first build compiles" \
  "everything and takes minutes" >&2
SECONDS=0
cmake -S . -B build-release -G Ninja -DCMAKE_BUILD_TYPE=Release -DPLANTVIEW_BUILD_TESTS=OFF \
  -DPLANTVIEW_BUILD_BENCH=OFF >/dev/null
if [ -t 1 ]; then
  cmake --build build-release -j "$jobs" --target plantview  # ninja: one status line, [done/total]
else
  # In a log (nohup, CI, a service manager): a line at the start and at every tenth of the
  # build, saying which step runs; the whole output goes to build-release/build.log.
  build_progress() {
    local shown=-1 line done_steps total tenth
    while IFS= read -r line; do
      printf '%s\n' "$line" >>build-release/build.log
      [[ $line =~ ^\[([0-9]+)/([0-9]+)\]\ (.*)$ ]] || continue
      done_steps=${BASH_REMATCH[1]} total=${BASH_REMATCH[2]}
      tenth=$((10 * done_steps / total))
      if ((tenth > shown)); then
        shown=$tenth
        echo "demo: build $((10 * tenth))% ($done_steps/$total steps, ${SECONDS} s): ${BASH_REMATCH[3]}" >&2
      fi
    done
  }
  : >build-release/build.log
  cmake --build build-release -j "$jobs" --target plantview 2>&1 | build_progress || {
    tail -n 40 build-release/build.log >&2
    echo "demo: the build failed; its log: build-release/build.log" >&2
    exit 1
  }
fi
plantview=./build-release/service/plantview
echo "demo: $plantview is built (${SECONDS} s)" >&2
$plantview --version

mkdir -p var
if ! $plantview info --store var/preset-c >/dev/null 2>&1; then
  echo "demo: generating the preset c plant into var/preset-c (once)" >&2
  rm -rf var/preset-c
  $plantview gen --preset c --store var/preset-c
fi
$plantview info --store var/preset-c
$plantview render --store var/preset-c --size 1280x720 --out var/review.png >var/review-stats.json
echo "review image: var/review.png (statistics in var/review-stats.json)"

if [ "${PLANTVIEW_DEMO_NO_SERVE:-0}" = 1 ]; then exit 0; fi
listen=${PLANTVIEW_LISTEN:-127.0.0.1:8080}
echo "open http://$listen/ in a browser (drag to orbit, right-drag to pan, wheel to zoom, WASD to walk, click to pick); Ctrl-C stops"
exec $plantview serve --store var/preset-c --listen "$listen"
