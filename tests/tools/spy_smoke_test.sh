#!/usr/bin/env bash
# scripts/spy starts lcm-spy (under a virtual X display) and it keeps running:
# Debian's own lcm-spy wrapper dies at once on Java 17 (-Xincgc).
#   spy_smoke_test.sh SOURCE_DIR BUILD_DIR
set -uo pipefail
source=$1 build=$2
if ! command -v xvfb-run >/dev/null; then
  echo "xvfb-run not installed; skipping"
  exit 77
fi
log=$(mktemp)
trap 'rm -f "$log"' EXIT
ROOMFIX_BUILD_DIR=$build timeout 8 xvfb-run -a "$source/scripts/spy" --lcm-url=memq:// >"$log" 2>&1
rc=$?
if ((rc != 124)); then
  echo "FAIL: lcm-spy exited with $rc before the time-out:"
  cat "$log"
  exit 1
fi
if grep -E 'Exception|Error:' "$log"; then
  echo "FAIL: lcm-spy printed an error"
  exit 1
fi
# Still running at the time-out proves nothing by itself (a wrapper that
# hangs before lcm-spy starts runs out the clock too): lcm-spy must have
# started and found every roomfix type on its class path, one per .lcm file.
types=$(find "$source/lcmtypes" -name '*.lcm' | wc -l)
if ! grep -qx "Found $types LCM types" "$log"; then
  echo "FAIL: lcm-spy did not say 'Found $types LCM types' (the roomfix jar's types):"
  cat "$log"
  exit 1
fi
echo "ok: lcm-spy ran for 8 s and found the $types roomfix types on its class path"
