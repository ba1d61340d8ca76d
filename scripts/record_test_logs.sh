#!/usr/bin/env bash
# Re-records the logs in tests/data that come from running roomfix itself.
# Run it after a deliberate change to a process's output (the replay tests
# then fail until the recording matches the new behaviour), and commit the
# new logs with the change that explains them.
#   scripts/record_test_logs.sh [BUILD_DIR]
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$here/build}
bin=$build/bin
site=$here/config/sites/demo_room.yaml
data=$here/tests/data

record() {  # record OUT CHANNELS -- commands run in the namespace while lcm-logger records
  local out=$1 channels=$2
  shift 3
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

# The demo's pipeline as live processes (the camera on the synthetic ceiling
# camera, trilat_proc robust, fusion_proc) for the replay tests
# (tools/replay_test.cc): their inputs and outputs, with the camera's marker
# pixels (the input of --nodes camera) but not its previews.
record "$data/pipeline_replay.lcm" 'RANGES|POSE_.*|STATUS|SITE|MARKER_PIXELS' -- \
  "'$bin/trilat_proc' --config '$site' --method robust --log-level warn & solver=\$!;
   '$bin/fusion_proc' --config '$site' --log-level warn & fusion=\$!;
   start=\$(( \$(date +%s%6N) + 1000000 ));
   '$bin/camera_proc' --config '$site' --start-utime \$start --log-level warn & camera=\$!;
   sleep 0.3;
   '$bin/roomfix_sim' --config '$site' --start-utime \$start --ranges --range-noise 0.02 \
     --nlos-probability 0.05 --dropout-probability 0.02 --seed 11 --duration 5 --log-level warn;
   sleep 0.3; kill -INT \$camera \$fusion \$solver; wait \$camera \$fusion \$solver"
