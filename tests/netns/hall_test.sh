#!/usr/bin/env bash
# The hall (config/sites/hall.yaml: 12 x 8 m, four cameras, twelve receivers
# on two radios, eight robots) across five simulated hosts on one LAN: network
# namespaces, each with its own hostname and a veth cable to a Linux bridge
# (as tests/netns/multi_host_test.sh), LCM at ttl=1:
#
#   camera-a  camera_proc --camera 0, --camera 1          -> POSE_CAMERA, MARKER_PIXELS
#   camera-b  camera_proc --camera 2, --camera 3
#   radio-a   roomfix_sim (the wall devices of both radios) + zigbee_bridge --radio 1
#   radio-b   zigbee_bridge --radio 2 on the simulator's second pseudo-terminal
#   solver    trilat_proc + fusion_proc + roomfix_logger   -> the log
#
# After ROOMFIX_HALL_SECONDS (default 60) everything stops with SIGINT and the
# solver host's log must show, for every robot: camera poses on the truth
# (p95 under kCameraP95 below) with no more than max_missed frames in a row without it from the cameras around it (so no
# robot was lost while handed from one camera to the next), ultrasonic fixes
# on the truth (p95 under kUltrasoundP95), fused poses never lost; and the
# logger must have written everything it received, and every MARKER_PIXELS
# each camera_proc published.
#
# The cameras run at ROOMFIX_HALL_FPS (default 10): four renderers at 30 fps
# do not fit a 2-core CI machine beside the rest (docs/operations.md,
# "A hall"; `roomfix_bench capacity` has what full rate needs).
#
#   hall_test.sh BIN_DIR SOURCE_DIR
#
# Exits 77 (ctest's skip code) when the machine does not allow the namespaces,
# and in the sanitizer build (below).
set -euo pipefail

bin=${1:?usage: hall_test.sh BIN_DIR SOURCE_DIR}
src=${2:?usage: hall_test.sh BIN_DIR SOURCE_DIR}
# The hall judges thirteen processes keeping up with real time on two cores
# (four cameras, eight robots). AddressSanitizer slows each several times:
# in `make test SANITIZE=1` the cameras fell to 5-16 fps with 450 ms of
# latency and the ultrasound to 1.1 Hz, and a robot lost a fused pose
# (issue #28). What it then measures is the sanitizer's cost, not roomfix:
# skipped there, saying so. The same processes' code runs under the
# sanitizer in multi_host_test, two_radios_test and kill_restart_test.
if ldd "$bin/roomfix_sim" 2>/dev/null | grep -q libasan; then
  echo "SKIP: a sanitizer build (roomfix_sim links libasan) cannot keep the hall's 13 processes in real time on this machine"
  exit 77
fi
seconds=${ROOMFIX_HALL_SECONDS:-60}
fps=${ROOMFIX_HALL_FPS:-10}
site=$src/config/sites/hall.yaml
url='udpm://239.255.76.67:7667?ttl=1'

# Targets (m). The synthetic clean camera maps a marker to a few mm; 1 cm at
# p95 leaves room for the time between a frame and the interpolated truth.
kCameraP95=0.010
# 12 receivers, 2 cm range noise and 5 % non-line-of-sight detours: 2 to 3
# cm at p95 in three runs; 10 cm catches a solver taking a detour.
kUltrasoundP95=0.10
# The filter between camera fixes: within the camera's figure plus motion.
kFusedP95=0.020
# No robot may go unseen for more than four frames in a row that the cameras
# around it processed (the frames either side of the miss that had a pose
# of it: a handover that drops the robot), after a 2 s warm-up (nine
# processes starting at once on two cores). Frames a loaded camera_proc
# dropped as stale (two periods old, counted in its STATUS; up to a second's
# worth in a stall of the shared machine) were never looked at and do not
# count (tests/netns/hall_handover.py).
max_missed=4

test_name=hall_test
# shellcheck source=tests/netns/bridged_hosts.sh
source "$(dirname "$0")/bridged_hosts.sh"
enter_private_namespaces "$@"
make_work_dir
make_bridged_hosts 10.78.0 camera-a camera-b radio-a radio-b solver

