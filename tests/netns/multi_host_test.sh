#!/usr/bin/env bash
# Several hosts on one LAN, simulated: three network namespaces ("camera",
# "radio", "solver"), each with its own hostname (UTS namespace) and one veth
# cable to a Linux bridge, addresses 10.77.0.1-3/24, 224.0.0.0/4 routed to the
# veth. The processes speak LCM at ttl=1 as on a real LAN:
#
#   camera host  camera_proc (synthetic camera)           -> POSE_CAMERA, MARKER_PIXELS
#   radio host   roomfix_sim --radio-pty + zigbee_bridge  -> RANGES (the pty is local to it)
#   solver host  trilat_proc + roomfix_logger             -> POSE_ULTRASOUND, the log
#
# After a few seconds everything stops with SIGINT and the solver host's log
# must hold POSE_CAMERA from the camera host, RANGES from the radio host,
# POSE_ULTRASOUND, and STATUS from every process stamped with its own host's
# name. Nothing leaves this machine: the namespaces are private (user + net +
# mount + UTS namespaces, no root needed).
#
#   multi_host_test.sh BIN_DIR SOURCE_DIR [SECONDS]
#
# Exits 77 (ctest's skip code) with one line when this machine does not allow
# the namespaces, a bridge or veth pairs.
set -euo pipefail

bin=${1:?usage: multi_host_test.sh BIN_DIR SOURCE_DIR [SECONDS]}
src=${2:?usage: multi_host_test.sh BIN_DIR SOURCE_DIR [SECONDS]}
seconds=${3:-8}
site=$src/config/sites/demo_room.yaml
url='udpm://239.255.76.67:7667?ttl=1'

test_name=multi_host_test
# shellcheck source=tests/netns/bridged_hosts.sh
source "$(dirname "$0")/bridged_hosts.sh"
enter_private_namespaces "$@"
# --- Inside: root of a private user namespace, in the "LAN" namespace. ------
make_work_dir
make_bridged_hosts 10.77.0 camera radio solver

start=$(( $(date +%s%N) / 1000 ))
log=$work/solver.lcm
radio=$work/radio

on_host solver "$bin/roomfix_logger" "$log" --lcm-url "$url" --log-level warn \
  2>"$work/roomfix_logger.err" &
logger=$!
pids+=("$logger")
on_host solver "$bin/trilat_proc" --config "$site" --lcm-url "$url" --method robust \
  --log-level warn 2>"$work/trilat_proc.err" &
trilat=$!
pids+=("$trilat")
sleep 0.5  # the logger joins the group before anything publishes

on_host radio "$bin/roomfix_sim" --config "$site" --lcm-url "$url" --start-utime "$start" \
  --radio-pty --pty-link "$radio" --log-level warn >"$work/sim.out" 2>"$work/roomfix_sim.err" &
sim=$!
pids+=("$sim")
for _ in $(seq 100); do [[ -e "$radio" ]] && break; sleep 0.05; done
[[ -e "$radio" ]] || fail "roomfix_sim made no pseudo-terminal: $(cat "$work/roomfix_sim.err")"
on_host radio "$bin/zigbee_bridge" --config "$site" --lcm-url "$url" --port "$radio" \
  --log-level warn 2>"$work/zigbee_bridge.err" &
bridge=$!
pids+=("$bridge")

on_host camera "$bin/camera_proc" --config "$site" --lcm-url "$url" --start-utime "$start" \
  --log-level warn 2>"$work/camera_proc.err" &
camera=$!
pids+=("$camera")

sleep "$seconds"
for p in camera bridge sim trilat; do
  pid=${!p}
  kill -0 "$pid" 2>/dev/null || fail "$p died early (see $work)"
done
# SIGINT, then the exit code within 10 s (128 + 9 when it had to be killed).
stop() {
  local pid=$1 rc=0
  kill -INT "$pid" 2>/dev/null || true
  for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
  kill -KILL "$pid" 2>/dev/null || true
  wait "$pid" || rc=$?
  return $rc
}
# Producers first, so the logger sees their last heartbeats.
for p in camera bridge sim trilat; do
  stop "${!p}" || fail "$p did not stop cleanly on SIGINT (exit $?)"
