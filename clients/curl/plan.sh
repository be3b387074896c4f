#!/usr/bin/env bash
# POST /v1/sessions/{id}:plan. Usage: plan.sh ID [TIME_MS [SIMULATIONS [CPU_MS]]]
set -euo pipefail; source "$(dirname "$0")/common.sh"
budget="{\"timeMs\": ${2:-1000}"
if [ -n "${3:-}" ]; then budget="$budget, \"simulations\": $3"; fi
if [ -n "${4:-}" ]; then budget="$budget, \"cpuMs\": $4"; fi
npfkct_curl -X POST -H "Content-Type: application/json" -d "{\"budget\": $budget}}" \
  "$NPFKCT_SERVER/v1/sessions/$1:plan"; echo
