#!/usr/bin/env bash
# The Debian package as a lab would get it, without installing anything on
# this machine: unpacked with dpkg-deb -x into a temporary root, then
#  - every program there links system libraries only (no RPATH/RUNPATH, ldd
#    resolves everything with no LD_LIBRARY_PATH), answers --help, and finds
#    roomfix's data under the unpacked prefix, not the current folder;
#  - `roomfix check-config` accepts the packaged demo site;
#  - the headers, .lcm files and CMake package build and run a small program
#    of another lab (tests/install/consumer) through find_package(roomfix);
#  - the Python types are in /usr/lib/python3/dist-packages/roomfix and
#    Debian's python3 imports and decodes with them;
#  - every package the .deb Depends on exists in Debian 12 at a version that
#    satisfies it (this machine's dpkg database, then its apt lists);
#  - with the Java jar (ROOMFIX_JAVA), the package lists /usr/bin/roomfix-spy
#    (scripts/spy) and the jar, and roomfix-spy uses the jar unpacked beside it.
#  - the licence: /usr/share/doc/roomfix/copyright is a DEP-5 file naming
#    GPL-3+, changelog.gz is gzip without a timestamp whose latest entry is
#    this version, and (MAN_PAGES ON) every program in /usr/bin has its
#    manual page, which man can format.
#   deb_test.sh PACKAGE_DIR VERSION SOURCE_DIR JAVA(ON|OFF) MAN_PAGES(ON|OFF)
set -uo pipefail
package_dir=$1 version=$2 source=$3 java=${4:-OFF} man_pages=${5:-OFF}
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

arch=$(dpkg --print-architecture)
deb=$package_dir/roomfix_${version}_${arch}.deb
[[ -f "$deb" ]] || { echo "FAIL: $deb not built (install.package makes it)"; exit 1; }
root=$(mktemp -d)
trap 'rm -rf "$root"' EXIT
dpkg-deb -x "$deb" "$root/tree" || { echo "FAIL: dpkg-deb -x $deb"; exit 1; }
prefix=$root/tree/usr
elsewhere=$root/cwd
mkdir -p "$elsewhere"
cd "$elsewhere" || exit 1

programs=(camera_proc trilat_proc fusion_proc zigbee_bridge roomfix_logger roomfix_viewer
  roomfix_sim roomfix roomfix_bench)
for p in "${programs[@]}"; do
  bin=$prefix/bin/$p
  if [[ ! -x "$bin" ]]; then fail "$p is not in the package"; continue; fi
  # Captured first: under pipefail `readelf | grep -q` fails when grep's
  # early exit kills readelf with SIGPIPE.
  dynamic=$(readelf -d "$bin")
  if grep -qE 'R(UN)?PATH' <<<"$dynamic"; then
    fail "$p has an RPATH/RUNPATH: $(grep -E 'R(UN)?PATH' <<<"$dynamic")"
  fi
  libs=$(ldd "$bin")
  if grep -q 'not found' <<<"$libs"; then
    fail "$p: libraries not found: $(grep 'not found' <<<"$libs" | tr -s ' \t' ' ')"
  fi
  if ! help=$(env -u LD_LIBRARY_PATH "$bin" --help 2>&1) || [[ "$help" != *"$p"* ]]; then
    fail "$p --help: $help"
  fi
done
scripts=()
[[ "$java" == ON ]] && scripts=(roomfix-spy)
extra=$(cd "$prefix/bin" && ls | grep -vxF -f <(printf '%s\n' "${programs[@]}" "${scripts[@]}"))
[[ -z "$extra" ]] || fail "programs packaged but not checked here: $extra"

