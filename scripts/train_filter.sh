#!/usr/bin/env bash
# Reproduces the shipped neural filter model solver/filter/model/filter.pt: generates the
# training, validation and test sets from the built-in simulator (different seeds), trains the
# network (one libtorch thread, as the shipped model was; about 25 minutes on this machine),
# evaluates it on the test set and times it. Figures go to bench/results/filter_*.json.
# Usage: scripts/train_filter.sh   (env: BUILD_DIR, DATA_DIR, MODEL, EPOCHS, TRAIN_SAMPLES)
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_prepare
DATA_DIR="${DATA_DIR:-$BUILD_DIR/filter-data}"
MODEL="${MODEL:-$NPFKCT_ROOT/solver/filter/model/filter.pt}"
EPOCHS="${EPOCHS:-30}"
TRAIN_SAMPLES="${TRAIN_SAMPLES:-6000}"
RESULTS="$NPFKCT_ROOT/bench/results"
TRAIN="$BUILD_DIR/solver/filter/npfkct-train"
mkdir -p "$DATA_DIR" "$RESULTS" "$(dirname "$MODEL")"
"$TRAIN" generate --out "$DATA_DIR/train.bin" --samples "$TRAIN_SAMPLES" --seed 1
"$TRAIN" generate --out "$DATA_DIR/val.bin" --samples 500 --seed 2
"$TRAIN" generate --out "$DATA_DIR/test.bin" --samples 1000 --seed 3
"$TRAIN" train --train "$DATA_DIR/train.bin" --val "$DATA_DIR/val.bin" --out "$MODEL" \
  --epochs "$EPOCHS" --seed 1 --threads 1
rm -f "$RESULTS/filter_eval.json" "$RESULTS/filter_bench.json"
"$TRAIN" evaluate --model "$MODEL" --test "$DATA_DIR/test.bin" --json "$RESULTS/filter_eval.json"
"$TRAIN" bench --model "$MODEL" --runs 100 --json "$RESULTS/filter_bench.json"
