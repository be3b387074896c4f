#!/usr/bin/env bash
# GET /v1/sessions/{id}. Usage: get_session.sh ID
set -euo pipefail; source "$(dirname "$0")/common.sh"
npfkct_curl "$NPFKCT_SERVER/v1/sessions/$1"; echo
