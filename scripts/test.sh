#!/usr/bin/env bash
# Builds npfkct and runs every test: unit tests, integration tests (real server on loopback,
# Python client, curl, the ROS package with roscore, schemas, restart, the hostile suite, a fleet of
# replicas with PostgreSQL and nginx, the deploy/ files), then the
# hostile-request tests again against an AddressSanitizer/UBSan build of the server (the
# memory-bomb test runs the Release server under an address-space cap, which ASan cannot run
# under). Usage: scripts/test.sh [build-dir]
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_install_deps
npfkct_install_test_deps
BUILD_DIR="${1:-$NPFKCT_ROOT/build}"
# With the PostgreSQL session store, which the fleet tests need (never silently left out).
npfkct_build "$BUILD_DIR" -DNPFKCT_WITH_POSTGRESQL=ON
ctest --test-dir "$BUILD_DIR" --output-on-failure -j 2

# The robustness and hostile tests again, against the server built with AddressSanitizer and
# UBSan.
ASAN_DIR="$BUILD_DIR-asan"
cmake -S "$NPFKCT_ROOT" -B "$ASAN_DIR" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DNPFKCT_SANITIZE=ON \
  -DNPFKCT_BUILD_TESTS=OFF >/dev/null
cmake --build "$ASAN_DIR" -j "$(nproc)" --target npfkct-server
ASAN_OPTIONS=abort_on_error=1:detect_leaks=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
  NPFKCT_BUILD_DIR="$BUILD_DIR" NPFKCT_SERVER_BIN="$ASAN_DIR/bin/npfkct-server" \
  NPFKCT_RELEASE_SERVER_BIN="$BUILD_DIR/bin/npfkct-server" \
  /usr/bin/python3 -m pytest -q -p no:cacheprovider "$NPFKCT_ROOT/tests/test_robustness.py" \
  "$NPFKCT_ROOT/tests/test_hostile.py"
