#!/usr/bin/env bash
# Installs every Debian 12 package evpipe needs, and only what is missing.
# Idempotent: a second run installs nothing and prints "nothing to install".
# Usage: tools/setup.sh            (as root, or with sudo available)
set -euo pipefail

# One list for the whole project (build, tests, fuzzing, tooling). Keep sorted by purpose.
PACKAGES=(
  # toolchain
  build-essential cmake ninja-build pkg-config git ca-certificates python3 python3-venv
  clang clang-format clang-tidy libclang-rt-14-dev   # libFuzzer + sanitizer runtimes, format/tidy configs
  # core libraries (design card)
  libeigen3-dev libopencv-dev libceres-dev libflann-dev libnanoflann-dev
  libspdlog-dev libfmt-dev libcli11-dev libyaml-cpp-dev
  liblz4-dev libzstd-dev libflatbuffers-dev flatbuffers-compiler
  libsystemd-dev libusb-1.0-0-dev libglib2.0-dev
  # LCM: C++ library, lcm-gen/lcm-logger/lcm-logplayer, Java for lcm-spy
  liblcm-dev liblcm-bin liblcm-java libjchart2d-java default-jdk-headless
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # operations checks (systemd-analyze verify, multicast route on lo)
  systemd iproute2
  # evpipe-view's end-to-end test and the docs screenshot (a virtual X display)
  xvfb
  # the Debian package and its release check (cpack DEB: dpkg-shlibdeps; tools/check_deb.sh: lintian, debootstrap)
  dpkg-dev fakeroot lintian debootstrap
  # handy for fixtures and benches
  lz4 zstd
)

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "setup.sh: must run as root (or with sudo) to install Debian packages" >&2; exit 1
  fi
fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup.sh: all ${#PACKAGES[@]} packages present, nothing to install"
  exit 0
fi

echo "setup.sh: installing ${#missing[@]} missing package(s): ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "setup.sh: done"