done
sleep 0.3
stop "$logger" || fail "roomfix_logger did not stop cleanly on SIGINT (exit $?)"
pids=()

"$bin/roomfix" log-info "$log" | sed 's/^/  /'
"$bin/roomfix" listen --lcm-url "file://$log?speed=0" 2>/dev/null | grep "^{" >"$work/log.jsonl" || true

# One JSON line per message; counted with grep (the fields come in the
# message's order: "process":...,"host":...).
count() { grep -c "\"channel\":\"$1\"" "$work/log.jsonl" || true; }
n_camera=$(count POSE_CAMERA)
n_ranges=$(count RANGES)
n_ultra=$(count POSE_ULTRASOUND)
echo "  logged on roomfix-solver: $n_camera POSE_CAMERA, $n_ranges RANGES, $n_ultra POSE_ULTRASOUND"
# Camera at up to 30 fps and the radio at 10 Hz for $seconds s; generous floors
# for a loaded machine.
((n_camera >= 2 * seconds)) || fail "only $n_camera POSE_CAMERA from the camera host"
((n_ranges >= 5 * seconds)) || fail "only $n_ranges RANGES from the radio host"
((n_ultra >= 3 * seconds)) || fail "only $n_ultra POSE_ULTRASOUND from the solver host"

grep '"channel":"STATUS"' "$work/log.jsonl" |
  grep -o '"process":"[^"]*","host":"[^"]*"' | sed 's/"process":"\([^"]*\)","host":"\([^"]*\)"/\1 \2/' \
  >"$work/status.txt" || true
echo "  STATUS heartbeats by process and host:"
sort "$work/status.txt" | uniq -c | sed 's/^/    /'
expect_host() {
  local process=$1 host=$2 n
  n=$(grep -c "^$process $host\$" "$work/status.txt" || true)
  ((n >= 2)) || fail "$n STATUS from $process on $host"
  n=$(grep "^$process " "$work/status.txt" | grep -vc " $host\$" || true)
  ((n == 0)) || fail "$n STATUS from $process on a host other than $host"
}
expect_host camera_proc roomfix-camera
expect_host roomfix_sim roomfix-radio
expect_host zigbee_bridge roomfix-radio
expect_host trilat_proc roomfix-solver
expect_host roomfix_logger roomfix-solver
# The control: at ttl=0 nothing crosses from one host to another, so what
# arrived above really went over the "LAN". A listener on the camera host
# itself must hear the control's simulator (it started and published), while
# the solver host's must time out (listen exits 3); a listener that timed out
# because nothing was published at all proves nothing.
local_url='udpm://239.255.76.67:7667?ttl=0'
on_host solver "$bin/roomfix" listen --lcm-url "$local_url" --channel POSE_GROUND_TRUTH \
  --count 1 --timeout 3 >/dev/null 2>&1 &
listener=$!
pids+=("$listener")
on_host camera "$bin/roomfix" listen --lcm-url "$local_url" --channel POSE_GROUND_TRUTH \
  --count 1 --timeout 3 >"$work/control_same_host.out" 2>&1 &
same_host=$!
pids+=("$same_host")
sleep 0.3
on_host camera "$bin/roomfix_sim" --config "$site" --lcm-url "$local_url" --duration 2 \
  --log-level error >/dev/null 2>"$work/control_sim.err" &
control_sim=$!
pids+=("$control_sim")
rc=0
wait "$control_sim" || rc=$?
((rc == 0)) || fail "the control's roomfix_sim on the camera host failed (exit $rc): $(cat "$work/control_sim.err")"
rc=0
wait "$same_host" || rc=$?
((rc == 0)) || fail "at ttl=0 the camera host did not hear its own roomfix_sim (listen exit $rc), so the control proves nothing: $(cat "$work/control_same_host.out")"
rc=0
wait "$listener" || rc=$?
((rc == 3)) || fail "at ttl=0 a message crossed from the camera host to the solver host (listen exit $rc)"
echo "  control: the camera host heard its own simulator at ttl=0; nothing crossed to the solver host"
echo "multi_host_test: passed"
