#!/usr/bin/env bash
# roomfix_logger --increment as bot-procman runs it (the demo's logger in
# sim_demo.pmd): a second start, as a respawn or a second sheriff's restart
# does, writes the next numbered file and leaves the first byte for byte.
# Each run records a recorded log replayed into it (file://...?speed=0) and
# stops at its end, so both files hold real traffic.
#   logger_restart_test.sh BUILD_DIR SOURCE_DIR
set -uo pipefail
build=$1 source=$2
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
events() { "$build/bin/roomfix" log-info "$1" | head -1 | sed -E 's/.*: ([0-9]+) events.*/\1/'; }

run_logger() {  # run_logger SOURCE_LOG: records it into $tmp/sim_demo.lcm --increment
  # At the end of the replayed log the process stops with exit 1 ("end of log").
  "$build/bin/roomfix_logger" "$tmp/sim_demo.lcm" --increment --log-level warn \
    --lcm-url "file://$1?speed=0" 2>"$tmp/logger.err"
  grep -q "end of log" "$tmp/logger.err" || fail "logger did not stop at the end of $1: $(cat "$tmp/logger.err")"
}

first_src=$source/tests/data/trilat_replay.lcm
second_src=$source/tests/data/ground_truth_sample.lcm
run_logger "$first_src"
[[ -f $tmp/sim_demo-00.lcm ]] || fail "the first run wrote no sim_demo-00.lcm: $(ls "$tmp")"
[[ -e $tmp/sim_demo.lcm ]] && fail "the bare name sim_demo.lcm was written"
first_events=$(events "$tmp/sim_demo-00.lcm")
[[ $first_events == $(events "$first_src") ]] ||
  fail "the first run recorded $first_events events of $(events "$first_src")"
first_sum=$(sha256sum <"$tmp/sim_demo-00.lcm")

run_logger "$second_src"   # the restart
[[ -f $tmp/sim_demo-01.lcm ]] || fail "the restart wrote no sim_demo-01.lcm: $(ls "$tmp")"
[[ $(sha256sum <"$tmp/sim_demo-00.lcm") == "$first_sum" ]] || fail "the restart changed sim_demo-00.lcm"
[[ $(events "$tmp/sim_demo-01.lcm") == $(events "$second_src") ]] ||
  fail "the restart recorded $(events "$tmp/sim_demo-01.lcm") events of $(events "$second_src")"

((failures == 0)) && echo "ok: sim_demo-00.lcm ($first_events events) intact after a restart wrote sim_demo-01.lcm"
exit $((failures > 0))