# The package's own listing (dpkg-deb -c: "-rwxr-xr-x root/root ... ./usr/bin/x").
contents=$(dpkg-deb -c "$deb")
if [[ "$java" == ON ]]; then
  for f in ./usr/bin/roomfix-spy "./usr/share/java/roomfix-lcmtypes-$version.jar"; do
    grep -qF " $f" <<<"$contents" || fail "$f is not listed by dpkg-deb -c"
  done
  # Java policy: the versioned jar, and the name class paths use as a link to it.
  link=$(readlink "$prefix/share/java/roomfix-lcmtypes.jar")
  [[ "$link" == "roomfix-lcmtypes-$version.jar" ]] ||
    fail "/usr/share/java/roomfix-lcmtypes.jar is not a symlink to roomfix-lcmtypes-$version.jar: '$link'"
  grep -qE '^-rwxr-xr-x .* \./usr/bin/roomfix-spy$' <<<"$contents" ||
    fail "/usr/bin/roomfix-spy is not executable: $(grep roomfix-spy <<<"$contents")"
  # Started from the unpacked tree, it must find that tree's jar, not a build's.
  if ! cp=$(env -u ROOMFIX_BUILD_DIR "$prefix/bin/roomfix-spy" --print-classpath 2>&1) ||
    [[ ":$cp:" != *":$prefix/share/java/roomfix-lcmtypes.jar:"* ]]; then
    fail "roomfix-spy --print-classpath does not name the packaged jar: $cp"
  fi
elif grep -q roomfix-spy <<<"$contents"; then
  fail "roomfix-spy packaged without the jar it needs"
fi

site=$prefix/share/roomfix/config/sites/demo_room.yaml
if ! out=$("$prefix/bin/roomfix" check-config "$site" 2>&1); then
  fail "roomfix check-config on the packaged demo site: $out"
fi
# The default site of `roomfix_bench camera` is the packaged one, whatever
# the current folder (CLI11 prints the default in --help).
bench_help=$("$prefix/bin/roomfix_bench" camera --help)
if ! grep -qF "$site" <<<"$bench_help"; then
  fail "roomfix_bench camera does not default to $site: $(grep -- --site <<<"$bench_help")"
fi

for f in include/roomfix/pose2d_t.hpp share/roomfix/lcmtypes/pose2d_t.lcm \
  share/roomfix/config/calibration/demo_room_camera.yaml share/doc/roomfix/README.md \
  share/doc/roomfix/docs/install.md; do
  [[ -f "$prefix/$f" ]] || fail "/usr/$f is not in the package"
done

# The licence and the changelog (packaging/).
doc=$prefix/share/doc/roomfix
copyright=$(cat "$doc/copyright" 2>/dev/null)
if [[ "$copyright" != "Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/"* ]] ||
  ! grep -qx 'License: GPL-3+' <<<"$copyright"; then
  fail "/usr/share/doc/roomfix/copyright is not a DEP-5 file naming GPL-3+"
fi
# gzip's header: bytes 4-7 are the modification time, 0 with -n.
if ! mtime=$(od -An -tu4 -j4 -N4 "$doc/changelog.gz" 2>/dev/null) || ((mtime != 0)); then
  fail "/usr/share/doc/roomfix/changelog.gz is missing or carries a timestamp (${mtime:-none})"
elif ! head=$(gzip -dc "$doc/changelog.gz" | head -1) || [[ "$head" != "roomfix ($version) "* ]]; then
  fail "changelog.gz's latest entry is not $version: $head"
fi
if [[ "$man_pages" == ON ]]; then
  for p in "${programs[@]}" "${scripts[@]}"; do
    page=$prefix/share/man/man1/$p.1.gz
    if [[ ! -f "$page" ]]; then fail "no manual page $p.1.gz"; continue; fi
    # man formats it without a warning, and its NAME line names the program
    # (a justified line may widen the spaces around the dash).
    if ! text=$(LC_ALL=C.UTF-8 MANWIDTH=80 man --warnings -E UTF-8 -l "$page" 2>"$root/man.err") ||
      [[ -s "$root/man.err" ]] || ! grep -qE "^ +$p +- " <<<"$text"; then
      fail "manual page $p.1.gz: $(cat "$root/man.err") $(head -c 300 <<<"$text")"
    fi
  done
fi

# The Python message types (docs/python.md) where Debian's python3 finds
# them: a module per .lcm file and the package's __init__.py, no bytecode,
# and Debian's own python3 importing them from the unpacked tree and
# decoding with them.
pydist=$prefix/lib/python3/dist-packages
for t in __init__ $(cd "$source/lcmtypes" && ls -- *.lcm | sed 's/\.lcm$//'); do
  [[ -f "$pydist/roomfix/$t.py" ]] || fail "/usr/lib/python3/dist-packages/roomfix/$t.py is not in the package"
