#!/usr/bin/env bash
# The main job: builds npfkct and runs a short benchmark of every planner on the classic
# problems, one JSON line per run. Usage: scripts/run.sh [build-dir]
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_install_deps
BUILD_DIR="${1:-$NPFKCT_ROOT/build}"
npfkct_build "$BUILD_DIR" >/dev/null
BENCH="$BUILD_DIR/scenarios/npfkct-bench"
THREADS="$(nproc)"
"$BENCH" --problem tiger --planner pomcp --episodes 50 --time-ms 0 --sims 5000 --threads "$THREADS"
"$BENCH" --problem rocksample --planner pomcp --episodes 20 --time-ms 100 --threads "$THREADS"
"$BENCH" --problem lightdark --planner pomcp --episodes 50 --time-ms 50 --threads "$THREADS"
"$BENCH" --problem lightdark --planner pomcpow --episodes 50 --time-ms 50 --threads "$THREADS"
for planner in pomcpow vomcpow advt kct; do
  "$BENCH" --problem vdptag --planner "$planner" --episodes 20 --time-ms 50 --threads "$THREADS"
done
