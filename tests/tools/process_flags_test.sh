#!/usr/bin/env bash
# Every process has --help, validates its flags and site file with --check,
# and cannot-start cases end with one clear line and a non-zero exit.
#   process_flags_test.sh BUILD_DIR SOURCE_DIR
set -uo pipefail
build=$1 source=$2
site=$source/config/sites/demo_room.yaml
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
# Output is captured whole before it is searched: under pipefail,
# `prog --help | grep -q X` fails at random, because grep exits at the first
# match and prog, still writing, dies of SIGPIPE (status 141).
has() {  # text pattern: whether a line of text matches the extended regex
  grep -qE -- "$2" <<<"$1"
}

for bin in roomfix_sim trilat_proc fusion_proc zigbee_bridge roomfix_viewer camera_proc; do
  extra=()
  # --check validates the port's name, not the device: none is needed here.
  [[ $bin == zigbee_bridge ]] && extra=(--port /dev/ttyUSB0)
  [[ $bin == roomfix_viewer ]] && extra=(--headless --png /tmp/never_written.png)
  help=$("$build/bin/$bin" --help)
  has "$help" '--lcm-url' || fail "$bin --help lacks --lcm-url"
  has "$help" '--config' || fail "$bin --help lacks --config"
  has "$help" '--log-color' || fail "$bin --help lacks --log-color"
  out=$("$build/bin/$bin" "${extra[@]}" --config "$site" --check 2>/dev/null) || fail "$bin --check failed"
  [[ "$out" == *"ok"* ]] || fail "$bin --check printed '$out'"
  err=$("$build/bin/$bin" "${extra[@]}" --config "$source/tests/data/broken_sites/duplicate_address.yaml" 2>&1 >/dev/null)
  rc=$?
  ((rc != 0)) || fail "$bin started on a broken site file"
  [[ $(grep -c . <<<"$err") -eq 1 && "$err" == *"duplicate address"* ]] || fail "$bin: '$err'"
  err=$("$build/bin/$bin" "${extra[@]}" --config "$site" --lcm-url "nonsense://" 2>&1 >/dev/null)
  rc=$?
  ((rc != 0)) || fail "$bin started on a bad LCM URL"
  [[ $(grep -c "$bin:" <<<"$err") -eq 1 && "$err" == *"cannot start LCM"* ]] || fail "$bin: '$err'"
done

err=$("$build/bin/zigbee_bridge" --port /dev/ttyUSB0 --baud 12345 --config "$site" 2>&1 >/dev/null)
(($? != 0)) && [[ $(grep -c . <<<"$err") -eq 1 && "$err" == *"baud"* ]] ||
  fail "zigbee_bridge on a bad baud rate: '$err'"
out=$("$build/bin/roomfix_sim" --config "$site" --radio-pty --faults all --check) ||
  fail "roomfix_sim --radio-pty --check failed"
[[ "$out" == *"pseudo-terminal"* ]] || fail "roomfix_sim --radio-pty --check printed '$out'"
err=$("$build/bin/roomfix_sim" --config "$site" --radio-pty --ranges --check 2>&1 >/dev/null)
(($? != 0)) && [[ "$err" == *"exclude each other"* ]] || fail "roomfix_sim --ranges --radio-pty: '$err'"

err=$(env -u DISPLAY "$build/bin/roomfix_viewer" --config "$site" 2>&1 >/dev/null)
(($? != 0)) && [[ "$err" == *"no display"* ]] || fail "roomfix_viewer without a display: '$err'"

logger=$build/bin/roomfix_logger
has "$("$logger" --help)" '--lcm-url' || fail "roomfix_logger --help lacks --lcm-url"
out=$("$logger" /tmp/never_written.lcm --check 2>/dev/null) || fail "roomfix_logger --check failed"
[[ "$out" == *"ok"* ]] || fail "roomfix_logger --check printed '$out'"
[[ ! -e /tmp/never_written.lcm ]] || fail "roomfix_logger --check wrote a file"
err=$("$logger" /tmp/x.lcm --lcm-url "nonsense://" 2>&1 >/dev/null)
(($? != 0)) && [[ "$err" == *"cannot start LCM"* ]] || fail "roomfix_logger on a bad URL: '$err'"

has "$("$build/bin/roomfix" version)" '^roomfix ' || fail "roomfix version"
has "$("$build/bin/roomfix" --help)" 'check-config' || fail "roomfix --help lacks check-config"
out=$("$build/bin/roomfix" log-info "$source/tests/data/ground_truth_sample.lcm") || fail "log-info"
grep -q 'POSE_GROUND_TRUTH.*roomfix.pose2d_t' <<<"$out" || fail "log-info did not list the poses: $out"

((failures == 0)) && echo "ok: process flags"
exit $((failures > 0))
