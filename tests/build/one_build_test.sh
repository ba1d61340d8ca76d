#!/usr/bin/env bash
# `make demo` then `make test` compile each file once (issue #32): the
# second command may add files (the tests, Google Benchmark's bench micro)
# but must not recompile any file the first one built.
#
# A new build folder is configured by the Makefile's own targets, as on a
# fresh machine that has only the demo's packages: `make configure-demo`
# (what `make demo` runs) with the test-only packages hidden from CMake
# (GoogleTest, Google Benchmark, the JDK: CMAKE_DISABLE_FIND_PACKAGE_*), then
# a few of the demo's objects are built, then `make configure-test` (what
# `make test` runs, with those packages back) reconfigures it. Checked:
#  1. make, dry run (-n), would compile none of the objects built before;
#  2. every file the demo configuration compiles has the same compile command
#     after the reconfigure (compile_commands.json), so no other object of
#     the demo would be rebuilt either (make rebuilds a target's objects when
#     its flags change);
#  3. the reconfigure did turn the test-only parts on (the tests and bench
#     micro are compiled), so checks 1 and 2 compared the two real settings.
# It prints how many files each configuration compiles (the figures the
# README quotes).
#   one_build_test.sh SOURCE_DIR
set -uo pipefail
source_dir=$1
skip=77
# Run from `make test`, ctest inherits the outer make's flags and command-line
# variables (MAKEFLAGS); the Makefile is run here as a user would run it.
unset MAKEFLAGS MFLAGS MAKELEVEL
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# The Makefile installs missing packages first; here nothing may be installed.
if ! missing=$("$source_dir/scripts/install_deps.sh" --check all); then
  echo "SKIP: $missing (make's configure step would install them)"
  exit $skip
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
build=$work/build
hidden=(GTest benchmark Java)
disable() {  # ON|OFF: the CMAKE_ARGS that hide (ON) or show the test packages
  local args=() p
  for p in "${hidden[@]}"; do args+=("-DCMAKE_DISABLE_FIND_PACKAGE_$p=$1"); done
  echo "${args[*]}"
}
configure() {  # make target, ON|OFF
  if ! out=$(make -s -C "$source_dir" "$1" BUILD_DIR="$build" CMAKE_ARGS="$(disable "$2")" 2>&1); then
    echo "FAIL: make $1: $out"; exit 1
  fi
  cp "$build/compile_commands.json" "$work/$1.json"
}

configure configure-demo ON
# A few objects of the demo: the tool (whose flags Google Benchmark changed),
# a library and a program that include the generated message headers.
objects=(tools/version_command.cc.o zigbee_bridge/bridge_node.cc.o zigbee_bridge/zigbee_bridge_main.cc.o)
if ! out=$(make -s -C "$build" roomfix_lcmtypes_gen 2>&1); then fail "lcm-gen: $out"; fi
for o in "${objects[@]}"; do
  if ! out=$(make -s -C "$build/$(dirname "$o")" "$(basename "$o")" 2>&1); then
    fail "make $o: $out"
  fi
done
built=$(find "$build" -name '*.cc.o' | wc -l)
((built == ${#objects[@]})) || fail "built $built objects, expected ${#objects[@]}"

configure configure-test OFF
for o in "${objects[@]}"; do
  plan=$(make -n -C "$build/$(dirname "$o")" "$(basename "$o")" 2>&1)
  # A compile is the compiler called with `-c <source>`.
  if grep -qE -- ' -c [^ ]+\.cc( |$)' <<<"$plan"; then
    fail "after the reconfigure make would recompile $o: $(grep -E -- ' -c ' <<<"$plan")"
  fi
done

python3 - "$work/configure-demo.json" "$work/configure-test.json" <<'PY' || failures=$((failures + 1))
import json, sys
demo = {e["file"]: e["command"] for e in json.load(open(sys.argv[1]))}
test = {e["file"]: e["command"] for e in json.load(open(sys.argv[2]))}
# A file the test configuration no longer compiles (bench_micro_absent.cc,
# replaced by bench_micro.cc) is not rebuilt; one it compiles differently is.
changed = sorted(f for f in demo if f in test and test[f] != demo[f])
for f in changed:
    print(f"FAIL: {f}: compile command changed\n  demo: {demo[f]}\n  test: {test[f]}")
new = [f for f in test if f not in demo]
if not any(f.endswith("_test.cc") for f in new) or not any(f.endswith("/bench_micro.cc") for f in new):
    print("FAIL: the test configuration compiles no test or no bench_micro.cc: "
          "the reconfigure did not turn the test packages on")
    sys.exit(1)
kept = len(test) - len(new)
print(f"make demo compiles {len(demo)} files; make test's build {len(test)}: {kept} of the "
      f"demo's, unchanged (not recompiled), and {len(new)} more")
sys.exit(1 if changed else 0)
PY

if ((failures)); then
  echo "$failures failures"; exit 1
fi
echo "ok: after make test's reconfigure, none of the ${#objects[@]} demo objects built would be recompiled"
