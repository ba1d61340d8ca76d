#!/usr/bin/env bash
# The Java jar of the LCM types exists, holds a class per type, and lcm-spy's
# own type database resolves every top-level type's fingerprint (as computed
# by the C++ headers) to the right class, then decodes a recorded log.
#   lcmtypes_jar_test.sh BUILD_DIR SOURCE_DIR CHECKER_CLASS_DIR
set -euo pipefail
build=$1 source=$2 checker=$3
jar=$build/share/java/roomfix-lcmtypes.jar
[[ -f "$jar" ]] || { echo "FAIL: $jar missing"; exit 1; }

listing=$(jar tf "$jar")
for t in counter_t detector_view_request_t detector_view_robot_t detector_view_t image_t marker_t marker_pixels_t pose2d_t process_status_t range_t range_set_t \
    site_file_t site_t; do
  grep -qx "roomfix/$t.class" <<<"$listing" || { echo "FAIL: roomfix/$t.class not in the jar"; exit 1; }
done
echo "ok: the jar holds a class per type"

# "  roomfix.pose2d_t fingerprint 0x..." -> "roomfix.pose2d_t=0x..."
mapfile -t pairs < <("$build/bin/roomfix" version | awk '/fingerprint/ {print $1 "=" $3}')
((${#pairs[@]} == 8)) || { echo "FAIL: roomfix version listed ${#pairs[@]} types, not 8"; exit 1; }

cp=$(ROOMFIX_BUILD_DIR=$build "$source/scripts/spy" --print-classpath)
java -Djava.awt.headless=true -cp "$cp:$checker" LcmTypeCheck "${pairs[@]}" \
  "--log=$source/tests/data/ground_truth_sample.lcm" "--log=$source/tests/data/site_sample.lcm"
