#!/usr/bin/env bash
# Reproduces the paper's Table 1 on the built-in simulator: every scenario x every planner, 20
# trials each, 1 s of planning per step, success within 50 steps. Writes
# bench/results/table1.jsonl (one JSON object per scenario and planner) and table1.md (the
# Markdown table of the README). Trials run trial-major, so machine noise spreads evenly over the
# planners. About 2 hours on a 2-core machine. Usage: scripts/bench_table1.sh [time_ms] [trials]
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_install_deps
BUILD_DIR="${BUILD_DIR:-$NPFKCT_ROOT/build}"
npfkct_build "$BUILD_DIR" >/dev/null
OUT="${OUT:-$NPFKCT_ROOT/bench/results}"
mkdir -p "$OUT"
D="$NPFKCT_ROOT/scenarios/data"
"$BUILD_DIR/scenarios/npfkct-bench" \
  --scenario "$D/loose1.json,$D/loose2.json,$D/hidden1.json,$D/covered1.json,$D/complex1.json,$D/fig16.json" \
  --planner "${PLANNERS:-pomcp,gpomcp,pomcpow,vomcpow,advt,kct}" \
  --trials "${2:-20}" --time-ms "${1:-1000}" --threads "$(nproc)" \
  --table "$OUT/table1.md" | tee "$OUT/table1.jsonl"
