#!/usr/bin/env bash
# The main job: builds npfkct-server and npfkct-drive, starts the planning server and drives the
# simulated Fetch robot through a scenario (default Loose1) over HTTP, printing each step and the
# outcome. The npfkct planner plans with the server's default model, the shipped neural filter
# (MODEL=name for another model of the server's model folder, MODEL=none for uniform candidates).
#
# Usage: scripts/run.sh [SCENARIO.json] [PLANNER]
#        scripts/run.sh --help
#   SCENARIO  a scenario file (default scenarios/loose1.json; see scenarios/)
#   PLANNER   npfkct (default), kct, pomcp, gpomcp, pomcp-joint, pomcpow, vomcpow, advt, oracle
#   env: MODEL, BUDGET_MS (planning time per step, default 1000), BUILD_DIR (default build/)
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
case "${1:-}" in
  -h|--help) sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
  -*) echo "run.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
esac
SCENARIO="${1:-$NPFKCT_ROOT/scenarios/loose1.json}"
PLANNER="${2:-npfkct}"
[ -f "$SCENARIO" ] || { echo "run.sh: no scenario file $SCENARIO (see --help)" >&2; exit 2; }
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_prepare npfkct-server npfkct-drive
MODEL_ARGS=()
case "${MODEL:-}" in
  "") ;;
  none) MODEL_ARGS=(--model "") ;;
  *) MODEL_ARGS=(--model "$MODEL") ;;
esac

LOG="$(mktemp)"
"$BUILD_DIR/bin/npfkct-server" --port 0 >"$LOG" 2>&1 &
SERVER=$!
trap 'kill "$SERVER" 2>/dev/null || true; rm -f "$LOG"' EXIT
for _ in $(seq 100); do
  grep -q "^listening on" "$LOG" && break
  sleep 0.1
done
PORT="$(sed -n 's/^listening on .*:\([0-9]*\)$/\1/p' "$LOG")"
[ -n "$PORT" ] || { cat "$LOG"; echo "the server did not start" >&2; exit 1; }
echo "npfkct-server on port $PORT; driving $(basename "$SCENARIO") with $PLANNER"
"$BUILD_DIR/bin/npfkct-drive" --server "http://127.0.0.1:$PORT" --scenario "$SCENARIO" \
  --planner "$PLANNER" "${MODEL_ARGS[@]}" --budget-ms "${BUDGET_MS:-1000}"
