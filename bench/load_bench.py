#!/usr/bin/env python3
"""Load benchmark of npfkct-server: N concurrent sessions planning and observing.

Each client drives its own session with the simulated robot (npfkct-sim-robot) for a number of
steps: :plan with a fixed time budget, execute, :observe. Reported:
  throughput        plans and observations completed per second, all clients together
  plan overhead     :plan latency seen by the client minus the planner's own time (elapsedMs),
                    p50 / p99 in milliseconds (goal: p99 under 5 ms); and the same inside the
                    server (request in to reply out), as the bucket bound of its histogram
  observe latency   p50 / p99 in milliseconds
  memory            server resident memory per session (RSS growth / sessions)

Usage: bench/load_bench.py [--sessions 32] [--steps 8] [--budget-ms 100] [--build build]
Prints one JSON line; run it from a quiet machine, the figures are medians of one run.
"""

import argparse
import concurrent.futures
import json
import os
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "clients", "python"))
from npfkct_client import NpfkctClient  # noqa: E402
from npfkct_client import World  # noqa: E402


def rss_kib(pid):
    with open(f"/proc/{pid}/status", encoding="ascii") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def histogram_quantile(metrics_text, name, q):
    """Upper bound of the bucket holding quantile q of a Prometheus histogram, in ms."""
    buckets = []
    for line in metrics_text.splitlines():
        if line.startswith(name + "_bucket{"):
            le = line.split('le="', 1)[1].split('"', 1)[0]
            buckets.append((float("inf") if le == "+Inf" else float(le), int(line.split()[-1])))
    total = buckets[-1][1] if buckets else 0
    for bound, count in buckets:
        if total and count >= q * total:
            return bound * 1000.0
    return float("nan")


def percentile(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, int(round(q * (len(values) - 1))))]


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sessions", type=int, default=32)
    parser.add_argument("--steps", type=int, default=8)
    parser.add_argument("--budget-ms", type=float, default=100.0)
    parser.add_argument("--scenario", default=os.path.join(ROOT, "scenarios",
                                                           "complex1.json"))
    parser.add_argument("--build", default=os.path.join(ROOT, "build"))
    args = parser.parse_args()

    server = subprocess.Popen([os.path.join(args.build, "bin", "npfkct-server"), "--port", "0",
                               "--threads", str(args.sessions + 8), "--log-level", "warn",
                               # every session may wait for a planning slot: this measures
                               # queueing, not refusals (429 beyond slots + queue)
                               "--plan-queue", str(args.sessions)],
                              stdout=subprocess.PIPE, text=True)
    port = int(server.stdout.readline().strip().rsplit(":", 1)[1])
    url = f"http://127.0.0.1:{port}"
    world = World.from_scenario(args.scenario)
    time.sleep(0.2)
    rss_before = rss_kib(server.pid)
    plan_overhead, plan_total, observe_latency = [], [], []

    def client(i):
        api = NpfkctClient(url)
        session = api.create_session(world, planner="npfkct", seed=i)
        robot = subprocess.Popen([os.path.join(args.build, "bin", "npfkct-sim-robot"),
                                  "--scenario", args.scenario, "--seed", str(i)],
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        out = []
        for _ in range(args.steps):
            t0 = time.perf_counter()
            plan = api.plan(session.id, time_ms=args.budget_ms)
            t1 = time.perf_counter()
            robot.stdin.write(json.dumps(plan.action.to_json()) + "\n")
            robot.stdin.flush()
            reply = json.loads(robot.stdout.readline())
            t2 = time.perf_counter()
            observed = api.observe(session.id, plan.action_id, body=reply["observation"])
            t3 = time.perf_counter()
            out.append(((t1 - t0) * 1000.0, plan.stats["elapsedMs"], (t3 - t2) * 1000.0))
            if observed.done:
                break
        robot.stdin.close()
        robot.wait()
        return session.id, out

    start = time.perf_counter()
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.sessions) as pool:
        results = list(pool.map(client, range(args.sessions)))
    wall = time.perf_counter() - start
    rss_after = rss_kib(server.pid)
    metrics = NpfkctClient(url).metrics()
    for _, steps in results:
        for total, planning, observe in steps:
            plan_total.append(total)
            plan_overhead.append(total - planning)
            observe_latency.append(observe)
    server.terminate()
    server.wait()
    report = {
        "sessions": args.sessions,
        "budget_ms": args.budget_ms,
        "plans": len(plan_total),
        "throughput_plans_per_s": round(len(plan_total) / wall, 2),
        "throughput_requests_per_s": round(2 * len(plan_total) / wall, 2),
        "plan_overhead_ms_p50": round(statistics.median(plan_overhead), 3),
        "plan_overhead_ms_p99": round(percentile(plan_overhead, 0.99), 3),
        "plan_latency_ms_p50": round(statistics.median(plan_total), 3),
        "server_plan_overhead_ms_p50_bucket": histogram_quantile(
            metrics, "npfkct_plan_overhead_seconds", 0.5),
        "server_plan_overhead_ms_p99_bucket": histogram_quantile(
            metrics, "npfkct_plan_overhead_seconds", 0.99),
        "observe_latency_ms_p50": round(statistics.median(observe_latency), 3),
        "observe_latency_ms_p99": round(percentile(observe_latency, 0.99), 3),
        "rss_per_session_kib": round((rss_after - rss_before) / args.sessions, 1),
        "cpus": os.cpu_count(),
        "wall_s": round(wall, 2),
    }
    print(json.dumps(report))


if __name__ == "__main__":
    main()
