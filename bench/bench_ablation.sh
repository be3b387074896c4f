#!/usr/bin/env bash
# The ablation table of docs/benchmarks.md: NPF-kCT from the paper's algorithm to the shipped
# planner, one change per row, each row keeping the changes above it, on the paper's six scenes at
# Table 1's protocol (1 s of the planning thread's CPU time per step, the same trial seeds; TRIALS
# per cell, 20 by default). Resumable like bench/bench_table1.sh: one file per row and scene,
# bench/results/ablation/RUN/ROW/SCENE.jsonl; finished cells are skipped; --commit commits each. The
# rows (npfkct-bench planner and options):
#   paper        kct with the paper's choices: uniform candidates, executed points uniform in the
#                sphere, the highest Qhat at the root, Qhat over the reward range, w2 = 0.5
#   aimed        + candidates aimed at what is left to see (object_search/proposals.h)
#   candidates   + Action_sam draws among the candidates a sphere covers
#   sibling      + Qhat normalised over the node's siblings
#   w2-rule      + w2 by appendix J's rule from this step's initial radii (= the kct planner)
#   filter       + the neural filter (the npfkct planner with the greedy rollout)
#   rollout      + the aimed rollout (half of the rollout's moves look at a grid-world placement
#                that no standing box hides)
#   ensemble     + the filter model an ensemble of three networks (= the npfkct planner)
# Every row above rollout runs with --rollout greedy, the model's rollout before it; the rows
# filter, rollout and lcb use the single network shipped before the ensemble,
# bench/models/filter-single.pt.
# and a change measured and not kept (run only when named in ROWS; results_table.py gives its
# change against the kept row it modifies):
#   visits       sibling with the most visited root sphere executed (instead of the highest Qhat)
#   lcb          filter with the root sphere of the highest lower confidence bound executed,
#                Qhat - 1 standard error of its returns (final_choice=2 final_lcb=1)
# With --generated the rows run on the 30 held-out generated scenes of bench/bench_generated.sh
# at its protocol (0.25 s of CPU per step, 5 trials, run name "generated"), with an oracle row, and
# the table gives each row's share of the oracle's reward and its change against the row above,
# paired over the scenes (results_table.py ablation).
# Usage: bench/bench_ablation.sh [--generated] [--run NAME] [--cpu-ms MS] [--trials N] [--commit]
#        env: SCENES (paper scenes) or SEEDS (with --generated), ROWS (default: the kept rows),
#        BUILD_DIR
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
ROW_NAMES="paper aimed candidates sibling w2-rule filter rollout ensemble"
SINGLE="$NPFKCT_ROOT/bench/models/filter-single.pt"
if [ "${1:-}" = --generated ]; then
  shift
  npfkct_bench_args 250 5 22 --run generated "$@"
  npfkct_prepare npfkct-bench npfkct-scenegen
  # shellcheck disable=SC2086  # one seed per word
  npfkct_generate_scenes "$BUILD_DIR/generated-scenes" ${SEEDS:-$(seq 900001 900030)}
  ROW_NAMES="oracle $ROW_NAMES"
else
  npfkct_bench_args 1000 20 22 "$@"
  npfkct_prepare npfkct-bench
  SCENE_FILES=()
  for scene in ${SCENES:-loose1 loose2 hidden1 covered1 complex1 fig16}; do
    SCENE_FILES+=("$NPFKCT_ROOT/scenarios/$scene.json")
  done
fi
ROWS="${ROWS:-$ROW_NAMES}"
PAPER="proposals.aimed=0 sample_candidates=0 final_choice=0 normalization=1 w2=0.5"
row_args() {
  local opts planner=kct rollout=greedy model=""
  case "$1" in
    paper) opts="$PAPER" ;;
    aimed) opts="${PAPER/proposals.aimed=0/proposals.aimed=1}" ;;
    candidates) opts="proposals.aimed=1 sample_candidates=1 final_choice=0 normalization=1 w2=0.5" ;;
    sibling) opts="proposals.aimed=1 sample_candidates=1 final_choice=0 normalization=2 w2=0.5" ;;
    visits) opts="proposals.aimed=1 sample_candidates=1 final_choice=1 normalization=2 w2=0.5" ;;
    w2-rule) opts="" ;;
    filter) opts="" planner=npfkct model="$SINGLE" ;;
    rollout) opts="" planner=npfkct rollout=aimed model="$SINGLE" ;;
    ensemble) opts="" planner=npfkct rollout=aimed ;;
    lcb) opts="final_choice=2 final_lcb=1" planner=npfkct model="$SINGLE" ;;
    oracle) opts="" planner=oracle ;;
    *) echo "bench_ablation.sh: unknown row $1" >&2; exit 2 ;;
  esac
  # The rows were measured with the executed point drawn in the chosen sphere, before kCT's
  # regressed final action became the default (docs/experiments.md); a rerun keeps that.
  [ "$planner" = oracle ] || opts="$opts final_action=0"
  ARGS=(--planner "$planner" --rollout "$rollout")
  if [ -n "$model" ]; then ARGS+=(--model "$model"); fi
  for o in $opts; do ARGS+=(--opt "$o"); done
}
OUT="$NPFKCT_ROOT/bench/results/ablation/$RUN"
for row in $ROWS; do
  row_args "$row"
  npfkct_bench_row "$OUT/$row" "${ARGS[@]}"
done
python3 "$NPFKCT_ROOT/bench/results_table.py" ablation "$OUT" | tee "$OUT/ablation.md"
