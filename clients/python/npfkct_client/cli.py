"""npfkct-client: the command-line client of the npfkct planning server (python3 -m npfkct_client).

  npfkct-client --server URL create --scenario FILE [--planner NAME] [--model NAME] [--seed N]
                [--map MAP.yaml]   (a ROS map_server occupancy grid for the room)
                [--workspaces WS.json [--pcd MAP.pcd]]   (traced workspaces; heights from a PCD)
  npfkct-client --server URL plan ID [--time-ms MS] [--cpu-ms MS] [--simulations N]
  npfkct-client --server URL observe ID --action-id A --body FILE   (an :observe body as JSON)
  npfkct-client --server URL get ID | belief ID [--png OUT] | list | delete ID | health

The server and the API key default to $NPFKCT_SERVER (else http://127.0.0.1:8080) and
$NPFKCT_API_KEY.
"""

import argparse
import json
import sys

from npfkct_client import __version__
from npfkct_client.client import ApiError, NpfkctClient
from npfkct_client.world import World


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="npfkct-client", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("--server", help="the server's URL (default: $NPFKCT_SERVER, else "
                        "http://127.0.0.1:8080)")
    parser.add_argument("--api-key", help="bearer key of a server run with --api-key (default: "
                        "$NPFKCT_API_KEY)")
    sub = parser.add_subparsers(dest="command", required=True)
    create = sub.add_parser("create", help="create a session from a scenario's prior map")
    create.add_argument("--scenario", required=True)
    create.add_argument("--planner", default="npfkct")
    create.add_argument("--model", help="neural filter model of the server (e.g. filter.pt)")
    create.add_argument("--seed", type=int)
    create.add_argument("--map", help="a ROS map_server YAML (with its PGM): the occupancy grid "
                        "in place of the scenario's room")
    create.add_argument("--workspaces", help="a JSON file with a list of workspaces "
                        "({name, polygon, height}) in place of the scenario's")
    create.add_argument("--pcd", help="a point-cloud map (PCD) that gives the heights the "
                        "workspaces file leaves out")
    plan = sub.add_parser("plan", help="plan the next action")
    plan.add_argument("id")
    plan.add_argument("--time-ms", type=float)
    plan.add_argument("--cpu-ms", type=float)
    plan.add_argument("--simulations", type=int)
    observe = sub.add_parser("observe", help="report the outcome of the pending action")
    observe.add_argument("id")
    observe.add_argument("--action-id", required=True)
    observe.add_argument("--body", required=True, help="JSON file with the :observe body")
    for name in ("get", "delete"):
        p = sub.add_parser(name)
        p.add_argument("id")
    belief = sub.add_parser("belief")
    belief.add_argument("id")
    belief.add_argument("--png", help="write the rendered belief to this file")
    sub.add_parser("list")
    sub.add_parser("health")
    args = parser.parse_args(argv)

    client = NpfkctClient(args.server, api_key=args.api_key)
    try:
        if args.command == "create":
            world = World.from_scenario(args.scenario)
            if args.map:
                world = world.with_map_files(args.map)
            if args.workspaces:
                with open(args.workspaces, encoding="utf-8") as f:
                    world = world.with_workspaces(json.load(f), args.pcd)
            out = client.create_session(world, planner=args.planner, seed=args.seed,
                                        model=args.model).raw
        elif args.command == "plan":
            p = client.plan(args.id, time_ms=args.time_ms, simulations=args.simulations,
                            cpu_ms=args.cpu_ms)
            out = {"actionId": p.action_id, "action": p.action.to_json(),
                   "expectedValue": p.expected_value, "stats": p.stats.raw, "budget": p.budget}
        elif args.command == "observe":
            with open(args.body, encoding="utf-8") as f:
                body = json.load(f)
            o = client.observe(args.id, args.action_id, body=body)
            out = {"done": o.done, "reward": o.reward, "session": o.session.raw}
        elif args.command == "get":
            out = client.get_session(args.id).raw
        elif args.command == "delete":
            client.delete_session(args.id)
            out = {}
        elif args.command == "belief":
            if args.png:
                with open(args.png, "wb") as f:
                    f.write(client.belief_png(args.id))
                out = {"written": args.png}
            else:
                out = client.belief(args.id)
        elif args.command == "list":
            out = {"sessions": [s.raw for s in client.list_sessions()]}
        else:
            out = client.health()
    except (ValueError, OSError) as e:  # a file the client reads: map, workspaces, PCD
        print(json.dumps({"error": {"message": str(e)}}), file=sys.stderr)
        return 2
    except ApiError as e:
        print(json.dumps({"error": {"status": e.status, "message": e.message,
                                    "field": e.field,
                                    "fieldViolations": [{"field": f, "description": d}
                                                        for f, d in e.violations]}}),
              file=sys.stderr)
        return 1
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
