#!/usr/bin/env bash
# Simulation speed of the object-search model against an earlier commit: builds that commit's
# npfkct-bench from `git archive` (ccache makes the build cheap), then runs both binaries in turn
# (base, this tree, base, ...) for ROUNDS rounds on the same scenes, planners and seeds with a
# fixed number of simulations per step, one trial at a time. A change that only makes the model
# faster must give the same rewards and steps in every cell (the script fails otherwise); the
# table gives each scene's median simulations per CPU-second of the planning thread, base and
# new, and their ratio (medians over rounds). Writes bench/results/model_speed/{base,new}-rN.jsonl
# and the table (summary.md, by results_table.py model-speed).
# Usage: bench/bench_model_speed.sh BASE_COMMIT [ROUNDS]
#        env: SCENES (scenario files), PLANNERS, SIMS (per step), TRIALS, BUILD_DIR
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
BASE="${1:?usage: bench/bench_model_speed.sh BASE_COMMIT [ROUNDS]}"
ROUNDS="${2:-3}"
npfkct_prepare npfkct-bench npfkct-scenegen
npfkct_generate_scenes "$BUILD_DIR/generated-scenes" 900007 900012 900020 900027
S="$NPFKCT_ROOT/scenarios"
G="$BUILD_DIR/generated-scenes"
SCENES="${SCENES:-$S/covered1.json,$S/complex1.json,$S/fig16.json,$G/gen-900007.json,$G/gen-900012.json,$G/gen-900020.json,$G/gen-900027.json}"
PLANNERS="${PLANNERS:-npfkct,gpomcp,vomcpow}"
BASE_DIR="$BUILD_DIR/model-speed-base"
rm -rf "$BASE_DIR/src"
mkdir -p "$BASE_DIR/src"
git -C "$NPFKCT_ROOT" archive "$BASE" | tar -x -C "$BASE_DIR/src"
cmake -S "$BASE_DIR/src" -B "$BASE_DIR/build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$BASE_DIR/build" --target npfkct-bench -j "$(nproc)" >&2
OUT="$NPFKCT_ROOT/bench/results/model_speed"
mkdir -p "$OUT"
for round in $(seq 1 "$ROUNDS"); do
  for side in base new; do
    if [ "$side" = base ]; then bench="$BASE_DIR/build/bin/npfkct-bench"; else
      bench="$BUILD_DIR/bin/npfkct-bench"; fi
    echo "round $round: $side" >&2
    "$bench" --scenario "$SCENES" --planner "$PLANNERS" --trials "${TRIALS:-2}" \
      --sims "${SIMS:-1000}" --threads 1 --seed 3 >"$OUT/$side-r$round.jsonl"
  done
done
{
  echo "Base $BASE."
  python3 "$NPFKCT_ROOT/bench/results_table.py" model-speed "$OUT"
} | tee "$OUT/summary.md"
