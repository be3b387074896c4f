#!/usr/bin/env bash
# Table 1 of docs/benchmarks.md: every planner on the paper's six scenes, 20 trials per cell, 1 s of
# the planning thread's CPU time per step, success within 50 steps, trials seeded 1000003 + i in
# every cell (the same worlds and noise for every planner).
#
# Resumable: each (scene, planner) cell is one file, bench/results/table1/RUN/SCENE/PLANNER.jsonl,
# and a cell whose file holds a finished run is skipped, so an interrupted run continues where it
# stopped (on this machine or another: CPU-time budgets make cells measured on different machines
# and days comparable). With --commit each finished cell is committed to git at once. The table
# (table1.md, with each planner's reward as a share of the oracle's) is rebuilt at the end.
#
# Besides the registry's planners, PLANNERS may name a preset (a planner run with options, its
# cells named after the preset; npfkct-bench --label):
#   npfkct-paper   the paper's complete NPF-kCT: the neural filter over uniform candidates (no
#                  aimed proposals), the executed point uniform in the sphere, the highest Qhat at
#                  the root, Qhat over the reward range, w2 = 0.5, the random rollout
#
# The full table is several CPU-hours (about 6 on the 2-core machine, i.e. 3 hours of wall time).
# Usage: bench/bench_table1.sh [--run NAME] [--cpu-ms MS] [--trials N] [--commit]
#        env: SCENES (default: the six), PLANNERS (default: every planner), BUILD_DIR
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_bench_args 1000 20 20 "$@"
npfkct_prepare npfkct-bench
SCENES="${SCENES:-loose1 loose2 hidden1 covered1 complex1 fig16}"
PLANNERS="${PLANNERS:-oracle npfkct kct pomcp gpomcp pomcp-joint pomcpow vomcpow advt}"
OUT="$NPFKCT_ROOT/bench/results/table1/$RUN"
planner_args() {
  case "$1" in
    npfkct-paper)
      ARGS=(--planner npfkct --label npfkct-paper --rollout random)
      for o in filter.target_share=0 filter.object_share=0 sample_candidates=0 final_choice=0 \
        final_action=0 normalization=1 w2=0.5; do
        ARGS+=(--opt "$o")
      done ;;
    *) ARGS=(--planner "$1") ;;
  esac
}
for scene in $SCENES; do
  for planner in $PLANNERS; do
    planner_args "$planner"
    npfkct_bench_cell "$OUT/$scene/$planner.jsonl" "$TRIALS" \
      --scenario "$NPFKCT_ROOT/scenarios/$scene.json" "${ARGS[@]}" \
      --trials "$TRIALS" --cpu-ms "$CPU_MS" --threads "$(nproc)" --seed 1
  done
done
python3 "$NPFKCT_ROOT/bench/results_table.py" table1 "$OUT" | tee "$OUT/table1.md"
