#!/usr/bin/env bash
# Packs, into .device-kit/ (ignored by git), what scripts/device_check.sh needs on a GPU machine
# lent to a session through the tool `device`: a bare machine of another distribution that
# cannot fetch packages. Run it here, after a build (scripts/test.sh or scripts/demo.sh), then
# hand the folder over with the check:
#   run(command: "bash scripts/device_check.sh", carry: [".device-kit"], timeout_s: 540)
#
# The kit holds:
#   bin/  plantview, bench_render and the rendering tests (render, occlusion, frame history,
#         out of core), stripped;
#   lib/  the shared libraries they load that a machine without plantview's packages lacks
#         (libepoxy, LMDB, zstd, libuv...); not the C and C++ runtimes, which the machine has
#         newer, nor OpenGL's, which its driver brings;
#   deb/  the GL dispatch libraries (libglvnd: libEGL, libGL, libOpenGL...) as Debian packages,
#         which the check unpacks there when the machine has none (the tool's README).
# Left out: the image module (OpenImageIO and the ~260 libraries it loads, over 360 MB against
# the 64 MiB a call carries), so nothing there writes or compares image files: the check runs
# bench_render --no-images, and the tests that read or write images fail there, by name.
#
# Usage: scripts/device_kit.sh [BUILD_DIR]   (default build/)
# Exit status: non-zero if a target cannot be built, a library is not found, or the kit is
# over 48 MiB (the call's limit, with the repository beside it, is 64 MiB).
set -euo pipefail
cd "$(dirname "$0")/.."

build=${1:-build}
kit=.device-kit
targets=(plantview bench_render plantview_render_tests plantview_occlusion_tests
  plantview_frame_history_tests plantview_out_of_core_tests)
[ -f "$build/CMakeCache.txt" ] || {
  echo "device_kit: no build in $build/: run scripts/test.sh or scripts/demo.sh first" >&2
  exit 1
}
cmake --build "$build" -j "$(nproc 2>/dev/null || echo 2)" --target "${targets[@]}"

rm -rf "$kit"
mkdir -p "$kit/bin" "$kit/lib" "$kit/deb"
binaries=("$build/service/plantview" "$build/bench/bench_render")
for t in "${targets[@]:2}"; do binaries+=("$build/tests/$t"); done
for b in "${binaries[@]}"; do
  strip -o "$kit/bin/$(basename "$b")" "$b"
done

# The libraries the loader resolves for each binary, less those every Linux with a GPU driver
# has (the C runtime, the C++ runtime, the GL dispatch libraries).
system='^(linux-vdso|ld-linux|libc|libm|libdl|libpthread|librt|libgcc_s|libstdc\+\+|libEGL|libGL|libGLX|libGLdispatch|libOpenGL|libGLESv2)\.'
for b in "${binaries[@]}"; do
  if ldd "$b" | grep -q "not found"; then
    echo "device_kit: $b: a library is not found here:" >&2
    ldd "$b" | grep "not found" >&2
    exit 1
  fi
  ldd "$b" | awk '$2 == "=>" && $3 ~ /^\// {print $1, $3}'
done | sort -u | while read -r name path; do
  [[ $name =~ $system ]] && continue
  cp -L "$path" "$kit/lib/$name"
done

# libglvnd's packages for this machine's architecture, as the device tool's README fetches them.
(cd "$kit/deb" && apt-get -o APT::Sandbox::User=root download -q libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2 >/dev/null)

cat >"$kit/MANIFEST" <<EOF
plantview device kit
made $(date -u +%Y-%m-%dT%H:%M:%SZ) from $(git rev-parse --short HEAD)$(git diff --quiet HEAD -- . ':!.device-kit' || echo ' (with uncommitted changes)')
built on $(sed -n 's/^PRETTY_NAME=//p' /etc/os-release | tr -d '"'), $(uname -m)
EOF
(cd "$kit" && find bin lib deb -type f | sort) >>"$kit/MANIFEST"

bytes=$(du -sb "$kit" | cut -f1)
echo "device_kit: $kit/ holds $(find "$kit" -type f | wc -l) files, $((bytes / 1048576)) MiB"
if [ "$bytes" -gt $((48 << 20)) ]; then
  echo "device_kit: over 48 MiB: the call carries at most 64 MiB with the repository" >&2
  exit 1
fi
