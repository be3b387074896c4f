#!/usr/bin/env bash
# Paper scenes beside their mirror images: the same scene with every object's position mirrored
# across the table's short axis (x -> -x on the table), so that in Hidden1 the row of tall boxes
# stands between the target and the *other* side of the table. Before its first step a planner
# knows only the table, whose four sides look alike, so which side it looks from first is a
# guess; this measures how much of a planner's result is that guess and how much is planning.
# Same protocol as Table 1 (1 s of CPU per step, 20 trials, seed 1). Writes
# bench/results/mirror/SCENE/PLANNER.jsonl, the first step of every trial
# (SCENE/PLANNER.first-views, from --trace) and a table of reward, steps and the trials whose
# first view saw the target (mirror.md).
# Usage: bench/bench_mirror.sh [--cpu-ms MS] [--trials N] [--commit]
#        (env: SCENES, default "hidden1 complex1 covered1"; PLANNERS, default
#        "oracle npfkct kct pomcp-joint gpomcp")
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_bench_args 1000 20 13 "$@"
npfkct_prepare npfkct-bench
OUT="$NPFKCT_ROOT/bench/results/mirror"
SCENES_DIR="$BUILD_DIR/mirror-scenes"
mkdir -p "$OUT" "$SCENES_DIR"
SCENES="${SCENES:-hidden1 complex1 covered1}"
for scene in $SCENES; do
  python3 - "$NPFKCT_ROOT/scenarios/$scene.json" "$SCENES_DIR/$scene-mirrored.json" <<'EOF'
import json, sys
scene = json.load(open(sys.argv[1]))
scene["description"] = scene["name"] + " with the objects mirrored across the table's short axis"
scene["name"] += "-mirrored"
for obj in scene["objects"]:
    if "on" not in obj:
        sys.exit(f"{sys.argv[1]}: object {obj['name']} is not on a piece of furniture")
    obj["position"][0] = -obj["position"][0]
json.dump(scene, open(sys.argv[2], "w"), indent=1)
EOF
done
for scene in $(for s in $SCENES; do echo "$s $s-mirrored"; done); do
  file="$NPFKCT_ROOT/scenarios/$scene.json"
  [[ "$scene" != *-mirrored ]] || file="$SCENES_DIR/$scene.json"
  mkdir -p "$OUT/$scene"
  for planner in ${PLANNERS:-oracle npfkct kct pomcp-joint gpomcp}; do
    # --trace prints every trial's steps; the first view of each trial is summarised below.
    npfkct_bench_cell "$OUT/$scene/$planner.jsonl" "$TRIALS" --scenario "$file" \
      --planner "$planner" --trials "$TRIALS" --cpu-ms "$CPU_MS" --threads "$(nproc)" --seed 1 \
      --trace 2>"$OUT/$scene/$planner.trace.tmp"
    # A cell found done already prints no steps and keeps its first views.
    if grep -q ' step  1: ' "$OUT/$scene/$planner.trace.tmp"; then
      grep ' step  1: ' "$OUT/$scene/$planner.trace.tmp" >"$OUT/$scene/$planner.first-views"
    fi
    grep -v ' step ' "$OUT/$scene/$planner.trace.tmp" >&2 || true
    rm -f "$OUT/$scene/$planner.trace.tmp"
  done
done
python3 "$NPFKCT_ROOT/bench/results_table.py" mirror "$OUT" | tee "$OUT/mirror.md"
