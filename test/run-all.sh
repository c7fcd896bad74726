#!/usr/bin/env bash
# The whole test suite on a fresh Debian bookworm machine, as root: install, build, test; the
# unit tests and the fuzz targets under AddressSanitizer + UBSan, the threaded parts under
# ThreadSanitizer; then the arm64 cross build, its unit tests as arm64 binaries under qemu, and
# the arm64 package.
set -euo pipefail
cd "$(dirname "$0")/.."
./deploy/install-deps.sh --test
cmake --preset release
cmake --build --preset release
ctest --preset release

cmake --preset sanitize
cmake --build --preset sanitize
ctest --preset sanitize
cmake --preset tsan
cmake --build --preset tsan
ctest --preset tsan

./toolchains/make-arm64-sysroot.sh
cmake --preset arm64
cmake --build --preset arm64
ctest --preset arm64
cpack --preset arm64
./deploy/check-package.sh build/arm64/packages/rankslam_*_arm64.deb
