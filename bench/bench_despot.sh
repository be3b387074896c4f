#!/usr/bin/env bash
# The solver library beside the authors' DESPOT (AdaCompNUS/despot) on RockSample(7,8), on this
# machine: builds their code from a checkout outside the repository, then runs episodes
# interleaved (episode i of every planner in one job, the planners' order rotating with i; JOBS
# jobs at once, one core each), each planner with CPU_S seconds of CPU per step and 90 steps at
# most (their sim_len). Theirs: DESPOT with their RockSample defaults (K 500, depth 90, xi 0.95,
# no pruning, MDP upper bound, "go east" lower bound, the exact belief). Ours: `despot` (the same
# algorithm and bounds, written from the papers) and `pomcp`.
#
# Usage: DESPOT_SRC=/path/to/despot bench/bench_despot.sh [episodes]   (default 60)
#   A checkout: git clone https://github.com/AdaCompNUS/despot /tmp/despot-src
# env: CPU_S (0.1), JOBS (nproc), FIRST (the first episode's seed, default 1: a rerun with new
#      episodes starts after the last one), SCRATCH (/tmp/npfkct-despot: their build and the raw logs),
#      PLANNERS (ours, default "despot pomcp"), OUT (the per-episode JSON lines; default
#      bench/results/despot/rocksample-<CPU_S>s.jsonl, replaced).
# The summary (mean discounted return, standard error = sd / sqrt(episodes), trials per step,
# each planner minus theirs) is bench/results_table.py despot OUT, printed at the end.
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_prepare npfkct-bench
BENCH="$BUILD_DIR/bin/npfkct-bench"
EPISODES="${1:-60}"
CPU_S="${CPU_S:-0.1}"
JOBS="${JOBS:-$(nproc)}"
SCRATCH="${SCRATCH:-/tmp/npfkct-despot}"
PLANNERS="${PLANNERS:-despot pomcp}"
FIRST="${FIRST:-1}"
OUT="${OUT:-$NPFKCT_ROOT/bench/results/despot/rocksample-${CPU_S}s.jsonl}"
if [ -z "${DESPOT_SRC:-}" ] || [ ! -f "$DESPOT_SRC/src/solver/despot.cpp" ]; then
  echo "bench_despot.sh: set DESPOT_SRC to a checkout of https://github.com/AdaCompNUS/despot" >&2
  exit 2
fi
mkdir -p "$SCRATCH/build" "$SCRATCH/logs" "$(dirname "$OUT")"
cmake -S "$DESPOT_SRC" -B "$SCRATCH/build" -DCMAKE_BUILD_TYPE=Release >"$SCRATCH/cmake.log"
make -C "$SCRATCH/build" -j"$(nproc)" despot_rock_sample >"$SCRATCH/make.log"
THEIRS="$SCRATCH/build/examples/cpp_models/rock_sample/despot_rock_sample"
DESPOT_COMMIT="$(git -C "$DESPOT_SRC" rev-parse HEAD 2>/dev/null || echo unknown)"
CPU_MS="$(python3 -c "print(round($CPU_S * 1000, 3))")"

# One episode of every planner; prints one JSON line per planner.
episode() {
  local i="$1" names=(theirs $PLANNERS) n k
  n=${#names[@]}
  for ((k = 0; k < n; ++k)); do
    local name="${names[$(((i + k) % n))]}"
    if [ "$name" = theirs ]; then
      local log="$SCRATCH/logs/theirs-$i.log"
      "$THEIRS" --size 7 --number 8 -t "$CPU_S" --runs 1 -r "$i" -v 3 >"$log" 2>&1
      python3 - "$log" "$i" "$DESPOT_COMMIT" <<'EOF'
import json, re, statistics, sys
text = open(sys.argv[1]).read()
ret = re.search(r"Average total discounted reward \(stderr\) = ([-0-9.e]+)", text)
steps = re.findall(r"Round 0 Step (\d+)", text)
trials = [int(t) for t in re.findall(r"Trials: no\. / max length = (\d+)", text)]
print(json.dumps({"planner": "despot-original", "episode": int(sys.argv[2]),
                  "discounted_return": float(ret.group(1)), "steps": len(steps),
                  "median_trials_per_step": statistics.median(trials) if trials else None,
                  "commit": sys.argv[3]}))
EOF
    else
      "$BENCH" --problem rocksample --planner "$name" --episodes 1 --seed "$i" --cpu-ms "$CPU_MS" \
        --time-ms 0 --max-steps 90 --threads 1 |
        python3 -c '
import json, sys
r = json.loads(sys.stdin.read())
print(json.dumps({"planner": r["planner"], "episode": int(sys.argv[1]),
                  "discounted_return": r["mean_discounted_return"], "steps": r["mean_steps"],
                  "median_trials_per_step": r["median_sims_per_step"]}))' "$i"
    fi
  done
}
export -f episode
export SCRATCH THEIRS CPU_S CPU_MS BENCH PLANNERS DESPOT_COMMIT
seq "$FIRST" $((FIRST + EPISODES - 1)) | xargs -P "$JOBS" -I{} bash -c 'episode {}' >"$OUT.tmp"
mv "$OUT.tmp" "$OUT"
python3 "$NPFKCT_ROOT/bench/results_table.py" despot "$OUT"
