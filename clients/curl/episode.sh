#!/usr/bin/env bash
# A whole episode with curl only: the simulated robot (npfkct-sim-robot) executes each planned
# action and its observation is posted back. Usage: episode.sh SCENARIO.json SIM_ROBOT [TIME_MS]
set -euo pipefail
here="$(dirname "$0")"; source "$here/common.sh"
scenario="$1"; robot="$2"; time_ms="${3:-300}"
field() { python3 -c "import json,sys; d=json.load(sys.stdin); print($1)"; }
robot_pid=""
tmp="$(mktemp -d)"; cleanup() {
  exec 3>&- 4<&- || true
  rm -rf "$tmp"
  if [ -n "$robot_pid" ]; then kill "$robot_pid" 2>/dev/null || true; fi
}
trap cleanup EXIT
python3 - "$scenario" > "$tmp/create.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
keys = ("robot", "room", "mapResolution", "furniture", "baseRegions", "discretePoses", "start",
        "params")
print(json.dumps({"world": {k: s[k] for k in keys if k in s}, "seed": 1,
                  "planner": {"name": "npfkct"}}))
PY
id="$("$here/create_session.sh" "$tmp/create.json" | field 'd["id"]')"
echo "session $id"
mkfifo "$tmp/to_robot" "$tmp/from_robot"
"$robot" --scenario "$scenario" --seed 1 < "$tmp/to_robot" > "$tmp/from_robot" &
robot_pid=$!
exec 3>"$tmp/to_robot" 4<"$tmp/from_robot"
for step in $(seq 50); do
  plan="$("$here/plan.sh" "$id" "$time_ms")"
  action_id="$(echo "$plan" | field 'd["actionId"]')"
  action="$(echo "$plan" | field 'json.dumps(d["action"])')"
  echo "$action" >&3
  read -r reply <&4
  # The server's answers reach Python as data (argv), never as source.
  echo "$reply" | python3 -c '
import json, sys
d = json.load(sys.stdin); o = d["observation"]; o["actionId"] = sys.argv[1]
json.dump(o, open(sys.argv[2], "w"))' "$action_id" "$tmp/observe.json"
  "$here/observe.sh" "$id" "$tmp/observe.json" > "$tmp/observed.json"
  echo "step $step: $(echo "$plan" | field 'd["action"]["type"]') -> $(echo "$reply" | field 'd["outcome"]["detail"]')"
  if [ "$(echo "$reply" | field 'd["outcome"]["terminal"]')" = "True" ]; then
    echo "outcome: target removed after $step steps"
    "$here/delete_session.sh" "$id" > /dev/null
    exit 0
  fi
done
echo "outcome: target not removed"
exit 3
