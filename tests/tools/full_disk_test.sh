#!/usr/bin/env bash
# Issue #15: a failed write of any output is a failed run. Every program that
# writes a file is pointed at /dev/full (directly, or through a symlink where
# it chooses the file name inside a folder) and must exit 1 with one line on
# stderr naming the file and the reason; standard output too.
#
# Issue #28: /dev/full fails the first write, but a disk that fills up part
# way lets a writer write some of its file first; cv::VideoWriter then
# reported nothing and a truncated video was left with exit 0. The second
# half runs each writer of a whole file on a real small filesystem (a tmpfs in
# a private mount namespace, `unshare -rm`) that fills up while it writes: it
# must exit 1 naming the file, and leave neither a file that stops short nor
# its hidden partial file (WriteOutputFile, camera::CheckedVideoWriter).
#   full_disk_test.sh BUILD_DIR SOURCE_DIR [--small-disk]
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

# expect_whole NAME FILE... -- COMMAND...: on the small disk, exit 1 with a
# line naming the first FILE, and none of the FILEs nor a partial file left.
expect_whole() {
  local name=$1
  shift
  local files=()
  while [[ $1 != -- ]]; do files+=("$1"); shift; done
  shift
  local err rc left
  err=$(timeout 120 "$@" 2>&1 >/dev/null)
  rc=$?
  left=$(find "$small" -mindepth 1 ! -name filler | sort)
  if ((rc != 1)); then
    echo "FAIL: $name: exit $rc, expected 1; stderr: $err"; failures=$((failures + 1))
  elif ! grep -q -- "${files[0]}: cannot write" <<<"$err"; then
    echo "FAIL: $name: stderr '$err' does not name ${files[0]}"; failures=$((failures + 1))
  elif [[ -n "$left" ]]; then
    echo "FAIL: $name: left on the full disk: $left"; failures=$((failures + 1))
  else
    echo "ok: $name: $(grep -- "${files[0]}" <<<"$err" | head -1)"
  fi
  find "$small" -mindepth 1 ! -name filler -delete
}

if [[ ${3:-} == --small-disk ]]; then
  # 4 MiB, of which all but 48 KiB is taken: every output below is larger.
  small=$tmp/small
  mkdir "$small" && mount -t tmpfs -o size=4m roomfix_full "$small" || exit 1
  head -c $((4096 * 1024 - 48 * 1024)) /dev/zero >"$small/filler"
  expect_whole "render-camera --out FILE.avi" "$small/cam.avi" -- \
    "$bin/roomfix" render-camera --site "$site" --out "$small/cam.avi" --duration 2
  expect_whole "viewer --video FILE.avi" "$small/view.avi" -- \
    "$bin/roomfix_viewer" --log "$gt_log" --config "$site" --headless --video "$small/view.avi"
  expect_whole "render-camera --png" "$small/frame.png" -- \
    "$bin/roomfix" render-camera --site "$site" --png "$small/frame.png"
  expect_whole "replay --out" "$small/new.lcm" -- \
    "$bin/roomfix" replay "$source/tests/data/pipeline_replay.lcm" --out "$small/new.lcm"
  "$bin/roomfix" render-camera --site "$site" --tripod-grid "$tmp/trip" >/dev/null 2>&1 || exit 1
  expect_whole "calibrate (picture, then calibration)" "$small/cam0.png" "$small/cam0.yaml" -- \
    "$bin/roomfix" calibrate --site "$site" --marker-images "$tmp/trip/points.csv" \
    --out "$small/cam0.yaml" --png "$small/cam0.png"
  exit $((failures > 0))
fi

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
mkdir "$tmp/grab" && ln -s /dev/full "$tmp/grab/frame_0000.jpg"
expect "grab (a frame)" "roomfix grab: $tmp/grab/frame_0000.jpg: cannot write: $full" \
  "$bin/roomfix" grab --site "$site" --out "$tmp/grab"
mkdir "$tmp/grab_csv" && ln -s /dev/full "$tmp/grab_csv/frames.csv"
expect "grab (frames.csv)" "roomfix grab: $tmp/grab_csv/frames.csv: cannot write: $full" \
  "$bin/roomfix" grab --site "$site" --out "$tmp/grab_csv"
mkdir "$tmp/analysis" && ln -s /dev/full "$tmp/analysis/report.md"
expect "analyze report.md" "roomfix analyze: $tmp/analysis/report.md: cannot write: $full" \
  "$bin/roomfix" analyze "$gt_log" --out "$tmp/analysis" --no-figures
expect "roomfix_bench viewer --png" "roomfix_bench viewer: /dev/full: cannot write: $full" \
  "$bin/roomfix_bench" viewer --frames 3 --png /dev/full

# Standard output: every command's JSON or table (roomfix_bench --json, frames, map).
err=$("$bin/roomfix" version 2>&1 >/dev/full)
rc=$?
if ((rc != 1)) || [[ "$err" != "roomfix: standard output: cannot write: $full" ]]; then
  echo "FAIL: version >/dev/full: exit $rc, stderr '$err'"; failures=$((failures + 1))
else
  echo "ok: version >/dev/full: $err"
fi
err=$("$bin/roomfix_bench" trilat --trials 10 --node-sets 10 --json 2>&1 >/dev/full)
rc=$?
if ((rc != 1)) || [[ "$err" != "roomfix_bench: standard output: cannot write"* ]]; then
  echo "FAIL: roomfix_bench trilat --json >/dev/full: exit $rc, stderr '$err'"; failures=$((failures + 1))
else
  echo "ok: roomfix_bench trilat --json >/dev/full: $err"
fi

if unshare -rm true 2>/dev/null; then
  unshare -rm "$0" "$build" "$source" --small-disk || failures=$((failures + 1))
else
  echo "SKIP: the small-disk cases need a private mount namespace (unshare -rm failed)"
fi
exit $((failures > 0))
