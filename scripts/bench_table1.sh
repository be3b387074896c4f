#!/usr/bin/env bash
# Reproduces the paper's Table 1 on the built-in simulator: every scenario x every planner, 20
# trials each, 1 s of planning per step, success within 50 steps. Writes
# bench/results/table1.jsonl (one JSON object per scenario and planner) and table1.md (the
# Markdown table of the README). One scenario at a time (its results are appended as soon as it
# ends, so an interrupted run keeps what it finished); inside a scenario trials run trial-major,
# so machine noise spreads evenly over the planners. About 2 hours on a 2-core machine.
# Usage: scripts/bench_table1.sh [time_ms] [trials]   (env: PLANNERS, SCENARIOS, BUILD_DIR, OUT)
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_prepare
OUT="${OUT:-$NPFKCT_ROOT/bench/results}"
mkdir -p "$OUT"
D="$NPFKCT_ROOT/scenarios/data"
: >"$OUT/table1.jsonl"
for scenario in ${SCENARIOS:-loose1 loose2 hidden1 covered1 complex1 fig16}; do
  "$BUILD_DIR/scenarios/npfkct-bench" --scenario "$D/$scenario.json" \
    --planner "${PLANNERS:-pomcp,gpomcp,pomcpow,vomcpow,advt,kct}" \
    --trials "${2:-20}" --time-ms "${1:-1000}" --threads "$(nproc)" | tee -a "$OUT/table1.jsonl"
done
python3 "$NPFKCT_ROOT/scripts/results_table.py" "$OUT/table1.jsonl" >"$OUT/table1.md"
cat "$OUT/table1.md"
