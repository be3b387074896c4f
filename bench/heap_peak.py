#!/usr/bin/env python3
"""Peak resident memory of a server whose plan grows a search tree to --max-heap-mb.

Starts npfkct-server (NPFKCT_SERVER_BIN, default build/bin/npfkct-server) with
--max-heap-mb MB and, CYCLES times, creates a pomcp-joint session of 10,000 particles with 64
discrete poses (1,728 joint actions per node) and search.maxDepth 100, plans 5 s and deletes the
session, printing the plan's statistics with the server's resident memory after the plan, after
the delete and at its peak (VmRSS, VmHWM).

Usage: bench/heap_peak.py [MB] [CYCLES]   (defaults 1024, 1)"""
import http.client
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MB = sys.argv[1] if len(sys.argv) > 1 else "1024"
CYCLES = int(sys.argv[2]) if len(sys.argv) > 2 else 1
BIN = os.environ.get("NPFKCT_SERVER_BIN", os.path.join(ROOT, "build", "bin", "npfkct-server"))


def main():
    with open(os.path.join(ROOT, "schemas", "examples", "create_session_request.json")) as f:
        world = json.load(f)["world"]
    world["discretePoses"] = [{"x": 0.1 + 0.01 * i, "y": 0.0, "yaw": 0.0} for i in range(64)]
    server = subprocess.Popen([BIN, "--port", "0", "--log-level", "warn", "--max-heap-mb", MB],
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        port = int(server.stdout.readline().rsplit(":", 1)[1])

        def memory(key):
            with open(f"/proc/{server.pid}/status") as f:
                return next(int(l.split()[1]) // 1024 for l in f if l.startswith(key))

        def call(method, path, body):
            c = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
            c.request(method, path, None if body is None else json.dumps(body),
                      {"Content-Type": "application/json"})
            r = c.getresponse()
            return json.loads(r.read())

        print(f"--max-heap-mb {MB}: resident at start {memory('VmRSS')} MiB", flush=True)
        for cycle in range(CYCLES):
            session = call("POST", "/v1/sessions",
                           {"world": world, "seed": 1 + cycle,
                            "planner": {"name": "pomcp-joint", "particles": 10000,
                                        "options": {"search.maxDepth": 100}}})
            plan = call("POST", f"/v1/sessions/{session['id']}:plan",
                        {"budget": {"timeMs": 5000}})
            stats = plan["stats"]
            after_plan = memory("VmRSS")
            call("DELETE", f"/v1/sessions/{session['id']}", None)
            print(f"cycle {cycle}: plan of {stats['elapsedMs']:.0f} ms, budgetExhausted "
                  f"{stats['budgetExhausted']}, {stats['treeNodes']} tree nodes; resident after "
                  f"it {after_plan} MiB, after the delete {memory('VmRSS')} MiB, peak "
                  f"{memory('VmHWM')} MiB", flush=True)
    finally:
        server.kill()
        server.wait()


if __name__ == "__main__":
    main()
