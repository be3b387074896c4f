#!/usr/bin/env bash
# The held-out generated scenes of docs/benchmarks.md: the 30 scenes npfkct-scenegen makes from
# seeds 900001-900030 (no filter training data comes from seeds above 900000), 5 trials per scene
# and planner, 0.25 s of the planning thread's CPU time per step, success within 50 steps. The
# summary gives each planner's mean share of the oracle's reward over the scenes (with a Student's t
# interval over the 30 scene means) and its success rate over all trials, then the same shares per
# placement of the target (in the open, hidden behind tall boxes, covered by a larger box).
# oracle-cover-unknown is a second ceiling: the oracle not told which box covers the target.
#
# Resumable like bench/bench_table1.sh: one file per scene and planner,
# bench/results/generated/RUN/SEED/PLANNER.jsonl; finished cells are skipped; --commit commits
# each cell. About 1.5 CPU-hours (45 minutes on 2 cores at d6ae15f).
# With SCENE_VERSION=2, the v2 held-out set instead (seeds 930001-930060, 20 open, 20 hidden and
# 20 covered: decoy covers, wall pockets, stacked covers, any yaw; docs/benchmarks.md), in
# bench/results/generated-v2/RUN, with nbv among the planners.
# Usage: bench/bench_generated.sh [--run NAME] [--cpu-ms MS] [--trials N] [--commit]
#        env: SCENE_VERSION (1, the default, or 2), SEEDS (default: 900001 ... 900030, or
#        930001 ... 930060 for version 2), PLANNERS, BUILD_DIR, ROLLOUT (the model's rollout policy
#        for every planner: aimed, the default, clear, or greedy, that of run1 and run2),
#        OBSTACLE_REWARD (what the planners' model pays for obstacle declarations: every, the
#        paper's, or covers), OPTS (planner options for every planner, KEY=VALUE separated by
#        spaces, as npfkct-bench --opt takes them). The v2 tuning scenes: SCENE_VERSION=2
#        SEEDS="$(seq 850001 850030)".
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_bench_args 250 5 23 "$@"
npfkct_prepare npfkct-bench npfkct-scenegen
export SCENE_VERSION="${SCENE_VERSION:-1}"
if [[ "$SCENE_VERSION" == 2 ]]; then
  SEEDS="${SEEDS:-$(seq 930001 930060)}"
  PLANNERS="${PLANNERS:-oracle npfkct kct nbv rollout gpomcp}"
  OUT="$NPFKCT_ROOT/bench/results/generated-v2/$RUN"
  SCENES_DIR="$BUILD_DIR/generated-scenes-v2"
else
  SEEDS="${SEEDS:-$(seq 900001 900030)}"
  PLANNERS="${PLANNERS:-oracle oracle-cover-unknown npfkct kct pomcp-joint gpomcp vomcpow}"
  OUT="$NPFKCT_ROOT/bench/results/generated/$RUN"
  SCENES_DIR="$BUILD_DIR/generated-scenes"
fi
# shellcheck disable=SC2086  # one seed per word
npfkct_generate_scenes "$SCENES_DIR" $SEEDS
OPT_ARGS=()
for opt in ${OPTS:-}; do OPT_ARGS+=(--opt "$opt"); done
for scene in "${SCENE_FILES[@]}"; do
  seed="$(basename "$scene" .json)"
  seed="${seed#gen-}"
  for planner in $PLANNERS; do
    npfkct_bench_cell "$OUT/$seed/$planner.jsonl" "$TRIALS" --scenario "$scene" \
      --planner "$planner" --trials "$TRIALS" --cpu-ms "$CPU_MS" --threads "$(nproc)" --seed 1 \
      --rollout "${ROLLOUT:-aimed}" --obstacle-reward "${OBSTACLE_REWARD:-every}" "${OPT_ARGS[@]}"
  done
done
python3 "$NPFKCT_ROOT/bench/results_table.py" generated "$OUT" "$SCENES_DIR" |
  tee "$OUT/summary.md"
