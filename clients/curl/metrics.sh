#!/usr/bin/env bash
# GET /metrics (Prometheus text)
set -euo pipefail; source "$(dirname "$0")/common.sh"
npfkct_curl "$NPFKCT_SERVER/metrics"
