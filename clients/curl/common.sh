# Sourced by the curl scripts: server address and optional bearer token.
NPFKCT_SERVER="${NPFKCT_SERVER:-http://127.0.0.1:8080}"
AUTH=()
if [ -n "${NPFKCT_API_KEY:-}" ]; then AUTH=(-H "Authorization: Bearer $NPFKCT_API_KEY"); fi
# curl that prints the body and fails (exit 22) on HTTP errors, showing the error body, reads
# brackets and braces in a path (a session id) as themselves, and
# gives up (exit 28) on a call that takes longer than NPFKCT_MAX_TIME seconds (default 300: a
# plan may search for 60 s and wait for a slot) or a connection that takes 10 s.
npfkct_curl() {
  curl -sS --globoff --fail-with-body --connect-timeout 10 --max-time "${NPFKCT_MAX_TIME:-300}" \
    "${AUTH[@]}" "$@"
}
