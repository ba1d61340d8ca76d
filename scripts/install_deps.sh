#!/usr/bin/env bash
# Installs the Debian 12 packages roomfix needs. Idempotent and silent when
# nothing is missing; uses apt-get as root or through sudo.
#
#   scripts/install_deps.sh [--check] [demo|all]
#
#   demo  only what `make demo`'s programs need to build and run: the compiler,
#         CMake, the libraries the eight programs link, gnuplot for the
#         report's figures, ip and unshare for the private network namespace.
#         No GoogleTest, Google Benchmark, JDK or X server.
#   all   (the default) everything for `make test` and `make package` too.
#   --check  only lists what is missing and exits 1 if anything is.
set -euo pipefail

set_name=all
check=0
# `firmware` adds the AVR toolchain and simavr to the demo set
# (make demo DEMO_DEVICES=firmware); `all` has them anyway.
with_firmware=0
for arg in "$@"; do
  case "$arg" in
    --check) check=1 ;;
    demo | all) set_name=$arg ;;
    firmware) with_firmware=1 ;;
    *)
      echo "usage: install_deps.sh [--check] [demo|all] [firmware]" >&2
      exit 2
      ;;
  esac
done

# The demo's programs (CMake target `demo`): every find_package they reach,
# plus what scripts/demo.sh runs besides them.
demo_packages=(
  build-essential cmake pkg-config
  liblcm-dev liblcm-bin
  libopencv-dev libjpeg62-turbo-dev libgsl-dev libeigen3-dev libserialport-dev
  libyaml-cpp-dev libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev libssl-dev
  gnuplot-nox iproute2 util-linux
)
# The rest of `make test`: the tests and benchmarks, the Java types jar, the
# viewer's window tests under a virtual X server, the Debian package test
# (help2man writes the manual pages, lintian checks the package, man reads them),
# python3-pandas for docs/export.md's pandas example (python.export_pandas),
# and universal-ctags for the size rule (build.long_functions).
test_packages=(
  git dpkg-dev file
  liblcm-java libjchart2d-java default-jdk-headless
  zlib1g-dev libgtest-dev libgmock-dev libbenchmark-dev
  procps xvfb xauth x11-apps
  help2man lintian man-db
  python3-pandas universal-ctags
)
# The devices' firmware (firmware/: avr-gcc, avr-libc) and simavr, which runs
# it in the tests and in roomfix_sim --devices firmware.
firmware_packages=(gcc-avr binutils-avr avr-libc simavr libsimavr-dev)
packages=("${demo_packages[@]}")
[[ "$set_name" == all || $with_firmware == 1 ]] && packages+=("${firmware_packages[@]}")
[[ "$set_name" == demo ]] || packages+=("${test_packages[@]}")

missing=()
for p in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${db:Status-Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "installed" ]] || missing+=("$p")
done
((${#missing[@]} == 0)) && exit 0

if ((check)); then
  echo "missing Debian packages: ${missing[*]}"
  exit 1
fi

if [[ $(id -u) -eq 0 ]]; then
  sudo=()
elif command -v sudo >/dev/null 2>&1; then
  sudo=(sudo)
else
  echo "install_deps: missing packages (${missing[*]}) and neither root nor sudo;" \
       "run: apt-get install ${missing[*]}" >&2
  exit 1
fi

echo "install_deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
# An image may ship with no package lists at all; refresh them once.
"${sudo[@]}" apt-get update -qq
"${sudo[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install_deps: done"
