#!/usr/bin/env bash
# The whole test suite on a fresh Debian bookworm machine, as root: install, build, test.
set -euo pipefail
cd "$(dirname "$0")/.."
./deploy/install-deps.sh --test
cmake --preset release
cmake --build --preset release
ctest --preset release
