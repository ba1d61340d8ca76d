#!/usr/bin/env bash
# The installed `roomfix` tool holds the product only (issue #33): none of the
# developer code that roomfix_bench (bench/) links, read from the binary's own
# symbol table (nm -C), so a stray link or a benchmark registered in the tool
# again fails here. The groups and the symbols that stand for them:
#  - the bridge (zigbee_bridge): BridgeNode, SerialLink;
#  - the simulator's devices and processes (sim/): VirtualWallDevices,
#    SharedAir, GroundTruthNode, SimRangesNode, PseudoTerminal, and the
#    firmware simulator (sim/firmware: roomfix::firmware::, FirmwareWorld,
#    AvrCore);
#  - the viewer's renderer (viewer/render.h);
#  - Google Benchmark (benchmark::).
# The synthetic camera (sim/synthetic_camera, roomfix::sim::) is allowed:
# render-camera and grab's `sim:` devices are product commands.
#   product_symbols_test.sh ROOMFIX_BINARY
set -uo pipefail
binary=$1
if ! symbols=$(nm -C "$binary" 2>&1); then
  echo "FAIL: nm -C $binary: $symbols"; exit 1
fi
# A stripped binary would pass vacuously: its own main must be there to read.
if ! grep -qE ' T main$' <<<"$symbols"; then
  echo "FAIL: $binary has no symbol main (stripped?): nothing to check"
  exit 1
fi
declare -A groups=(
  [bridge]='roomfix::(BridgeNode|SerialLink)\b'
  [simulator]='roomfix::(VirtualWallDevices|SharedAir|GroundTruthNode|SimRangesNode|PseudoTerminal)\b|roomfix::firmware::'
  [viewer_renderer]='roomfix::viewer::(Render|MakeFloorMapping)\('
  [google_benchmark]='(^| )benchmark::'
)
failures=0
for group in bridge simulator viewer_renderer google_benchmark; do
  found=$(grep -E -- "${groups[$group]}" <<<"$symbols")
  if [[ -n "$found" ]]; then
    echo "FAIL: $binary links the $group: $(wc -l <<<"$found") symbols, such as"
    head -3 <<<"$found" | sed 's/^/    /'
    failures=$((failures + 1))
  else
    echo "ok: no symbol of the $group"
  fi
done
if ((failures)); then
  echo "$failures of 4 groups linked into $(basename "$binary"): they belong to roomfix_bench (bench/)"
  exit 1
fi
echo "ok: $(basename "$binary") holds none of the bridge, the simulator's devices, the viewer's renderer or Google Benchmark"
