#!/usr/bin/env bash
# Installs the Debian 12 packages roomfix needs to build, test and run.
# Idempotent and silent when nothing is missing; uses apt-get as root or
# through sudo. Usage: scripts/install_deps.sh [--check]  (--check only lists
# what is missing and exits 1 if anything is).
set -euo pipefail

packages=(
  build-essential cmake pkg-config git
  dpkg-dev file
  liblcm-dev liblcm-bin liblcm-java libjchart2d-java default-jdk-headless
  libopencv-dev libjpeg62-turbo-dev zlib1g-dev libgsl-dev libeigen3-dev libserialport-dev
  libyaml-cpp-dev libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev libssl-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  gnuplot-nox iproute2 util-linux procps xvfb xauth x11-apps
)

missing=()
for p in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${db:Status-Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "installed" ]] || missing+=("$p")
done
((${#missing[@]} == 0)) && exit 0

if [[ "${1:-}" == "--check" ]]; then
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
