#!/usr/bin/env bash
# Thread scaling of NPF-kCT (search.threads: independent trees over the same belief and initial
# spheres, root statistics merged): the same planner with 1 and 2 search threads at the same
# wall-clock budget per step (1 s), trials one after the other so that the search threads have
# the machine's cores. Reports simulations per wall second (median over steps) and rewards. Wall
# time is the point here, so run it on an otherwise idle machine. Writes
# bench/results/threads/PLANNER-tN.jsonl.
# Usage: bench/bench_threads.sh [trials]   (env: SCENES, PLANNER, TIME_MS, BUILD_DIR)
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_prepare npfkct-bench
TRIALS="${1:-10}"
PLANNER="${PLANNER:-npfkct}"
OUT="$NPFKCT_ROOT/bench/results/threads"
mkdir -p "$OUT"
SCENARIOS=""
for scene in ${SCENES:-loose1 covered1 complex1}; do
  SCENARIOS="$SCENARIOS${SCENARIOS:+,}$NPFKCT_ROOT/scenarios/$scene.json"
done
for threads in 1 2; do
  "$BUILD_DIR/bin/npfkct-bench" --scenario "$SCENARIOS" --planner "$PLANNER" \
    --opt "search.threads=$threads" --trials "$TRIALS" --time-ms "${TIME_MS:-1000}" --threads 1 \
    --seed 1 | tee "$OUT/$PLANNER-t$threads.jsonl"
done
python3 "$NPFKCT_ROOT/bench/results_table.py" threads "$OUT/$PLANNER-t1.jsonl" \
  "$OUT/$PLANNER-t2.jsonl"
