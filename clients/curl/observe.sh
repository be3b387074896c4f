#!/usr/bin/env bash
# POST /v1/sessions/{id}:observe with a body file (it carries the actionId).
# Usage: observe.sh ID BODY.json   (see schemas/examples/observe_request.json)
set -euo pipefail; source "$(dirname "$0")/common.sh"
npfkct_curl -X POST -H "Content-Type: application/json" --data-binary "@$2" \
  "$NPFKCT_SERVER/v1/sessions/$1:observe"; echo
