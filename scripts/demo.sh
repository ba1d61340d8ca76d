#!/usr/bin/env bash
# `make demo`: runs the roomfix pipeline on the simulator with the embedded
# default site (config/sites/demo_room.yaml), records everything with
# roomfix_logger, and summarises the log.
#
#   [DEMO_CAMERA=0] scripts/demo.sh BUILD_DIR SECONDS
#
# DEMO_CAMERA=0 runs the ultrasound path alone, as a lab with no ceiling
# camera would: no camera_proc, so fusion_proc has only POSE_ULTRASOUND.
#
# Runs inside a private network namespace when this machine allows one, so the
# multicast traffic stays private; otherwise on the host-only LCM default
# (ttl=0).
set -euo pipefail
build=${1:-build}
seconds=${2:-10}
camera=${DEMO_CAMERA:-1}
if [[ "$camera" != 0 && "$camera" != 1 ]]; then
  echo "demo.sh: DEMO_CAMERA must be 0 or 1, not '$camera'" >&2
  exit 2
fi
export DEMO_CAMERA=$camera
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
  if [[ -x "$bin/fusion_proc" ]]; then
    "$bin/fusion_proc" --config "$site" --log-level info 2>"$out/fusion_proc.txt" &
    pids+=($!)
  fi
  # The viewer: a window when there is a display, else headless, saving the
  # last picture.
  viewer_args=(--png "$out/viewer.png")
  [[ -n "${DISPLAY:-}" ]] || viewer_args+=(--headless)
  "$bin/roomfix_viewer" --config "$site" "${viewer_args[@]}" --log-level warn \
    2>"$out/roomfix_viewer.txt" &
  viewer=$!
  sleep 0.5  # let the logger and the solver join the group before anything publishes
  # One t = 0 for the simulator and the synthetic camera, a moment ahead so
  # both are up when the robot starts.
  start_utime=$(( $(date +%s%6N) + 1000000 ))
  # The ceiling camera: the synthetic webcam (the site's sim:webcam: blur,
  # rolling shutter, sensor noise, Bayer, MJPEG at quality 80, timestamp
  # latency and jitter; docs/synthetic_camera.md) renders the robot at
  # 1920 x 1080 and 30 fps through its own lens, whose calibration
  # demo_room_webcam.yaml is (the site's names the nominal lens).
  if ((camera)); then
    "$bin/camera_proc" --config "$site" --start-utime "$start_utime" --log-level info \
      --calibration "$here/config/calibration/demo_room_webcam.yaml" \
      2>"$out/camera_proc.txt" &
    pids+=($!)
  fi
  # The simulator publishes the true poses and plays the beacon and the wall
  # receivers on a pseudo-terminal, with a radio that buffers, reorders,
  # duplicates, loses and corrupts, and a neighbour's module on the air;
  # zigbee_bridge reads it as it would a ZigBee coordinator on /dev/ttyUSB0.
  radio=$out/radio
  rm -f "$radio"
  "$bin/roomfix_sim" --config "$site" --log-level info --start-utime "$start_utime" \
    --radio-pty --pty-link "$radio" \
    --range-noise 0.02 --nlos-probability 0.05 --dropout-probability 0.02 \
    --buffering 0.05 --buffer-hold 0.04 --reorder 0.01 --duplicate 0.05 --lost-report 0.01 \
    --foreign 0.1 \
    --corrupt-byte 0.0002 --garbage 0.01 \
    > "$out/roomfix_sim.path" 2> >(sed 's/^/  /') &
  sim=$!
  for _ in $(seq 100); do [[ -e "$radio" ]] && break; sleep 0.05; done
  "$bin/zigbee_bridge" --config "$site" --port "$radio" --log-level info \
    2> >(sed 's/^/  /') &
  bridge=$!
  pids+=("$bridge" "$sim")
  sleep "$seconds"
  kill -INT "$viewer" 2>/dev/null || true
  wait "$viewer" 2>/dev/null || true
  # The bridge stops before its device goes away, so its last word is a
  # clean summary rather than a lost device.
  kill -INT "$bridge"
  wait "$bridge" || true
  kill -INT "$sim"
  wait "$sim" || true
  sleep 0.3  # let the last messages reach the logger
  cleanup
  trap - EXIT
  exit 0
fi

mkdir -p "$out"
echo "roomfix demo: ${seconds} s on the simulator, site $site"
((camera)) || echo "  without the ceiling camera (DEMO_CAMERA=0): the ultrasound path alone"
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
echo "The reference paper's measurements (timing, circle fits, errors, figures), and whether"
echo "each source can be trusted (status shares, worst fix flagged ok, errors inside the"
echo "fix's own 95 % covariance ellipse: 95 % and a median squared distance of 1.39 when calibrated):"
"$bin/roomfix" analyze "$out/demo.lcm" --out "$out/analysis" | sed 's/^/  /'
echo
echo "Each pose source against the simulator's ground truth:"
"$bin/roomfix" compare "$out/demo.lcm" --json "$out/summary.json" \
  --report "$out/analysis/report.md" | sed 's/^/  /'
echo
echo "  log:     $out/demo.lcm (replay: lcm-logplayer $out/demo.lcm)"
echo "  report:  $out/analysis/report.md (figures in $out/analysis/)"
echo "  viewer:  $out/viewer.png"
echo "  summary: $out/summary.json"
