#!/usr/bin/env bash
# DELETE /v1/sessions/{id}. Usage: delete_session.sh ID
set -euo pipefail; source "$(dirname "$0")/common.sh"
npfkct_curl -X DELETE "$NPFKCT_SERVER/v1/sessions/$1"; echo
