#!/usr/bin/env bash
# pmd_check.py has no exemptions and its twin check can fail:
# - with fusion_proc missing from the build, the shipped sim_demo.pmd is
#   rejected, naming it (it used to be skipped as "being written");
# - an installed-host file whose command differs from its source-tree twin
#   in more than the data path is rejected.
#   pmd_check_test.sh BUILD_DIR SOURCE_DIR
set -uo pipefail
build=$1 source=$2
check=$source/tests/tools/pmd_check.py
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# A build with every program but fusion_proc.
mkdir -p "$tmp/build/bin"
for f in "$build"/bin/*; do
  [[ $(basename "$f") == fusion_proc ]] || ln -s "$f" "$tmp/build/bin/"
done
out=$("$check" --build "$tmp/build" --source "$source" "$source/config/procman/sim_demo.pmd" 2>&1)
rc=$?
((rc == 1)) || fail "sim_demo.pmd without fusion_proc built: exit $rc, expected 1"
[[ "$out" == *'unknown binary "fusion_proc"'* ]] || fail "no 'unknown binary \"fusion_proc\"' in: $out"
# The same file passes against the real build (the failure above is fusion_proc's).
"$check" --build "$build" --source "$source" "$source/config/procman/sim_demo.pmd" >/dev/null ||
  fail "sim_demo.pmd fails against the full build"

# Twins: a copy of the shipped pair passes; a changed flag in the installed one fails.
mkdir -p "$tmp/procman/installed"
cp "$source/config/procman/single_host.pmd" "$tmp/procman/"
cp "$source/config/procman/installed/single_host.pmd" "$tmp/procman/installed/"
"$check" --build "$build" --source "$source" "$tmp/procman/installed/single_host.pmd" >/dev/null ||
  fail "a copy of the shipped installed/single_host.pmd fails"
sed -i 's/--method robust/--method cauchy/' "$tmp/procman/installed/single_host.pmd"
out=$("$check" --build "$build" --source "$source" "$tmp/procman/installed/single_host.pmd" 2>&1)
rc=$?
((rc == 1)) || fail "an installed file differing from its twin: exit $rc, expected 1"
[[ "$out" == *'command "trilat_proc" differs from its twin'* ]] || fail "no twin difference in: $out"

((failures == 0)) && echo "ok: pmd_check.py rejects a missing fusion_proc and a twin that differs"
exit $((failures > 0))