done
grep -q __pycache__ <<<"$contents" && fail "the package ships Python bytecode (__pycache__)"
if [[ -x /usr/bin/python3 ]]; then
  debian_path=$(/usr/bin/python3 -c 'import sys; print("\n".join(sys.path))')
  grep -qx /usr/lib/python3/dist-packages <<<"$debian_path" ||
    fail "Debian's python3 does not search /usr/lib/python3/dist-packages: $debian_path"
  if ! py=$(cd "$elsewhere" && PYTHONDONTWRITEBYTECODE=1 PYTHONPATH=$pydist /usr/bin/python3 -c '
import roomfix
p = roomfix.pose2d_t()
p.robot_id, p.x_m = 3, 1.5
q = roomfix.pose2d_t.decode(p.encode())
print(roomfix.__file__, q.robot_id, q.x_m)' 2>&1) || [[ "$py" != "$pydist/roomfix/__init__.py 3 1.5" ]]; then
    fail "python3 with the packaged roomfix types: $py"
  fi
fi

# Another lab's program, built against the unpacked package only.
consumer=$root/consumer
if ! cmake -S "$source/tests/install/consumer" -B "$consumer" -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_FIND_PACKAGE_PREFER_CONFIG=ON >"$root/consumer.log" 2>&1 ||
  ! cmake --build "$consumer" >>"$root/consumer.log" 2>&1; then
  fail "find_package(roomfix) consumer did not build:"; cat "$root/consumer.log"
elif ! grep -q "$(ls "$source"/lcmtypes/*.lcm | wc -l) .lcm files in $prefix/share/roomfix/lcmtypes" "$root/consumer.log"; then
  fail "consumer: ROOMFIX_LCMTYPES_DIR: $(grep roomfix_consumer: "$root/consumer.log")"
elif ! out=$("$consumer/roomfix_consumer"); then
  fail "consumer: $out"
else
  echo "consumer: $out"
fi

# Depends: "a (>= 1), b | c, d". Each clause needs one alternative that this
# machine knows: installed (dpkg-query) or in its Debian 12 apt lists.
satisfied() {  # name [op version]
  local name=$1 op=${2:-} want=${3:-} have
  have=$(dpkg-query -W -f='${Version}\n' "$name" 2>/dev/null | head -1)
  [[ -n "$have" ]] || have=$(apt-cache show "$name" 2>/dev/null | sed -n 's/^Version: //p' | head -1)
  if [[ -z "$have" ]]; then
    # A virtual package (libspdlog1.10-fmt9 is provided by libspdlog1.10):
    # an installed package or one in the apt lists must provide it.
    # (Each list is captured before grep -q reads it: see SIGPIPE above.)
    local provides reverse
    provides=$(dpkg-query -W -f='${Provides}\n' 2>/dev/null | tr ',' '\n')
    grep -qE "^ *$name( |\$)" <<<"$provides" && return 0
    reverse=$(apt-cache showpkg "$name" 2>/dev/null | sed -n '/^Reverse Provides:/,$p' | sed 1d)
    grep -q . <<<"$reverse" && return 0
    return 1
  fi
  [[ -z "$op" ]] && return 0
  case $op in
    '>=') op=ge ;; '<=') op=le ;; '>>') op=gt ;; '<<') op=lt ;; '=') op=eq ;;
  esac
  dpkg --compare-versions "$have" "$op" "$want"
}
depends=$(dpkg-deb -f "$deb" Depends)
[[ -n "$depends" ]] || fail "the package declares no Depends (CPACK_DEBIAN_PACKAGE_SHLIBDEPS)"
checked=0
IFS=',' read -ra clauses <<<"$depends"
for clause in "${clauses[@]}"; do
  ok=0
  IFS='|' read -ra alternatives <<<"$clause"
  for alt in "${alternatives[@]}"; do
    read -r name op want <<<"$(sed -E 's/[()]//g' <<<"$alt")"
    if satisfied "$name" "$op" "$want"; then ok=1; break; fi
  done
  checked=$((checked + 1))
  ((ok)) || fail "Depends: no Debian 12 package satisfies '$clause'"
done
echo "Depends: $checked clauses checked: $depends"

if ((failures)); then
  echo "$failures failures"; exit 1
fi
echo "roomfix_${version}_${arch}.deb: ${#programs[@]} programs, check-config, consumer: ok"
