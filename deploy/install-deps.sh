#!/usr/bin/env bash
# Installs what rankslam needs on Debian bookworm, as root. With --test, also what the test
# suite needs (test-only peers and oracles, the real-kernel test machinery).
set -euo pipefail

build_packages=(
  build-essential cmake ninja-build pkg-config file
  libeigen3-dev libopencv-dev libceres-dev libsuitesparse-dev libopenni2-dev
  libnanoflann-dev libcli11-dev libyaml-cpp-dev libsystemd-dev zlib1g-dev libhwy-dev
)
test_packages=(
  libgtest-dev libgmock-dev libbenchmark-dev libopencv-contrib-dev libpcl-dev
  qemu-system-x86 busybox-static can-utils iproute2
  clang-14 libclang-rt-14-dev
)

packages=("${build_packages[@]}")
if [[ "${1:-}" == "--test" ]]; then
  packages+=("${test_packages[@]}")
fi

export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${packages[@]}"
