#!/usr/bin/env bash
# The estimator experiments of issue 39 (docs/experiments.md, "Where do the steps go on the v2
# scenes?"): npfkct with one change of its value estimate or belief per row, beside the references
# (oracle, oracle-cover-unknown, nbv, kct), on the 30 v2 tuning scenes (npfkct-scenegen --version
# 2, seeds 850001-850030; the held-out v2 set is 930001-930060), 3 trials per scene, 0.25 s of the
# planning thread's CPU time per step, success within 50 steps. The table gives each row's share
# of the oracle's reward, its target-only share, steps and success, and the changes against the
# row "defaults" paired over the scenes (mean ± 95% t interval over the scenes).
# Resumable: one file per row and scene, bench/results/estimator-v2/RUN/ROW/SEED.jsonl; finished
# cells are skipped; --commit commits each. About 10 CPU-minutes per npfkct row.
# With TRACE=1, each row's trials instead go to one npfkct-bench --trace file, gzipped,
# bench/results/estimator-v2/RUN/ROW.trace.gz (skipped when it exists), for
# `results_table.py steps`: where each row's steps go (moves, declarations, removals).
# Usage: bench/bench_estimator.sh [--run NAME] [--cpu-ms MS] [--trials N] [--commit]
#        env: SEEDS (default: 850001 ... 850030), ROWS (default: every row below), BUILD_DIR,
#        TRACE
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_bench_args 250 3 16 "$@"
npfkct_prepare npfkct-bench npfkct-scenegen
SEEDS="${SEEDS:-$(seq 850001 850030)}"
DEFAULT_ROWS="oracle oracle-cover-unknown nbv kct defaults depth30 rollout-clear r-co-0"
DEFAULT_ROWS="$DEFAULT_ROWS target-only obstacle-covers grid-free-3 grid-odds reuse rollout-first"
DEFAULT_ROWS="$DEFAULT_ROWS regression uniform-final covers covers-grid-free-3 filter-exact"
ROWS="${ROWS:-$DEFAULT_ROWS}"
OUT="$NPFKCT_ROOT/bench/results/estimator-v2/$RUN"
export SCENE_VERSION=2
# shellcheck disable=SC2086  # one seed per word
npfkct_generate_scenes "$BUILD_DIR/tuning-scenes-v2" $SEEDS
TUNING_SCENES=("${SCENE_FILES[@]}")
# SCENE_FILES: the tuning scenes with the robot's grid update for a seen free cell at -3;
# SCENE_PARAMS: those scene parameters, which the row's cells then name.
grid_free_3_scenes() {
  SCENE_PARAMS='{"gridFreeDelta": -3.0}'
  mkdir -p "$BUILD_DIR/tuning-scenes-v2-grid3"
  SCENE_FILES=()
  for file in "${TUNING_SCENES[@]}"; do
    python3 -c "import json,sys; d=json.load(open(sys.argv[1])); \
d['params']=json.loads(sys.argv[3]); json.dump(d, open(sys.argv[2], 'w'))" \
      "$file" "$BUILD_DIR/tuning-scenes-v2-grid3/$(basename "$file")" "$SCENE_PARAMS"
    SCENE_FILES+=("$BUILD_DIR/tuning-scenes-v2-grid3/$(basename "$file")")
  done
}
for row in $ROWS; do
  SCENE_FILES=("${TUNING_SCENES[@]}")
  SCENE_PARAMS=""
  case "$row" in
    oracle | oracle-cover-unknown | nbv | kct) ARGS=(--planner "$row") ;;
    defaults) ARGS=(--planner npfkct) ;;
    depth30) ARGS=(--planner npfkct --opt search.max_depth=30) ;;
    rollout-clear) ARGS=(--planner npfkct --rollout clear) ;;
    r-co-0) ARGS=(--planner npfkct --plan-r-co 0) ;;
    target-only) ARGS=(--planner npfkct --opt search.max_depth=30 --rollout clear --plan-r-co 0) ;;
    obstacle-covers) ARGS=(--planner npfkct --rollout clear --obstacle-reward covers) ;;
    # R_co in planning only for declaring what hides the particle's guessed target (the world
    # still pays R_co for every obstacle): no steps spent collecting declarations.
    covers) ARGS=(--planner npfkct --obstacle-reward covers) ;;
    grid-odds) ARGS=(--planner npfkct --grid-sampling odds) ;;
    reuse) ARGS=(--planner npfkct --opt search.reuse_tree=1) ;;
    rollout-first) ARGS=(--planner npfkct --opt search.rollout_first=1) ;;
    # The regressed final action, kCT's default since it was measured (the rows above ran before).
    regression) ARGS=(--planner npfkct --opt final_action=2 --opt regression_reach=20 --opt regression_trust=10) ;;
    uniform-final) ARGS=(--planner npfkct --opt final_action=0) ;;
    # The filter's ceiling: Net_sam ranking the proposals by g computed exactly, as a network
    # without error would. If it does not beat kct, no filter trained on g can.
    filter-exact) ARGS=(--planner npfkct --opt filter.exact=1) ;;
    grid-free-3)
      # The same scenes with the robot's grid update for a seen free cell at -3 instead of -1.
      grid_free_3_scenes
      ARGS=(--planner npfkct) ;;
    covers-grid-free-3)
      # covers, so that no steps go to declarations collected for R_co, with grid-free-3, so that
      # seen cells give up their mass and what is left lies beneath the boxes: clearing a box is
      # then worth more than one more view, where with covers alone the search kept viewing.
      grid_free_3_scenes
      ARGS=(--planner npfkct --obstacle-reward covers) ;;
    *) echo "bench_estimator.sh: unknown row $row" >&2; exit 2 ;;
  esac
  if [ "${TRACE:-0}" = 1 ]; then
    trace="$OUT/$row.trace"
    [ -s "$trace.gz" ] && { echo "done already: ${trace#"$NPFKCT_ROOT"/}.gz" >&2; continue; }
    mkdir -p "$OUT"
    echo "running: ${trace#"$NPFKCT_ROOT"/}" >&2
    : >"$trace.tmp"
    for file in "${SCENE_FILES[@]}"; do
      "$BUILD_DIR/bin/npfkct-bench" --scenario "$file" "${ARGS[@]}" --trials "$TRIALS" \
        --cpu-ms "$CPU_MS" --threads "$(nproc)" --seed 1 --trace 2>>"$trace.tmp" >/dev/null
    done
    mv "$trace.tmp" "$trace"
    gzip -9f "$trace"
    continue
  fi
  npfkct_bench_row "$OUT/$row" "${ARGS[@]}"
  if [ -n "$SCENE_PARAMS" ]; then
    # Each cell names the scene parameters its row changed (the bench line does not).
    for cell in "$OUT/$row"/*.jsonl; do
      python3 -c "import json,sys; d=json.loads(open(sys.argv[1]).readline()); \
d['scene_params']=json.loads(sys.argv[2]); open(sys.argv[1],'w').write(json.dumps(d)+chr(10))" \
        "$cell" "$SCENE_PARAMS"
    done
  fi
done
if [ "${TRACE:-0}" = 1 ]; then
  python3 "$NPFKCT_ROOT/bench/results_table.py" steps "$OUT" "$BUILD_DIR/tuning-scenes-v2" |
    tee "$OUT/steps.md"
  exit 0
fi
python3 "$NPFKCT_ROOT/bench/results_table.py" estimator "$OUT" "$BUILD_DIR/tuning-scenes-v2" |
  tee "$OUT/estimator.md"
