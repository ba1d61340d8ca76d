#!/usr/bin/env bash
# `roomfix check-config` accepts every shipped site file, and gives each
# broken one in tests/data/broken_sites (the site itself is wrong) and
# tests/data/broken_calibration_sites (a valid site naming a calibration that
# camera_proc would refuse) exactly one line on stderr, naming the file and
# the expected problem, with a non-zero exit.
#   check_config_test.sh BUILD_DIR SOURCE_DIR
set -uo pipefail
build=$1 source=$2
roomfix=$build/bin/roomfix
failures=0

for site in "$source"/config/sites/*.yaml; do
  if ! out=$("$roomfix" check-config "$site" 2>&1); then
    echo "FAIL: $site rejected: $out"; failures=$((failures + 1))
  fi
done

for site in "$source"/tests/data/broken_sites/*.yaml \
  "$source"/tests/data/broken_calibration_sites/*.yaml; do
  expected=$(head -1 "$site" | sed 's/^# expect: //')
  stdout=$("$roomfix" check-config "$site" 2>/tmp/check_config_err.$$)
  rc=$?
  stderr=$(cat /tmp/check_config_err.$$)
  lines=$(printf '%s\n' "$stderr" | grep -c .)
  if ((rc != 1)); then
    echo "FAIL: $site: exit $rc, expected 1"; failures=$((failures + 1))
  elif [[ -n "$stdout" || $lines -ne 1 ]]; then
    echo "FAIL: $site: expected one line on stderr, got stdout '$stdout' and stderr:"
    echo "$stderr"; failures=$((failures + 1))
  elif [[ "$stderr" != "$site:"* || "$stderr" != *"$expected"* ]]; then
    echo "FAIL: $site: '$stderr' does not name the file and '$expected'"; failures=$((failures + 1))
  else
    echo "ok: $stderr"
  fi
done
rm -f /tmp/check_config_err.$$

# Not files at all: refused at once (a read of /dev/zero would never end;
# the timeout makes a hang a failure instead of a stuck test).
for path in /dev/zero "$source/config"; do
  err=$(timeout 10 "$roomfix" check-config "$path" 2>&1 >/dev/null)
  rc=$?
  if ((rc != 1)) || [[ "$err" != "$path: not a regular file ("* ]]; then
    echo "FAIL: check-config $path: exit $rc, stderr '$err'"; failures=$((failures + 1))
  else
    echo "ok: $err"
  fi
done
# Streaming text inputs (map, solve) refuse an endless line instead of
# growing it until memory runs out.
for cmd in "map --calibration $source/config/calibration/demo_room_camera.yaml" "solve"; do
  name=${cmd%% *}
  # shellcheck disable=SC2086
  err=$(timeout 10 "$roomfix" $cmd /dev/zero 2>&1 >/dev/null)
  rc=$?
  if ((rc != 1)) || [[ "$err" != "roomfix $name: /dev/zero:1: line longer than 64 KiB: not a text input" ]]; then
    echo "FAIL: $name /dev/zero: exit $rc, stderr '$err'"; failures=$((failures + 1))
  else
    echo "ok: $err"
  fi
done

# --ids: what scripts/demo.sh and the hall test start one process per.
ids=$("$roomfix" check-config --ids cameras "$source/config/sites/hall.yaml" | tr '\n' ' ')
radios=$("$roomfix" check-config --ids radios "$source/config/sites/hall.yaml" | tr '\n' ' ')
none=$("$roomfix" check-config --ids radios "$source/config/sites/demo_room.yaml")
if [[ "$ids" != "0 1 2 3 " || "$radios" != "1 2 " || -n "$none" ]]; then
  echo "FAIL: check-config --ids: cameras '$ids', radios '$radios', demo room radios '$none'"
  failures=$((failures + 1))
else
  echo "ok: check-config --ids: hall cameras $ids, radios $radios; demo room no radios"
fi

# camera_proc refuses the same calibration check-config refuses: a stored
# fit residual over tolerance.
bad_fit=$source/tests/data/broken_calibration_sites/calibrations/fit_32px.yaml
err=$("$build/bin/camera_proc" --config "$source/config/sites/demo_room.yaml" \
  --calibration "$bad_fit" --check 2>&1 >/dev/null)
rc=$?
if ((rc != 1)) || [[ "$err" != "camera_proc: $bad_fit: fit_rms_px: the fit's RMS residual 32.4 px is over the 2 px tolerance"* ]]; then
  echo "FAIL: camera_proc with $bad_fit: exit $rc, stderr '$err'"; failures=$((failures + 1))
else
  echo "ok: $err"
fi
exit $((failures > 0))
