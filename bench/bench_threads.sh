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
python3 - "$OUT/$PLANNER-t1.jsonl" "$OUT/$PLANNER-t2.jsonl" <<'EOF'
import json, sys
one = [json.loads(l) for l in open(sys.argv[1])]
two = [json.loads(l) for l in open(sys.argv[2])]
print("| Scene | sims/s, 1 thread | sims/s, 2 threads | ratio | reward, 1 thread | reward, 2 threads |")
print("|---|---|---|---|---|---|")
for a, b in zip(one, two):
    ratio = b["median_sims_per_second"] / max(a["median_sims_per_second"], 1e-9)
    print(f"| {a['scenario']} | {a['median_sims_per_second']:.0f} | {b['median_sims_per_second']:.0f} "
          f"| {ratio:.2f}x | {a['mean_discounted_reward']:.1f} ± {a['ci95']:.1f} "
          f"| {b['mean_discounted_reward']:.1f} ± {b['ci95']:.1f} |")
EOF
