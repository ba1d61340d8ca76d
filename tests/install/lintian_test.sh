#!/usr/bin/env bash
# Debian's own package checker on the .deb that install.package built: no
# error (E:) may remain. Warnings are printed, not failed on: the ones that
# remain, and why, are listed in docs/install.md ("What lintian still says");
# a new warning shows in this test's output. Skipped (exit 77), saying so,
# where lintian is not installed (scripts/install_deps.sh installs it).
#   lintian_test.sh PACKAGE_DIR VERSION
set -uo pipefail
package_dir=$1 version=$2
if ! command -v lintian >/dev/null 2>&1; then
  echo "SKIP: lintian is not installed (apt-get install lintian)"
  exit 77
fi
deb=$package_dir/roomfix_${version}_$(dpkg --print-architecture).deb
[[ -f "$deb" ]] || { echo "FAIL: $deb not built (install.package makes it)"; exit 1; }

# --info prints each tag's explanation with it; --fail-on error: the exit
# status is 0 when no error is reported, 1 when one is, more when lintian
# itself fails. The E: lines are counted too, so that neither verdict hides
# the other.
out=$(lintian --info --no-tag-display-limit --fail-on error "$deb" 2>&1)
status=$?
echo "$out"
errors=$(grep -c '^E: ' <<<"$out")
warnings=$(grep -c '^W: ' <<<"$out")
echo "lintian $(lintian --version | awk '{print $2}') on $(basename "$deb"):" \
  "$errors errors, $warnings warnings (exit status $status)"
if ((errors > 0)); then
  echo "FAIL: lintian reports errors"
  exit 1
fi
if ((status != 0)); then
  echo "FAIL: lintian did not complete (exit status $status)"
  exit 1
fi
