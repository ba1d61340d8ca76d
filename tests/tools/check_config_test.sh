#!/usr/bin/env bash
# `roomfix check-config` accepts every shipped site file, and gives each
# broken one in tests/data/broken_sites exactly one line on stderr, naming the
# file and the expected problem, with a non-zero exit.
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

for site in "$source"/tests/data/broken_sites/*.yaml; do
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
exit $((failures > 0))
