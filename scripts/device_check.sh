#!/usr/bin/env bash
# The checks that need a GPU, as one run on a machine lent through the tool `device` (CI never
# has one). Pack the kit here first (scripts/device_kit.sh), then:
#   run(command: "bash scripts/device_check.sh", carry: [".device-kit"], timeout_s: 540)
# It takes about 4-6 minutes there, which leaves a session's 15 minutes of device time room to
# start the machine and run it once more.
#
# What it checks and writes into $OUT (./device-check-out when OUT is unset), six files:
#   check.log          everything below as it ran
#   summary.json       the EGL devices (`plantview devices`), the one picked and whether it is
#                      hardware, each test binary's counts and failures (first line of each
#                      message; those that need the image module, which the kit leaves out,
#                      marked so), and every "json:" line of the benchmarks
#   bench_render.txt   bench_render's default run on preset c (100-view walk and 12 interior
#                      views, every policy with occlusion off and on; on a GPU the occlusion
#                      test is automatically the exact one), no image files and no PSNR
#   bench_coarse.txt   the same with --occlusion-test coarse (llvmpipe's automatic choice),
#                      over a 30-view walk, for the two tests side by side on one device
#   bench_ooc.txt      bench_render --out-of-core on preset c at --scale 100, 30 views, 256 MB
#   tests.json         the rendering tests' gtest reports, merged
# Exit status: 0 when plantview picked a hardware device and every test that does not need
# the image module passed; 1 otherwise (each reason in check.log and summary.json).
#
# Each step has a time limit, cut to what is left of DEVICE_CHECK_SECONDS (default 480) less
# 20 s for the summary; a step with under 30 s left is skipped, and says so.
# DEVICE_CHECK_QUICK=1 makes every run small (bench --quick, 3 out-of-core views): to try the
# script on a machine without a GPU, where it reports the software device and exits 1.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1

kit=$PWD/.device-kit
out=${OUT:-$PWD/device-check-out}
mkdir -p "$out"
work=$(mktemp -d /tmp/plantview-device-check.XXXXXX)
trap 'rm -rf "$work"' EXIT
quick=${DEVICE_CHECK_QUICK:-0}
deadline=$((SECONDS + ${DEVICE_CHECK_SECONDS:-480} - 20))
status=0
note() { echo "== $*"; }
# The kit's libraries for plantview's programs alone (the machine's own tools keep theirs).
pv() { LD_LIBRARY_PATH="$kit/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" "$@"; }
# The time limit of a step that may take up to $1 s: 0 (skip it) when under 30 s are left.
limit() {
  local left=$((deadline - SECONDS))
  if [ "$left" -lt 30 ]; then echo 0; elif [ "$left" -lt "$1" ]; then echo "$left"; else echo "$1"; fi
}
# run_limited CAP CMD...: CMD under the limit, or a note that it was skipped.
run_limited() {
  local cap
  cap=$(limit "$1")
  shift
  if [ "$cap" = 0 ]; then
    note "skipped, no time left: $*"
    return 124
  fi
  pv timeout "$cap" "$@"
}

