#!/usr/bin/env bash
# The main job: builds npfkct, starts the planning server and drives the simulated Fetch robot
# through the Loose1 scenario over HTTP, printing each step and the outcome. The npfkct planner
# uses the shipped neural filter model, filter.pt of the server's model folder (MODEL= to plan
# without it, MODEL=name for another model of that folder).
# Usage: scripts/run.sh [scenario.json] [planner]
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_prepare
SCENARIO="${1:-$NPFKCT_ROOT/scenarios/data/loose1.json}"
PLANNER="${2:-npfkct}"
MODEL="${MODEL-filter.pt}"
FILTER_ARGS=()
if [ "$PLANNER" = npfkct ] && [ -n "$MODEL" ]; then FILTER_ARGS=(--model "$MODEL"); fi

LOG="$(mktemp)"
"$BUILD_DIR/server/npfkct-server" --port 0 >"$LOG" 2>&1 &
SERVER=$!
trap 'kill "$SERVER" 2>/dev/null || true; rm -f "$LOG"' EXIT
for _ in $(seq 100); do
  grep -q "^listening on" "$LOG" && break
  sleep 0.1
done
PORT="$(sed -n 's/^listening on .*:\([0-9]*\)$/\1/p' "$LOG")"
[ -n "$PORT" ] || { cat "$LOG"; echo "the server did not start" >&2; exit 1; }
echo "npfkct-server on port $PORT; driving $(basename "$SCENARIO") with $PLANNER" \
  "${FILTER_ARGS[@]:+(neural filter $(basename "$MODEL"))}"
"$BUILD_DIR/scenarios/npfkct-drive" --server "http://127.0.0.1:$PORT" --scenario "$SCENARIO" \
  --planner "$PLANNER" "${FILTER_ARGS[@]}" --budget-ms 1000
