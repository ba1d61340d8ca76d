#!/usr/bin/env bash
# `make demo`: runs the roomfix pipeline on the simulator with the embedded
# default site (config/sites/demo_room.yaml), records everything with
# roomfix_logger, and summarises the log.
#
#   scripts/demo.sh BUILD_DIR SECONDS
#
# Runs inside a private network namespace when this machine allows one, so the
# multicast traffic stays private; otherwise on the host-only LCM default
# (ttl=0). As later parts land (trilat_proc, zigbee_bridge, camera_proc, the
# logger, the viewer) they join the process list below.
set -euo pipefail
build=${1:-build}
seconds=${2:-10}
here=$(cd "$(dirname "$0")/.." && pwd)
site=$here/config/sites/demo_room.yaml
out=$here/build/demo
bin=$build/bin
[[ "$bin" == /* ]] || bin=$here/$bin

if [[ "${3:-}" == "--inner" ]]; then
  log=$out/demo.lcm
  rm -f "$log"
  pids=()
  cleanup() {
    for pid in "${pids[@]}"; do kill -INT "$pid" 2>/dev/null || true; done
    wait 2>/dev/null || true
  }
  trap cleanup EXIT
  "$bin/roomfix_logger" "$log" --force --log-level warn 2>"$out/roomfix_logger.txt" &
  pids+=($!)
  "$bin/trilat_proc" --config "$site" --method robust --log-level info 2>"$out/trilat_proc.txt" &
  pids+=($!)
  sleep 0.5  # let the logger and the solver join the group before anything publishes
  # The simulator publishes the true poses and, standing in for the virtual
  # wall devices and zigbee_bridge until they exist, noisy range sets.
  "$bin/roomfix_sim" --config "$site" --duration "$seconds" --log-level info \
    --ranges --range-noise 0.02 --nlos-probability 0.05 --dropout-probability 0.02 \
    2>&1 | sed 's/^/  /'
  sleep 0.3  # let the last messages reach the logger
  cleanup
  trap - EXIT
  exit 0
fi

mkdir -p "$out"
echo "roomfix demo: ${seconds} s on the simulator, site $site"
"$bin/roomfix" check-config "$site" | sed 's/^/  /'
rc=0
"$here/scripts/netns_run" "$0" "$build" "$seconds" --inner 2>/dev/null || rc=$?
if ((rc == 77)); then
  echo "  (no private network namespace here; using the host-only LCM default, ttl=0)"
  "$0" "$build" "$seconds" --inner
elif ((rc != 0)); then
  exit $rc
fi

echo
echo "Recorded log: $out/demo.lcm (replay with: lcm-logplayer $out/demo.lcm)"
"$bin/roomfix" log-info "$out/demo.lcm" | sed 's/^/  /'
echo
echo "Each pose source against the simulator's ground truth (summary: $out/summary.json):"
"$bin/roomfix" compare "$out/demo.lcm" --json "$out/summary.json" --fit-circle | sed 's/^/  /'
