#!/usr/bin/env bash
# Closed-loop Loose1 and Hidden1 with perception from rendered 640x480 RGB-D frames (the image
# scored by SIFT and colour against the target's photos), from the same frames' depth with a
# simulated YOLO-style detector's 2D boxes (boxes), and with the geometric observation shortcut
# (same planner, trials, seeds, 1 s of the planning thread's CPU time per step), and the
# perception pipeline's time per stage. Writes bench/results/perception.jsonl,
# perception.md and perception_stages.json. Usage: bench/bench_perception.sh [cpu_ms] [trials]
# (env: BUILD_DIR, OUT, PLANNER)
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_prepare npfkct-bench npfkct-perception-bench
OUT="${OUT:-$NPFKCT_ROOT/bench/results}"
mkdir -p "$OUT"
D="$NPFKCT_ROOT/scenarios"
: >"$OUT/perception.jsonl"
for scenario in loose1 hidden1; do
  "$BUILD_DIR/bin/npfkct-bench" --scenario "$D/$scenario.json" \
    --planner "${PLANNER:-kct}" --observe geometric,perception,boxes \
    --trials "${2:-20}" --cpu-ms "${1:-1000}" --threads "$(nproc)" | tee -a "$OUT/perception.jsonl"
done
python3 "$NPFKCT_ROOT/bench/results_table.py" flat "$OUT/perception.jsonl" >"$OUT/perception.md"
cat "$OUT/perception.md"
"$BUILD_DIR/bin/npfkct-perception-bench" | tee "$OUT/perception_stages.json"
