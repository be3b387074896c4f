# Sourced by the curl scripts: server address and optional bearer token.
NPFKCT_SERVER="${NPFKCT_SERVER:-http://127.0.0.1:8080}"
AUTH=()
if [ -n "${NPFKCT_API_KEY:-}" ]; then AUTH=(-H "Authorization: Bearer $NPFKCT_API_KEY"); fi
# curl that prints the body and fails (exit 22) on HTTP errors, showing the error body.
npfkct_curl() { curl -sS --fail-with-body "${AUTH[@]}" "$@"; }
