#!/usr/bin/env bash
# POST /v1/sessions with a request body file. Usage: create_session.sh BODY.json
# (see schemas/examples/create_session_request.json)
set -euo pipefail; source "$(dirname "$0")/common.sh"
npfkct_curl -X POST -H "Content-Type: application/json" --data-binary "@$1" \
  "$NPFKCT_SERVER/v1/sessions"; echo