main() {

if [ ! -x "$kit/bin/plantview" ]; then
  echo "device_check: no kit in $kit: run scripts/device_kit.sh here and carry .device-kit" >&2
  exit 1
fi
note "kit: $(sed -n 2,3p "$kit/MANIFEST" | paste -sd ' ')"

# OpenGL's dispatch libraries where the machine has none, and NVIDIA's EGL vendor file where
# its driver is mounted but not registered (the device tool's README).
if ! ldconfig -p | grep -q 'libEGL\.so\.1 '; then
  note "no libEGL.so.1 here: unpacking the kit's libglvnd packages"
  for f in "$kit"/deb/*.deb; do dpkg -x "$f" /; done
  ldconfig
fi
nvidia_vendor=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
if [ -f "$nvidia_vendor" ] && [ -z "${__EGL_VENDOR_LIBRARY_FILENAMES:-}" ]; then
  export __EGL_VENDOR_LIBRARY_FILENAMES=$nvidia_vendor
fi
command -v nvidia-smi >/dev/null && nvidia-smi -L
note "$(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GiB", $2 / 1048576}' /proc/meminfo)"

for b in "$kit"/bin/*; do
  if pv ldd "$b" | grep -q "not found"; then
    note "$(basename "$b"): libraries not found:"
    pv ldd "$b" | grep "not found"
    status=1
  fi
done

# 1. The devices EGL offers, and the one taken: bench_render's smoke run names it.
note "plantview devices"
run_limited 60 "$kit/bin/plantview" devices --json >"$work/devices.json" || status=1
cat "$work/devices.json"
note "device (bench_render --quick --no-images)"
run_limited 120 "$kit/bin/bench_render" --quick --no-images >"$work/quick.txt" 2>&1
cat "$work/quick.txt"
device=$(sed -n 's/^device: //p' "$work/quick.txt" | head -1)
if [ -z "$device" ]; then
  note "no device: bench_render could not make a context"
  status=1
elif [[ $device == *"(software)"* || $device == *llvmpipe* || $device == *"Mesa surfaceless"* ]]; then
  note "software device: the GPU was not picked"
  status=1
fi

# 2. Stores.
note "generating preset c, and preset c at --scale 100"
pv "$kit/bin/plantview" gen --preset c --store "$work/c" || status=1
scale=100
[ "$quick" = 1 ] && scale=2
pv "$kit/bin/plantview" gen --preset c --scale "$scale" --store "$work/x100" || status=1

# 3. The rendering tests, side by side (each in a directory of its own).
note "rendering tests"
pids=()
for t in "$kit"/bin/plantview_*_tests; do
  name=$(basename "$t")
  mkdir -p "$work/$name"
  (cd "$work/$name" && run_limited 240 "$t" --gtest_brief=1 --gtest_output="json:$work/$name.json" \
    >"$work/$name.log" 2>&1; echo "$name exit $?" >>"$work/$name.log") &
  pids+=($!)
done
wait "${pids[@]}"
for t in "$kit"/bin/plantview_*_tests; do
  name=$(basename "$t")
  note "$name"
  cat "$work/$name.log"
done

# 4. The benchmarks.
frames=()
ooc_frames=30
if [ "$quick" = 1 ]; then
  frames=(--quick)
  ooc_frames=3
fi
note "bench_render ${frames[*]} (default occlusion test)"
run_limited 200 "$kit/bin/bench_render" --store "$work/c" --no-images "${frames[@]}" \
  2>&1 | tee "$out/bench_render.txt"
note "bench_render --occlusion-test coarse"
coarse_frames=(--frames 30)
[ "$quick" = 1 ] && coarse_frames=(--quick)
run_limited 90 "$kit/bin/bench_render" --store "$work/c" --no-images --occlusion-test coarse \
  "${coarse_frames[@]}" 2>&1 | tee "$out/bench_coarse.txt"
note "bench_render --out-of-core"
run_limited 120 "$kit/bin/bench_render" --out-of-core --store "$work/x100" --frames "$ooc_frames" \
  --no-images 2>&1 | tee "$out/bench_ooc.txt"

# 5. The summary.
python3 - "$work" "$out" "$device" <<'EOF' || status=1
import glob, json, os, sys
work, out, device = sys.argv[1:4]
software = (not device) or "(software)" in device or "llvmpipe" in device or "surfaceless" in device
summary = {"device": device, "hardware": not software, "tests": {}, "bench": []}
try:
    summary["devices"] = json.load(open(os.path.join(work, "devices.json")))
except (OSError, ValueError) as e:
    summary["devices"] = "plantview devices gave no JSON: %s" % e
merged = {}
failed_elsewhere = 0
for path in sorted(glob.glob(os.path.join(work, "plantview_*_tests.json"))):
    name = os.path.basename(path)[:-5]
    try:
        report = json.load(open(path))
    except (OSError, ValueError) as e:
        summary["tests"][name] = {"error": "no report: %s" % e}
        failed_elsewhere += 1
        continue
    merged[name] = report
    failures = []
    for suite in report.get("testsuites", []):
        for case in suite.get("testsuite", []):
            if not case.get("failures"):
                continue
            first = case["failures"][0].get("failure", "").strip().splitlines()
            message = " ".join(first[:3])
            failures.append({"test": suite["name"] + "." + case["name"],
                             "needs_image_module": "image module" in case["failures"][0].get("failure", ""),
                             "message": message[:400]})
    summary["tests"][name] = {"tests": report.get("tests", 0), "failures": report.get("failures", 0),
                              "failed": failures}
    failed_elsewhere += sum(1 for f in failures if not f["needs_image_module"])
for log in glob.glob(os.path.join(work, "plantview_*_tests.log")):
    name = os.path.basename(log)[:-4]
    if name not in summary["tests"]:
        summary["tests"][name] = {"error": "no report (crashed or timed out): " + open(log).read()[-400:]}
        failed_elsewhere += 1
for f in ("bench_render.txt", "bench_coarse.txt", "bench_ooc.txt"):
    p = os.path.join(out, f)
    if os.path.exists(p):
        for line in open(p):
            if line.startswith("json: "):
                try:
                    summary["bench"].append(dict(json.loads(line[6:]), file=f))
                except ValueError:
                    pass
summary["test_failures_not_explained_by_the_image_module"] = failed_elsewhere
json.dump(merged, open(os.path.join(out, "tests.json"), "w"))
json.dump(summary, open(os.path.join(out, "summary.json"), "w"), indent=1)
print("== summary: device %r (%s); test failures other than the image module's: %d"
      % (device, "hardware" if not software else "software", failed_elsewhere))
sys.exit(1 if software or failed_elsewhere else 0)
EOF
  note "device_check: exit $status"
  return $status
}

main 2>&1 | tee "$out/check.log"
exit "${PIPESTATUS[0]}"
