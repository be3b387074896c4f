#!/usr/bin/env bash
# GET /v1/sessions/{id}/belief; with OUT.png, the rendered belief. Usage: belief.sh ID [OUT.png]
set -euo pipefail; source "$(dirname "$0")/common.sh"
if [ -n "${2:-}" ]; then
  npfkct_curl -o "$2" "$NPFKCT_SERVER/v1/sessions/$1/belief?format=png"
else
  npfkct_curl "$NPFKCT_SERVER/v1/sessions/$1/belief"; echo
fi
