#!/usr/bin/env bash
# Issue #15: a failed write of any output is a failed run. Every program that
# writes a file is pointed at /dev/full (directly, or through a symlink where
# it chooses the file name inside a folder) and must exit 1 with one line on
# stderr naming the file and the reason; standard output too.
#   full_disk_test.sh BUILD_DIR SOURCE_DIR
set -uo pipefail
build=$1 source=$2
bin=$build/bin
site=$source/config/sites/demo_room.yaml
gt_log=$source/tests/data/ground_truth_sample.lcm
ranges_log=$source/tests/data/trilat_replay.lcm
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
full="No space left on device"

# expect NAME EXPECTED_STDERR COMMAND...: exit 1 and exactly that one line,
# besides the line where a tool says which site it used (issue #20: "site
# from ..." or "note: site unknown: ..."), which comes before any work.
expect() {
  local name=$1 expected=$2
  shift 2
  local err rc
  err=$(timeout 60 "$@" 2>&1 >/dev/null)
  rc=$?
  err=$(grep -Ev '^[a-z_ ]+: (site from |note: site unknown: )' <<<"$err")
  if ((rc != 1)); then
    echo "FAIL: $name: exit $rc, expected 1; stderr: $err"; failures=$((failures + 1))
  elif [[ "$err" != "$expected" ]]; then
    echo "FAIL: $name: stderr '$err', expected '$expected'"; failures=$((failures + 1))
  else
    echo "ok: $name: $err"
  fi
}

expect "viewer --png" "roomfix_viewer: /dev/full: cannot write: $full" \
  "$bin/roomfix_viewer" --log "$gt_log" --config "$site" --headless --png /dev/full
expect "survey --out" "roomfix survey: /dev/full: cannot write: $full" \
  "$bin/roomfix" survey "$ranges_log" --site "$site" --no-reference --pin 1,2 --out /dev/full
expect "survey --json" "roomfix survey: /dev/full: cannot write: $full" \
  "$bin/roomfix" survey "$ranges_log" --site "$site" --no-reference --pin 1,2 --json /dev/full
expect "compare --json" "roomfix compare: /dev/full: cannot write: $full" \
  "$bin/roomfix" compare "$gt_log" --json /dev/full
expect "render-camera --png" "roomfix render-camera: /dev/full: cannot write: $full" \
  "$bin/roomfix" render-camera --site "$site" --png /dev/full
mkdir "$tmp/frames" && ln -s /dev/full "$tmp/frames/truth.csv"
expect "render-camera --out (truth.csv)" \
  "roomfix render-camera: $tmp/frames: cannot write $tmp/frames/truth.csv: $full" \
  "$bin/roomfix" render-camera --site "$site" --out "$tmp/frames" --duration 0.1
mkdir "$tmp/analysis" && ln -s /dev/full "$tmp/analysis/report.md"
expect "analyze report.md" "roomfix analyze: $tmp/analysis/report.md: cannot write: $full" \
  "$bin/roomfix" analyze "$gt_log" --out "$tmp/analysis" --no-figures
expect "bench viewer --png" "roomfix bench viewer: /dev/full: cannot write: $full" \
  "$bin/roomfix" bench viewer --frames 3 --png /dev/full

# Standard output: every command's JSON or table (bench --json, frames, map).
err=$("$bin/roomfix" version 2>&1 >/dev/full)
rc=$?
if ((rc != 1)) || [[ "$err" != "roomfix: standard output: cannot write: $full" ]]; then
  echo "FAIL: version >/dev/full: exit $rc, stderr '$err'"; failures=$((failures + 1))
else
  echo "ok: version >/dev/full: $err"
fi
err=$("$bin/roomfix" bench trilat --trials 10 --node-sets 10 --json 2>&1 >/dev/full)
rc=$?
if ((rc != 1)) || [[ "$err" != "roomfix: standard output: cannot write"* ]]; then
  echo "FAIL: bench trilat --json >/dev/full: exit $rc, stderr '$err'"; failures=$((failures + 1))
else
  echo "ok: bench trilat --json >/dev/full: $err"
fi
exit $((failures > 0))
