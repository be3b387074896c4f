#!/usr/bin/env bash
# Sensitivity of NPF-kCT's defaults: npfkct with its defaults and with one option changed per row,
# on 20 tuning scenes that no figure of record uses: npfkct-scenegen seeds 910001-910020 (the filter
# trains on 30001-830000 and validates on 20001-22000; the held-out benchmark uses 900001-900030),
# at the generated scenes' protocol (0.25 s of the planning thread's CPU time per step, 5 trials,
# success within 50 steps), with an oracle row for the shares. The table gives each row's share of
# the oracle's reward and its change against the defaults, paired over the scenes (mean ± 95% t
# interval over the scenes).
# Resumable: one file per row and scene, bench/results/sensitivity/RUN/ROW/SEED.jsonl; finished
# cells are skipped; --commit commits each. About 1.5 CPU-hours with the default rows.
# Usage: bench/bench_sensitivity.sh [--run NAME] [--cpu-ms MS] [--trials N] [--commit]
#        env: SEEDS (default: 910001 ... 910020), ROWS (default: oracle, defaults and the options
#        below; a row is "defaults", "oracle" or one npfkct option key=value), BUILD_DIR
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_bench_args 250 5 14 "$@"
npfkct_prepare npfkct-bench npfkct-scenegen
SEEDS="${SEEDS:-$(seq 910001 910020)}"
DEFAULT_ROWS="oracle defaults w1=1 w1=2 k=2 k=4 c_r=0.02 c_r=0.1 num_candidates=128"
DEFAULT_ROWS="$DEFAULT_ROWS num_candidates=512 w2_ratio=1 max_initial_clusters=16"
ROWS="${ROWS:-$DEFAULT_ROWS}"
OUT="$NPFKCT_ROOT/bench/results/sensitivity/$RUN"
# shellcheck disable=SC2086  # one seed per word
npfkct_generate_scenes "$BUILD_DIR/tuning-scenes" $SEEDS
for row in $ROWS; do
  case "$row" in
    oracle) ARGS=(--planner oracle) ;;
    defaults) ARGS=(--planner npfkct) ;;
    *=*) ARGS=(--planner npfkct --opt "$row") ;;
    *) echo "bench_sensitivity.sh: a row is defaults, oracle or key=value, not $row" >&2; exit 2 ;;
  esac
  npfkct_bench_row "$OUT/$row" "${ARGS[@]}"
done
python3 "$NPFKCT_ROOT/bench/results_table.py" sensitivity "$OUT" | tee "$OUT/sensitivity.md"
