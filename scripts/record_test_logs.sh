#!/usr/bin/env bash
# Re-records the logs in tests/data that come from running roomfix itself.
# Run it after a deliberate change to a process's output (the replay tests
# then fail until the recording matches the new behaviour), and commit the
# new logs with the change that explains them.
#   scripts/record_test_logs.sh [BUILD_DIR [LOG_NAME...]]
# With LOG_NAMEs (e.g. pipeline_replay.lcm), only those logs are re-recorded.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$here/build}
only=("${@:2}")
bin=$build/bin
site=$here/config/sites/demo_room.yaml
data=$here/tests/data

record() {  # record OUT CHANNELS -- commands run in the namespace while lcm-logger records
  local out=$1 channels=$2
  shift 3
  if ((${#only[@]})) && [[ " ${only[*]} " != *" $(basename "$out") "* ]]; then return 0; fi
  rm -f "$out"
  "$here/scripts/netns_run" bash -c "
    lcm-logger -f '$out' -c '$channels' >/dev/null 2>&1 & logger=\$!
    sleep 0.5
    $*
    sleep 0.3
    kill -INT \$logger; wait \$logger"
  "$bin/roomfix" log-info "$out"
}

record "$data/ground_truth_sample.lcm" '.*' -- \
  "'$bin/roomfix_sim' --config '$site' --rate-hz 30 --duration 2.2 --log-level warn"

record "$data/trilat_replay.lcm" 'RANGES|POSE_ULTRASOUND' -- \
  "'$bin/trilat_proc' --config '$site' --method robust --log-level warn & solver=\$!;
   sleep 0.3;
   '$bin/roomfix_sim' --config '$site' --ranges --range-noise 0.02 --nlos-probability 0.1 \
     --dropout-probability 0.1 --seed 7 --duration 3.05 --log-level warn;
   sleep 0.3; kill -INT \$solver; wait \$solver"

# Issue #20: a log that carries its site (SITE from trilat_proc and
# roomfix_sim), for the tools that take the site from the log.
record "$data/site_sample.lcm" 'SITE|STATUS|RANGES|POSE_.*' -- \
  "'$bin/trilat_proc' --config '$site' --log-level warn & solver=\$!;
   sleep 0.3;
   '$bin/roomfix_sim' --config '$site' --ranges --range-noise 0.01 --seed 11 --duration 2.5 \
     --log-level warn;
   sleep 0.3; kill -INT \$solver; wait \$solver"

# The camera-less demo's ultrasound (make demo DEMO_CAMERA=0: the radio with
# the demo's faults, zigbee_bridge, trilat_proc --method robust) with ground
# truth at 10 Hz, 40 s, for fusion's covariance calibration test.
record "$data/ultrasound_demo_40s.lcm" 'POSE_ULTRASOUND|POSE_GROUND_TRUTH' -- \
  "'$bin/trilat_proc' --config '$site' --method robust --log-level warn & solver=\$!;
   rm -f /tmp/roomfix_record_radio;
   '$bin/roomfix_sim' --config '$site' --rate-hz 10 --duration 40 --log-level warn \
     --radio-pty --pty-link /tmp/roomfix_record_radio \
     --range-noise 0.02 --nlos-probability 0.05 --dropout-probability 0.02 \
     --buffering 0.05 --buffer-hold 0.04 --reorder 0.01 --duplicate 0.05 --lost-report 0.01 \
     --foreign 0.1 --corrupt-byte 0.0002 --garbage 0.01 >/dev/null & sim=\$!;
   for _ in \$(seq 100); do [[ -e /tmp/roomfix_record_radio ]] && break; sleep 0.05; done;
   '$bin/zigbee_bridge' --config '$site' --port /tmp/roomfix_record_radio --log-level warn & bridge=\$!;
   wait \$sim; sleep 0.3; kill -INT \$bridge \$solver; wait \$bridge \$solver"

# The demo's pipeline as live processes (the camera on the synthetic ceiling
# camera, trilat_proc robust, fusion_proc) for the replay tests
# (tools/replay_test.cc): their inputs and outputs, with the camera's marker
# pixels (the input of --nodes camera) but not its previews.
record "$data/pipeline_replay.lcm" 'RANGES|POSE_.*|STATUS|SITE|MARKER_PIXELS' -- \
  "'$bin/trilat_proc' --config '$site' --method robust --log-level warn & solver=\$!;
   '$bin/fusion_proc' --config '$site' --log-level warn & fusion=\$!;
   start=\$(( \$(date +%s%6N) + 1000000 ));
   '$bin/camera_proc' --config '$site' --device sim:reference_circle --start-utime \$start --log-level warn & camera=\$!;
   sleep 0.3;
   '$bin/roomfix_sim' --config '$site' --start-utime \$start --ranges --range-noise 0.02 \
     --nlos-probability 0.05 --dropout-probability 0.02 --seed 11 --duration 5 --log-level warn;
   sleep 0.3; kill -INT \$camera \$fusion \$solver; wait \$camera \$fusion \$solver"

# The demo itself (scripts/demo.sh, 30 s: the synthetic webcam, the radio
# with the demo's faults, zigbee_bridge, trilat_proc robust, fusion_proc)
# without its previews and heartbeats, for the regression test of the
# README's headline figures (DemoFigures in tests/tools/analyze_test.cc), which
# replays its camera, trilat and fusion nodes: their inputs (MARKER_PIXELS,
# RANGES), the ground truth, the site and the live poses.
record "$data/demo_30s.lcm" 'RANGES|POSE_.*|SITE|MARKER_PIXELS' -- \
  "'$here/scripts/demo.sh' '$build' 30 --inner"
