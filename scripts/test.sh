#!/usr/bin/env bash
# Sets up (packages + build) and runs the whole test suite. Exit status is
# non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh --with-tests
ctest --test-dir "${BUILD_DIR:-build}" --output-on-failure -j "$(nproc)" "$@"
