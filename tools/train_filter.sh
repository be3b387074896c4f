#!/usr/bin/env bash
# Reproduces the shipped neural filter model filter/model/filter.pt: generates the training
# and validation sets from npfkct-scenegen scenes (32,000 snapshots drawn from seeds 30001-830000,
# and 1,000 from seeds 20001-22000: never the paper's six scenes, never the benchmark's held-out
# seeds above 900000), trains one network per seed on them (one libtorch thread; seeds 1, 2 and 3),
# writes the networks as one ensemble model (their Gaussians pooled as a mixture), and evaluates
# it on two test sets of layouts it never saw: the 30 held-out generated scenes (seeds
# 900001-900030) and the paper's six scenes. Figures go to bench/results/filter_eval.json (one
# line per test set) and filter_bench.json; each network's training to filter_train_log.txt.
# Usage: tools/train_filter.sh   (env: BUILD_DIR, DATA_DIR, MODEL, EPOCHS, TRAIN_SAMPLES, SEEDS)
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_prepare npfkct-train
DATA_DIR="${DATA_DIR:-$BUILD_DIR/filter-data}"
MODEL="${MODEL:-$NPFKCT_ROOT/filter/model/filter.pt}"
# Five epochs, the learning rate x0.7 after each: an earlier model trained on 20,000 snapshots
# from 20,000 seeds with the rate halved every 5 epochs overfitted after epoch 5 (its validation
# loss jumped from -1.69 to -1.20); more layouts and a decaying rate keep the validation loss
# falling. The checkpoint kept is the one of the best validation loss.
EPOCHS="${EPOCHS:-5}"
# Networks trained alike from different seeds differ by several tenths of a point of accuracy (the
# draw of the training); their ensemble is steadier and better calibrated than any one of them.
SEEDS="${SEEDS:-1 2 3}"
TRAIN_SAMPLES="${TRAIN_SAMPLES:-32000}"
RESULTS="$NPFKCT_ROOT/bench/results"
TRAIN="$BUILD_DIR/bin/npfkct-train"
SCENES="$NPFKCT_ROOT/scenarios"
PAPER="$SCENES/loose1.json,$SCENES/loose2.json,$SCENES/hidden1.json,$SCENES/covered1.json"
PAPER="$PAPER,$SCENES/complex1.json,$SCENES/fig16.json"
mkdir -p "$DATA_DIR" "$RESULTS" "$(dirname "$MODEL")"
"$TRAIN" generate --out "$DATA_DIR/train.bin" --samples "$TRAIN_SAMPLES" \
  --scene-seed 30001 --scene-count 800000 --max-steps 4 --seed 11
"$TRAIN" generate --out "$DATA_DIR/val.bin" --samples 1000 --scene-seed 20001 --scene-count 2000 \
  --max-steps 4 --seed 12
"$TRAIN" generate --out "$DATA_DIR/test_heldout.bin" --samples 1500 --scene-seed 900001 \
  --scene-count 30 --seed 13
"$TRAIN" generate --out "$DATA_DIR/test_paper.bin" --samples 1500 --scenarios "$PAPER" --seed 14
rm -f "$RESULTS/filter_train_log.txt"
members=()
for seed in $SEEDS; do
  member="$DATA_DIR/network-seed$seed.pt"
  "$TRAIN" train --train "$DATA_DIR/train.bin" --val "$DATA_DIR/val.bin" --out "$member" \
    --epochs "$EPOCHS" --lr-decay 0.7 --lr-decay-every 1 --patience 3 --seed "$seed" \
    --threads 1 2>&1 | tee -a "$RESULTS/filter_train_log.txt"
  members+=("$member")
done
"$TRAIN" ensemble --models "$(IFS=,; echo "${members[*]}")" --out "$MODEL" |
  tee -a "$RESULTS/filter_train_log.txt"
rm -f "$RESULTS/filter_eval.json" "$RESULTS/filter_bench.json"
for set in heldout paper; do
  "$TRAIN" evaluate --model "$MODEL" --test "$DATA_DIR/test_$set.bin" --label "$set" \
    --json "$RESULTS/filter_eval.json"
done
"$TRAIN" bench --model "$MODEL" --runs 100 --json "$RESULTS/filter_bench.json"
