#!/usr/bin/env bash
# Builds a libFuzzer target with clang (ASan + UBSan, coverage on all project
# code) into build-fuzz/ and runs it for a while on a copy of its corpus.
#
#   scripts/fuzz.sh <target> [seconds]      e.g. scripts/fuzz.sh xbee_frame 60
#
# Targets are listed in tests/fuzz/CMakeLists.txt; the corpus is
# tests/data/fuzz/<target>/. New inputs libFuzzer finds stay in the working
# copy (build-fuzz/corpus/<target>/); a crashing input is written into
# tests/data/fuzz/<target>/ (crash-<sha1>), where fuzz_regression_test runs
# it in every build from then on. Exit status: 0 when the run found nothing.
#
# Environment: CC / CXX (default clang-14 / clang++-14), FUZZ_JOBS (build
# parallelism, default 2), FUZZ_ARGS (extra libFuzzer flags).
set -euo pipefail

if [[ $# -lt 1 || $# -gt 2 || "$1" == -h || "$1" == --help ]]; then
  sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
target=$1
seconds=${2:-60}
[[ "$seconds" =~ ^[0-9]+$ ]] || { echo "fuzz.sh: seconds must be a whole number" >&2; exit 2; }

root=$(cd "$(dirname "$0")/.." && pwd)
build="$root/build-fuzz"
corpus="$root/tests/data/fuzz/$target"
work="$build/corpus/$target"
[[ -d "$corpus" ]] || { echo "fuzz.sh: no corpus folder $corpus" >&2; exit 2; }

cc=${CC:-clang-14}
cxx=${CXX:-clang++-14}
# Coverage feedback for every library the target links; ROOMFIX_SANITIZE adds
# ASan + UBSan (aborting on UB) to the whole build.
if [[ -f "$build/CMakeCache.txt" ]]; then
  # Picks up targets added since the first configure.
  cmake "$build" > "$build.configure.log" 2>&1 || { cat "$build.configure.log"; exit 1; }
else
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER="$cc" -DCMAKE_CXX_COMPILER="$cxx" \
    -DCMAKE_C_FLAGS="-fsanitize=fuzzer-no-link" -DCMAKE_CXX_FLAGS="-fsanitize=fuzzer-no-link" \
    -DROOMFIX_SANITIZE=ON -DROOMFIX_FUZZ=ON > "$build.configure.log" 2>&1 \
    || { cat "$build.configure.log"; rm -f "$build/CMakeCache.txt"; exit 1; }
fi
cmake --build "$build" -j "${FUZZ_JOBS:-2}" --target "${target}_fuzzer" -- --no-print-directory

mkdir -p "$work"
cp -n "$corpus"/* "$work"/ 2>/dev/null || true

echo "fuzz.sh: running ${target}_fuzzer for ${seconds} s on $work"
status=0
# shellcheck disable=SC2086
"$build/bin/${target}_fuzzer" "$work" \
  -max_total_time="$seconds" -timeout=10 -print_final_stats=1 \
  -artifact_prefix="$corpus/" ${FUZZ_ARGS:-} || status=$?
if [[ $status -ne 0 ]]; then
  echo "fuzz.sh: ${target}_fuzzer failed (status $status); crash input(s) in $corpus/:" >&2
  for file in "$corpus"/crash-* "$corpus"/leak-* "$corpus"/timeout-* "$corpus"/oom-*; do
    [[ -e "$file" ]] && echo "  $file" >&2
  done
fi
exit $status
