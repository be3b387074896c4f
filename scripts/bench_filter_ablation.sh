#!/usr/bin/env bash
# The neural filter's ablation: NPF-kCT with the shipped filter (npfkct: only the candidates the
# filter keeps) against NPF-kCT with uniform candidates (kct), in the same bench process per
# scenario (trials interleaved, same seeds), on every Table 1 scenario at 1 s of CPU per step.
# Writes bench/results/ablation.jsonl and ablation.md. The baselines at the same settings are
# Table 1 (scripts/bench_table1.sh).
# Usage: scripts/bench_filter_ablation.sh [cpu_ms] [trials]  (env: SCENARIOS, BUILD_DIR, OUT, MODEL)
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_prepare
OUT="${OUT:-$NPFKCT_ROOT/bench/results}"
MODEL="${MODEL:-$NPFKCT_ROOT/solver/filter/model/filter.pt}"
mkdir -p "$OUT"
D="$NPFKCT_ROOT/scenarios/data"
: >"$OUT/ablation.jsonl"
for scenario in ${SCENARIOS:-loose1 loose2 hidden1 covered1 complex1 fig16}; do
  "$BUILD_DIR/scenarios/npfkct-bench" --scenario "$D/$scenario.json" --planner "${PLANNERS:-kct,npfkct}" \
    --model "$MODEL" --trials "${2:-20}" --cpu-ms "${1:-1000}" --threads "$(nproc)" |
    tee -a "$OUT/ablation.jsonl"
done
python3 "$NPFKCT_ROOT/scripts/results_table.py" flat "$OUT/ablation.jsonl" >"$OUT/ablation.md"
cat "$OUT/ablation.md"
