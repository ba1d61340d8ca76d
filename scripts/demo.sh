#!/usr/bin/env bash
# `make demo`: runs the roomfix pipeline on the simulator with the embedded
# default site (config/sites/demo_room.yaml), records everything with
# roomfix_logger, and summarises the log.
#
#   [DEMO_CAMERA=0] [DEMO_SITE=FILE] [DEMO_CAMERA_FPS=N] scripts/demo.sh BUILD_DIR SECONDS
#
# DEMO_CAMERA=0 runs the ultrasound path alone, as a lab with no ceiling
# camera would: no camera_proc, so fusion_proc has only POSE_ULTRASOUND.
# DEMO_SITE runs another site (config/sites/hall.yaml: four cameras, two
# radios, eight robots): one camera_proc per camera (--camera ID), one
# zigbee_bridge per radio (--radio ID) on the simulator's pseudo-terminal for
# it. On a machine with fewer than two cores per camera the cameras run at
# DEMO_CAMERA_FPS (default 10; the site's rate when enough cores), and the
# summary says so (docs/operations.md, "A hall").
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
# DEMO_DEVICES=firmware plays the beacon and the receivers as their firmware
# in simavr (roomfix_sim --devices firmware) instead of the behavioural model.
devices=${DEMO_DEVICES:-behavioural}
if [[ "$devices" != behavioural && "$devices" != firmware ]]; then
  echo "demo.sh: DEMO_DEVICES must be behavioural or firmware, not '$devices'" >&2
  exit 2
