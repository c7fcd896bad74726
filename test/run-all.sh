#!/usr/bin/env bash
# The whole test suite on a fresh Debian bookworm machine, as root: install, build, test; the
# unit tests and the fuzz targets under AddressSanitizer + UBSan, the threaded parts under
# ThreadSanitizer; then the arm64 cross build, its unit tests as arm64 binaries under qemu, and
# the arm64 package.
set -euo pipefail
cd "$(dirname "$0")/.."
# Each stage's start, in seconds since this script started.
stage() { echo "== run-all: $1 at ${SECONDS} s"; }
stage install
./deploy/install-deps.sh --test
stage release
cmake --preset release
cmake --build --preset release
ctest --preset release

stage sanitize
cmake --preset sanitize
cmake --build --preset sanitize
ctest --preset sanitize
stage tsan
cmake --preset tsan
cmake --build --preset tsan
ctest --preset tsan

stage arm64
./toolchains/make-arm64-sysroot.sh
cmake --preset arm64
cmake --build --preset arm64
ctest --preset arm64
cpack --preset arm64
./deploy/check-package.sh build/arm64/packages/rankslam_*_arm64.deb
stage done
