#!/usr/bin/env bash
# GET /healthz
set -euo pipefail; source "$(dirname "$0")/common.sh"
npfkct_curl "$NPFKCT_SERVER/healthz"; echo
