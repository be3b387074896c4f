#!/usr/bin/env bash
# GET /v1/sessions. Usage: list_sessions.sh [PAGE_SIZE [PAGE_TOKEN]]
set -euo pipefail; source "$(dirname "$0")/common.sh"
npfkct_curl "$NPFKCT_SERVER/v1/sessions?pageSize=${1:-50}&pageToken=${2:-}"; echo