log=$work/solver.lcm
radio=$work/radio
on_host solver "$bin/roomfix_logger" "$log" --lcm-url "$url" --log-level info \
  2>"$work/roomfix_logger.err" &
logger=$!
on_host solver "$bin/trilat_proc" --config "$site" --lcm-url "$url" --method robust \
  --merge-deadline 0.5 --log-level warn 2>"$work/trilat_proc.err" &
trilat=$!
# --q-turn 1 --q-accel 0.1: the figures of eight turn at up to 1.9 rad/s at
# their ends, straighten within half a second and accelerate at 0.23 m/s²,
# which the defaults (0.3 and 0.03, tuned on the demo's gentle circle at
# 30 fps) cannot follow at the hall's 3 to 10 camera frames a second, nor
# through a stall of the shared machine: the prediction curved off, grew
# overconfident, and gated the next fixes and frames (docs/fusion.md,
# "The hall").
on_host solver "$bin/fusion_proc" --config "$site" --lcm-url "$url" \
  --camera-calibration-sigma 0.0003 --q-turn 1 --q-accel 0.1 --log-level warn \
  2>"$work/fusion_proc.err" &
fusion=$!
pids+=("$logger" "$trilat" "$fusion")
sleep 0.5  # the logger joins the group before anything publishes

start=$(($(date +%s%N) / 1000 + 1000000))
on_host radio-a "$bin/roomfix_sim" --config "$site" --lcm-url "$url" --start-utime "$start" \
  --radio-pty --pty-link "$radio" --range-noise 0.02 --nlos-probability 0.05 \
  --log-level warn >"$work/sim.out" 2>"$work/roomfix_sim.err" &
sim=$!
pids+=("$sim")
for _ in $(seq 100); do [[ -e "$radio-1" && -e "$radio-2" ]] && break; sleep 0.05; done
[[ -e "$radio-2" ]] || fail "roomfix_sim made no pseudo-terminal per radio: $(cat "$work/roomfix_sim.err")"
on_host radio-a "$bin/zigbee_bridge" --config "$site" --lcm-url "$url" --port "$radio-1" \
  --radio 1 --log-level warn 2>"$work/zigbee_bridge_1.err" &
bridge1=$!
on_host radio-b "$bin/zigbee_bridge" --config "$site" --lcm-url "$url" --port "$radio-2" \
  --radio 2 --log-level warn 2>"$work/zigbee_bridge_2.err" &
bridge2=$!
pids+=("$bridge1" "$bridge2")
cameras=()
for id in 0 1 2 3; do
  h=camera-a
  ((id < 2)) || h=camera-b
  on_host "$h" "$bin/camera_proc" --config "$site" --camera "$id" --lcm-url "$url" \
    --start-utime "$start" --fps "$fps" --log-level info 2>"$work/camera_proc_$id.err" &
  cameras+=($!)
done
pids+=("${cameras[@]}")

sleep "$seconds"
for pid in "${pids[@]}"; do
  kill -0 "$pid" 2>/dev/null || fail "a process died early (see $work)"
done
stop() {
  local pid=$1 rc=0
  kill -INT "$pid" 2>/dev/null || true
  for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
  kill -KILL "$pid" 2>/dev/null || true
  wait "$pid" || rc=$?
  return $rc
}
for pid in "${cameras[@]}" "$bridge1" "$bridge2" "$sim" "$trilat" "$fusion"; do
  stop "$pid" || fail "process $pid did not stop cleanly on SIGINT (exit $?; see $work)"
done
sleep 0.5
stop "$logger" || fail "roomfix_logger did not stop cleanly on SIGINT"
pids=()

# The logger wrote all it received.
summary=$(grep -o '[0-9]* received, [0-9]* written, [0-9]* dropped' "$work/roomfix_logger.err" ||
  true)
[[ -n "$summary" ]] || fail "no summary from roomfix_logger: $(cat "$work/roomfix_logger.err")"
read -r received _ written _ dropped _ <<<"$summary"
echo "  roomfix_logger: $summary"
((received == written && dropped == 0)) || fail "the logger lost messages: $summary"

