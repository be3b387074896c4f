#!/usr/bin/env bash
# Builds npfkct and runs every test, by ctest label: unit (GoogleTest beside each module),
# integration (real server on loopback, Python client, curl, the ROS package with roscore,
# schemas, restart, the hostile suite, the web console, the quick start), fleet (replicas with
# PostgreSQL and nginx, the deploy/ files), then asan: the hostile-request tests again against an
# AddressSanitizer/UBSan build of the server (the memory-bomb test runs the Release server under
# an address-space cap, which ASan cannot run under). Usage: scripts/test.sh [build-dir]
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_install_deps
npfkct_install_test_deps
BUILD_DIR="${1:-$NPFKCT_ROOT/build}"
# With the PostgreSQL session store, which the fleet tests need (never silently left out).
npfkct_build "$BUILD_DIR" -DNPFKCT_WITH_POSTGRESQL=ON -DNPFKCT_ASAN_SERVER=
# Labels unit, integration and fleet.
ctest --test-dir "$BUILD_DIR" --output-on-failure -j 2 -LE asan

# Label asan: the robustness and hostile tests again, against the server built with
# AddressSanitizer and UBSan.
ASAN_DIR="$BUILD_DIR-asan"
cmake -S "$NPFKCT_ROOT" -B "$ASAN_DIR" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DNPFKCT_SANITIZE=ON \
  -DNPFKCT_BUILD_TESTS=OFF >/dev/null
cmake --build "$ASAN_DIR" -j "$(nproc)" --target npfkct-server
cmake -S "$NPFKCT_ROOT" -B "$BUILD_DIR" -DNPFKCT_ASAN_SERVER="$ASAN_DIR/bin/npfkct-server" >/dev/null
ctest --test-dir "$BUILD_DIR" --output-on-failure -L asan
