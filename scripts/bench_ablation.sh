#!/usr/bin/env bash
# The ablation table of the README: NPF-kCT from the paper's algorithm to the shipped planner, one
# change per row, each row keeping the changes above it, on the paper's six scenes at Table 1's
# protocol (1 s of the planning thread's CPU time per step, the same trial seeds; TRIALS per
# cell, 20 by default). Resumable like scripts/bench_table1.sh: one file per row and scene,
# bench/results/ablation/RUN/ROW/SCENE.jsonl; finished cells are skipped; --commit commits each.
# The rows (npfkct-bench planner and options):
#   paper        kct with the paper's choices: uniform candidates, executed points uniform in the
#                sphere, the highest Qhat at the root, Qhat over the reward range, w2 = 0.5
#   aimed        + candidates aimed at what is left to see (object_search/proposals.h)
#   candidates   + Action_sam draws among the candidates a sphere covers
#   sibling      + Qhat normalised over the node's siblings
#   visits       + the most visited root sphere is executed
#   w2-rule      + w2 by appendix J's rule from this step's initial radii (= the kct planner)
#   filter       + the neural filter (= the npfkct planner)
# Usage: scripts/bench_ablation.sh [--run NAME] [--cpu-ms MS] [--trials N] [--commit]
#        env: SCENES, ROWS (default: all, in order), BUILD_DIR
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_bench_args 1000 20 19 "$@"
npfkct_prepare npfkct-bench
SCENES="${SCENES:-loose1 loose2 hidden1 covered1 complex1 fig16}"
ROWS="${ROWS:-paper aimed candidates sibling visits w2-rule filter}"
PAPER="proposals.aimed=0 sample_candidates=0 final_choice=0 normalization=1 w2=0.5"
row_args() {
  local opts planner=kct
  case "$1" in
    paper) opts="$PAPER" ;;
    aimed) opts="${PAPER/proposals.aimed=0/proposals.aimed=1}" ;;
    candidates) opts="proposals.aimed=1 sample_candidates=1 final_choice=0 normalization=1 w2=0.5" ;;
    sibling) opts="proposals.aimed=1 sample_candidates=1 final_choice=0 normalization=2 w2=0.5" ;;
    visits) opts="proposals.aimed=1 sample_candidates=1 final_choice=1 normalization=2 w2=0.5" ;;
    w2-rule) opts="" ;;
    filter) opts="" planner=npfkct ;;
    *) echo "bench_ablation.sh: unknown row $1" >&2; exit 2 ;;
  esac
  ARGS=(--planner "$planner")
  for o in $opts; do ARGS+=(--opt "$o"); done
}
OUT="$NPFKCT_ROOT/bench/results/ablation/$RUN"
for row in $ROWS; do
  row_args "$row"
  for scene in $SCENES; do
    npfkct_bench_cell "$OUT/$row/$scene.jsonl" "$TRIALS" \
      --scenario "$NPFKCT_ROOT/scenarios/data/$scene.json" "${ARGS[@]}" \
      --trials "$TRIALS" --cpu-ms "$CPU_MS" --threads "$(nproc)" --seed 1
  done
done
python3 "$NPFKCT_ROOT/scripts/results_table.py" ablation "$OUT" | tee "$OUT/ablation.md"