fi
export DEMO_DEVICES=$devices
here=$(cd "$(dirname "$0")/.." && pwd)
site=${DEMO_SITE:-$here/config/sites/demo_room.yaml}
[[ "$site" == /* ]] || site=$PWD/$site
if [[ ! -f "$site" ]]; then
  echo "demo.sh: DEMO_SITE: no file $site" >&2
  exit 2
fi
export DEMO_SITE=$site
out=$here/build/demo
bin=$build/bin
[[ "$bin" == /* ]] || bin=$here/$bin
# The site's cameras and radios (ids, one per line; none: an empty list).
mapfile -t camera_ids < <("$bin/roomfix" check-config --ids cameras "$site")
mapfile -t radio_ids < <("$bin/roomfix" check-config --ids radios "$site")
((camera)) || camera_ids=()
# Every camera_proc renders and searches its own frames: measured
# (roomfix_bench capacity) a 1280 x 960 synthetic camera at 30 fps takes
# most of a core, so with fewer than two cores per camera they run slower.
camera_fps=${DEMO_CAMERA_FPS:-}
if [[ -z "$camera_fps" ]] && ((${#camera_ids[@]} > 1 && $(nproc) < 2 * ${#camera_ids[@]})); then
  camera_fps=10
fi
export DEMO_CAMERA_FPS=$camera_fps

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
  # Several radios: a firing's parts come through different bridges; a
  # loaded machine can hold one back past the default 0.1 s.
  trilat_args=()
  ((${#radio_ids[@]} < 2)) || trilat_args+=(--merge-deadline 0.5)
  # The firmware's ranges are 4x finer than the behavioural model's 2 cm
  # noise: a range sigma of 5 mm from the devices' error budget
  # (docs/devices.md, "Range sigma"), or every fix's ellipse is too large.
  [[ "$devices" != firmware ]] || trilat_args+=(--range-sigma 0.005)
  "$bin/trilat_proc" --config "$site" --method robust --log-level info "${trilat_args[@]}" \
    2>"$out/trilat_proc.txt" &
  pids+=($!)
  if [[ -x "$bin/fusion_proc" ]]; then
    # Several cameras: each calibration's error at a place is the same in
    # every frame, so fusion adds it as --camera-calibration-sigma
    # (docs/fusion.md, "Several cameras"): 0.3 mm for the hall, whose
    # calibrations are fitted to the discs' centres over each camera's whole
    # view (docs/calibration.md; measured: 93.7 to 100 % of fused errors in
    # the 95 % ellipse); 0.6 mm for two_cameras, whose two calibrations
    # disagree by up to 1.02 mm in the overlap. The hall's figures of eight
    # turn and accelerate harder than the default process noise follows at
    # the hall's reduced frame rate (docs/fusion.md, "The hall").
    fusion_args=()
    if ((${#camera_ids[@]} > 1)); then
      calibration_sigma_m=0.0006
      [[ "$(basename "$site")" != hall.yaml ]] || calibration_sigma_m=0.0003
      fusion_args+=(--camera-calibration-sigma "$calibration_sigma_m" --q-turn 1 --q-accel 0.1)
    fi
    "$bin/fusion_proc" --config "$site" --log-level info "${fusion_args[@]}" \
      2>"$out/fusion_proc.txt" &
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
  # The demo room's webcam renders through its own lens, whose fit is
  # demo_room_webcam.yaml: every site with the demo room's camera (the demo
  # room, its pillar variant) takes it, or its camera poses sit 2 cm off
  # (camera_proc warns: "is not the lens sim:webcam renders through"); other
  # sites' cameras use their own calibration.
  camera_args=()
  if grep -q '^ *calibration: \.\./calibration/demo_room_camera\.yaml' "$site"; then
    camera_args+=(--calibration "$here/config/calibration/demo_room_webcam.yaml")
  fi
  [[ -z "$camera_fps" ]] || camera_args+=(--fps "$camera_fps")
  for id in "${camera_ids[@]}"; do
    name=camera_proc
    ((${#camera_ids[@]} == 1)) || name=camera_proc_$id
    "$bin/camera_proc" --config "$site" --camera "$id" --start-utime "$start_utime" \
      --log-level info "${camera_args[@]}" 2>"$out/$name.txt" &
    pids+=($!)
  done
  # The simulator publishes the true poses and plays the beacon and the wall
  # receivers on a pseudo-terminal, with a radio that buffers, reorders,
  # duplicates, loses and corrupts, and a neighbour's module on the air;
  # zigbee_bridge reads it as it would a ZigBee coordinator on /dev/ttyUSB0.
  radio=$out/radio
  rm -f "$radio"
  # With DEMO_DEVICES=firmware the devices are their firmware: the noise is
  # the model's (radio timing, detector), the faults those with a place there
  # (a lost frame, a buffering module).
  if [[ "$devices" == firmware ]]; then
    device_args=(--devices firmware --buffering 0.05 --buffer-hold 0.04 --lost-report 0.01)
  else
    device_args=(--range-noise 0.02 --nlos-probability 0.05 --dropout-probability 0.02
      --buffering 0.05 --buffer-hold 0.04 --reorder 0.01 --duplicate 0.05 --lost-report 0.01
      --foreign 0.1 --corrupt-byte 0.0002 --garbage 0.01)
  fi
  "$bin/roomfix_sim" --config "$site" --log-level info --start-utime "$start_utime" \
    --radio-pty --pty-link "$radio" "${device_args[@]}" \
    > "$out/roomfix_sim.path" 2> >(sed 's/^/  /') &
  sim=$!
  # One coordinator (the site names no radios) or one per radio, each on
  # its own pseudo-terminal RADIO-ID.
  ports=("$radio")
  bridge_args=("")
  if ((${#radio_ids[@]})); then
    ports=()
    bridge_args=()
    for id in "${radio_ids[@]}"; do
      ports+=("$radio-$id")
      bridge_args+=("$id")
    done
  fi
  # The firmware's receivers answer after their listening window, one by
  # one: the bridge's deadline is what `roomfix devices` says it must be
  # for this site (docs/devices.md, "The bridge's deadline").
  deadline_args=()
  if [[ "$devices" == firmware ]]; then
    deadline_ms=$("$bin/roomfix" devices --config "$site" --out "$out/devices" |
      sed -n 's/^zigbee_bridge: .* e\.g\. \([0-9]*\) .*/\1/p')
    [[ -z "$deadline_ms" ]] || deadline_args=(--deadline-ms "$deadline_ms")
  fi
  bridges=()
  for i in "${!ports[@]}"; do
    for _ in $(seq 100); do [[ -e "${ports[$i]}" ]] && break; sleep 0.05; done
    args=(--config "$site" --port "${ports[$i]}" --log-level info "${deadline_args[@]}")
    [[ -z "${bridge_args[$i]}" ]] || args+=(--radio "${bridge_args[$i]}")
    "$bin/zigbee_bridge" "${args[@]}" 2> >(sed 's/^/  /') &
    bridges+=($!)
  done
  pids+=("${bridges[@]}" "$sim")
  sleep "$seconds"
  kill -INT "$viewer" 2>/dev/null || true
  wait "$viewer" 2>/dev/null || true
  # The bridge stops before its device goes away, so its last word is a
  # clean summary rather than a lost device.
  for bridge in "${bridges[@]}"; do kill -INT "$bridge"; done
  for bridge in "${bridges[@]}"; do wait "$bridge" || true; done
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
[[ "$devices" != firmware ]] ||
  echo "  devices: the beacon's and receivers' firmware in simavr, one ATmega328P each (DEMO_DEVICES=firmware)"
if [[ -n "$camera_fps" ]]; then
  echo "  ${#camera_ids[@]} cameras at $camera_fps fps, below the site's rate: $(nproc) cores" \
    "carry fewer than 2 per camera (DEMO_CAMERA_FPS sets it; full rate: docs/operations.md, \"A hall\")"
fi
((${#radio_ids[@]} < 2)) || echo "  ${#radio_ids[@]} radios: one zigbee_bridge each (--radio ID)"
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
echo "  devices: $devices$([[ "$devices" != firmware ]] || echo " (build/firmware/*.elf in simavr)")"
if [[ -n "$camera_fps" ]]; then
  echo "  cameras: ${#camera_ids[@]} at $camera_fps fps (reduced for this machine's $(nproc) cores)"
fi
