#!/usr/bin/env bash
# Fuzzes plantview's parsers and decoders with libFuzzer (the harnesses: tests/fuzz/): builds the
# fuzzers with clang, AddressSanitizer and UBSan in build-fuzz/, then runs each for SECONDS
# (default 60), one process each, one after the other.
#
#   scripts/fuzz.sh [SECONDS] [NAME...]     NAME: a harness (fuzz_NAME), default every one built
#
# Each fuzzer runs with its dictionary (tests/fuzz/NAME.dict, where there is one) over a working
# corpus var/fuzz/corpus/NAME/ (outside git; it grows from run to run), reading the checked-in
# seeds tests/fuzz/corpus/NAME/ too. What it finds that breaks the harness (crash-*, leak-*,
# timeout-*, oom-*) lands in var/fuzz/crashes/NAME/; once the bug is fixed, copy the input into
# tests/fuzz/corpus/NAME/ under a name that says what it was (crash-<what>), and CTest replays it
# from then on. To shrink the checked-in corpus after adding seeds:
#   build-fuzz/tests/fuzz/fuzz_NAME -merge=1 <empty dir> tests/fuzz/corpus/NAME
# Prints per fuzzer: executions, executions a second, coverage (cov: edges, ft: features) and
# the working corpus' size. Idempotent: a second run rebuilds only what changed.
# Exit status: non-zero if a fuzzer broke its harness (or the build failed).
set -euo pipefail
cd "$(dirname "$0")/.."

seconds=60
if [[ $# -gt 0 && $1 =~ ^[0-9]+$ ]]; then
  seconds=$1
  shift
fi

jobs=$(nproc 2>/dev/null || echo 2)
echo "== build-fuzz (clang, libFuzzer, ASan + UBSan)" >&2
CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=Debug \
  -DCMAKE_CXX_FLAGS=-O1 -DPLANTVIEW_SANITIZE=address -DPLANTVIEW_FUZZ=ON -DPLANTVIEW_WERROR=ON \
  -DPLANTVIEW_BUILD_BENCH=OFF >/dev/null
cmake --build build-fuzz -j "$jobs" --target plantview_tests_fuzz

names=("$@")
if [ ${#names[@]} -eq 0 ]; then
  for program in build-fuzz/tests/fuzz/fuzz_*; do
    [ -x "$program" ] && names+=("${program##*/fuzz_}")
  done
fi

# A leak is a finding like a crash; a 10 s input is a hang (the parsers are linear).
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1
status=0
summary=()
for name in "${names[@]}"; do
  program=build-fuzz/tests/fuzz/fuzz_$name
  if [ ! -x "$program" ]; then
    echo "fuzz.sh: no fuzzer named $name ($program)" >&2
    exit 2
  fi
  corpus=var/fuzz/corpus/$name
  crashes=var/fuzz/crashes/$name
  log=var/fuzz/$name.log
  mkdir -p "$corpus" "$crashes"
  args=(-max_total_time="$seconds" -timeout=10 -print_final_stats=1 -artifact_prefix="$crashes/")
  [ -f "tests/fuzz/$name.dict" ] && args+=(-dict="tests/fuzz/$name.dict")
  echo "== fuzz_$name for ${seconds} s (log: $log)" >&2
  rc=0
  "$program" "${args[@]}" "$corpus" "tests/fuzz/corpus/$name" >"$log" 2>&1 || rc=$?
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  coverage=$(grep -o 'cov: [0-9]* ft: [0-9]*' "$log" | tail -1)
  files=$(find "$corpus" -type f | wc -l)
  if [ "$rc" -ne 0 ]; then
    status=1
    found=$(ls -t "$crashes" | head -1)
    result="BROKE THE HARNESS (exit $rc): $crashes/$found; see $log"
  else
    result=ok
  fi
  summary+=("$(printf '%-14s %10s runs %7s/s  %-20s corpus %5s files  %s' \
    "$name" "${runs:-?}" "${rate:-?}" "${coverage:-cov: ?}" "$files" "$result")")
done

echo "== fuzz results (${seconds} s each)"
printf '%s\n' "${summary[@]}"
exit $status