"$bin/roomfix" compare "$log" --config "$site" >"$work/compare.txt" 2>"$work/compare.err" ||
  fail "roomfix compare: $(cat "$work/compare.err")"
sed 's/^/  /' "$work/compare.txt"
# source robot fixes rate_hz rmse_m p95_m max_m latency_ms lost
for robot in 1 2 3 4 5 6 7 8; do
  for check in "camera $kCameraP95" "ultrasound $kUltrasoundP95" "fused $kFusedP95"; do
    read -r source limit <<<"$check"
    row=$(awk -v s="$source" -v r="$robot" '$1 == s && $2 == r' "$work/compare.txt")
    [[ -n "$row" ]] || fail "robot $robot has no $source poses"
    read -r _ _ fixes _ _ p95 _ _ lost <<<"$row"
    awk -v p="$p95" -v l="$limit" 'BEGIN { exit !(p == p + 0 && p < l) }' ||
      fail "robot $robot: $source p95 $p95 m, over $limit m"
    if [[ "$source" == fused ]]; then
      ((lost == 0)) || fail "robot $robot: $lost lost fused poses"
    fi
  done
done

# Per robot, the longest time between camera poses (any camera) after the
# first: a handover that loses the robot shows as a gap. And per camera, the
# MARKER_PIXELS in the log against what its camera_proc says it processed.
"$bin/roomfix" listen --lcm-url "file://$log?speed=0" 2>/dev/null | grep '^{' >"$work/log.jsonl" ||
  true
grep '"channel":"POSE_CAMERA"' "$work/log.jsonl" |
  sed -n 's/.*"utime":\([0-9]*\).*"camera_id":\([-0-9]*\),"robot_id":\([0-9]*\).*"status":\([0-9]\).*/\3 \1 \2 \4/p' |
  sort -n -k1,1 -k2,2 >"$work/camera_poses.txt"
first=$(sort -n -k2,2 "$work/camera_poses.txt" | awk 'NR == 1 { print $2 }')
gaps=$(awk -v from=$((first + 2000000)) '$4 != 2 && $2 >= from {
              if ($1 == r && $2 - t > g[r]) g[r] = $2 - t; r = $1; t = $2 }
            END { for (k in g) print k, g[k] }' "$work/camera_poses.txt" | sort -n)
# Printed, not checked: a machine stall (a camera_proc dropping every frame
# for a second as stale, counted in its STATUS) shows here too. The check is
# hall_handover.py's: frames the cameras around a robot processed without it.
echo "  longest gap between camera poses per robot (us): $(echo $gaps)"
for id in 0 1 2 3; do
  processed=$(sed -n 's/.*stopped: \([0-9]*\) frames processed.*/\1/p' "$work/camera_proc_$id.err")
  logged=$(grep '"channel":"MARKER_PIXELS"' "$work/log.jsonl" | grep -c "\"camera_id\":$id," || true)
  echo "  camera $id: $processed frames processed, $logged MARKER_PIXELS logged"
  [[ -n "$processed" ]] || fail "camera_proc $id gave no summary"
  ((logged == processed)) || fail "camera $id: $processed frames, $logged MARKER_PIXELS in the log"
done
# Handovers: checked, the largest step of the fused error between two
# camera-held fused poses within 0.5 s of a camera's first or last frame of a
# stretch (the issue's bound: 1 cm) and the frames missed in a row; printed,
# the longest gap between fused poses, the degraded (ultrasound-held) poses
# among them and the fused covariance's coverage. A fused pose LOST anywhere
# fails the compare check above.
python3 "$src/tests/netns/hall_handover.py" "$work/log.jsonl" --warmup-s 2 --max-step-m 0.01 \
  --max-missed "$max_missed" ||
  fail "a handover moved a fused pose 1 cm or more, the cameras missed a robot on more than $max_missed frames in a row, or a robot was never handed over"
grep '"process":"fusion_proc"' "$work/log.jsonl" | tail -1 |
  grep -o '"rejected":{[^}]*},"counters":{[^}]*}' | sed 's/^/  fusion_proc: /'
"$bin/roomfix_bench" capacity --latency-only \
  --log "$log" | grep 'POSE_FUSED' | sed 's/^/ /'
echo "hall_test: passed"
