#!/usr/bin/env bash
# Builds npfkct and runs every test. Usage: scripts/test.sh [build-dir]
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_install_deps
BUILD_DIR="${1:-$NPFKCT_ROOT/build}"
npfkct_build "$BUILD_DIR"
ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$(nproc)"
