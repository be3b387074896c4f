#!/usr/bin/env python3
"""Fleet benchmark: npfkct-server replicas behind nginx, sessions in PostgreSQL, on this machine.

Starts a throwaway PostgreSQL cluster and Debian's nginx with deploy/nginx/npfkct.conf (the
helpers of tests/fleet.py), then, for 1 and for 3 replicas, drives --robots simulated robots
through the fleet, each planning with a CPU-time budget, executing with npfkct-sim-robot and
observing, starting a new episode when one ends, until --plans plans were made. Reported per
fleet size:
  plans_per_s       plans completed per second, all robots together
  plan overhead     :plan latency seen by the client minus the planner's own time (elapsedMs),
                    p50 / p99 in ms: HTTP, nginx, the store's refresh and save, queueing for a
                    planning slot; and the replicas' own histogram (npfkct_plan_overhead_seconds,
                    request in to reply out, buckets merged over replicas) as a bucket bound
                  (null: above the largest bound, 100 ms); the store's refresh and save
                  latencies (npfkct_store_operation_seconds) the same way
Then, --kills times, with 3 fresh replicas and the robots running, the replica holding the most of
their sessions is killed with SIGKILL; reported over all its sessions of all rounds:
  probe             for each of its sessions, the time from the kill until a GET of the session
                    through nginx answers 200 again (served by another replica, which loads it
                    from the store); median and max over the sessions
  next_step         for each of its sessions, the time from the kill until its robot's next
                    acknowledged :plan or :observe; median and max

Usage: bench/fleet_bench.py [--robots 6] [--plans 480] [--cpu-ms 50] [--kills 5]
                              [--failover-plans 60] [--build build] [--out FILE]
Prints one JSON object. Figures are from one run; the load of the machine (other processes)
changes them: the JSON records the load average.
"""

import argparse
import concurrent.futures
import json
import os
import statistics
import subprocess
import sys
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def percentile(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, int(round(q * (len(values) - 1))))]


def histogram_quantile(texts, name, q, labels=""):
    """Upper bound, in ms, of the bucket holding quantile q of a Prometheus histogram summed
    over several replicas' /metrics texts (`labels`: the series' labels before le, with their
    comma)."""
    merged = {}
    for text in texts:
        for line in text.splitlines():
            if line.startswith(name + "_bucket{" + labels + "le="):
                le = line.split('le="', 1)[1].split('"', 1)[0]
                bound = float("inf") if le == "+Inf" else float(le)
                merged[bound] = merged.get(bound, 0) + int(line.split()[-1])
    buckets = sorted(merged.items())
    total = buckets[-1][1] if buckets else 0
    for bound, count in buckets:
        if total and count >= q * total:
            return None if bound == float("inf") else bound * 1000.0
    return None


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", type=int, default=6)
    parser.add_argument("--plans", type=int, default=480, help="plans per fleet size")
    parser.add_argument("--kills", type=int, default=5, help="failover rounds")
    parser.add_argument("--failover-plans", type=int, default=60, help="plans per round")
    parser.add_argument("--cpu-ms", type=float, default=50.0, help="planning budget (CPU time)")
    parser.add_argument("--planner", default="pomcp")
    parser.add_argument("--scenario", default="loose1")
    parser.add_argument("--build", default=os.path.join(ROOT, "build"))
    parser.add_argument("--out", help="also write the JSON here")
    args = parser.parse_args()

    os.environ["NPFKCT_BUILD_DIR"] = os.path.abspath(args.build)
    sys.path.insert(0, os.path.join(ROOT, "tests"))
    import requests  # noqa: E402
    from conftest import SimRobot, world_of  # noqa: E402
    from fleet import Nginx, Postgres, call, start_replica  # noqa: E402

    world = world_of(args.scenario)
    budget = {"cpuMs": args.cpu_ms}

    class Robot:
        """One robot: episodes of plan, execute, observe through the fleet; timings kept."""

        def __init__(self, url, seed):
            self.url, self.seed = url, seed
            self.overheads, self.acked = [], []  # ms; times of acknowledged requests
            self.session = None

        def new_session(self, deadline):
            r = call("POST", self.url + "/v1/sessions", deadline,
                     json={"world": world, "seed": self.seed,
                           "planner": {"name": args.planner}})
            assert r.status_code == 200, r.text
            self.session = r.json()["id"]
            self.seed += 1000

        def run(self, plans_left, stop, deadline):
            sim = SimRobot(args.scenario, seed=self.seed)
            try:
                self.new_session(deadline)
                steps = 0
                while not stop.is_set() and plans_left():
                    base = f"{self.url}/v1/sessions/{self.session}"
                    t0 = time.perf_counter()
                    r = call("POST", base + ":plan", deadline, json={"budget": budget})
                    if r.status_code == 400 and "is pending" in r.text:
                        # Saved by a replica that died before replying: served from the store.
                        j = call("GET", base, deadline).json()["pendingAction"]
                    else:
                        assert r.status_code == 200, r.text
                        j = r.json()
                        client_ms = (time.perf_counter() - t0) * 1e3
                        self.overheads.append(client_ms - j["stats"]["elapsedMs"])
                    self.acked.append(time.time())
                    observation = sim.execute(j["action"])["observation"]
                    r = call("POST", base + ":observe", deadline,
                             json=dict(observation, actionId=j["actionId"]))
                    if r.status_code == 400 and "already observed" in r.text:
                        done = call("GET", base, deadline).json()["state"] == "DONE"
                    else:
                        assert r.status_code == 200, r.text
                        done = r.json()["done"]
                    self.acked.append(time.time())
                    steps += 1
                    if done or steps >= 50:
                        sim.close()
                        sim = SimRobot(args.scenario, seed=self.seed)
                        self.new_session(deadline)
                        steps = 0
            finally:
                sim.close()

    def drive(robots, plans, kill=None):
        """Runs robots until `plans` plans were made; `kill`, when given, runs beside them."""
        made = [0]
        lock = threading.Lock()

        def plans_left():
            with lock:
                if made[0] >= plans:
                    return False
                made[0] += 1
                return True

        stop = threading.Event()
        deadline = time.time() + 1800
        t0 = time.perf_counter()
        with concurrent.futures.ThreadPoolExecutor(len(robots) + 1) as pool:
            futures = [pool.submit(r.run, plans_left, stop, deadline) for r in robots]
            killed = pool.submit(kill, robots) if kill else None
            for f in futures:
                f.result()
            wall = time.perf_counter() - t0
            return wall, (killed.result() if killed else None)

    pg = Postgres()
    results = {
        "command": "bench/fleet_bench.py " + " ".join(sys.argv[1:]),
        "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "machine": f"{os.cpu_count()} cores",
        "load_average_at_start": os.getloadavg(),
        "robots": args.robots, "plans_per_fleet_size": args.plans,
        "budget": budget, "planner": args.planner, "scenario": args.scenario,
        "fleets": [],
    }
    try:
        commit = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"],
                                capture_output=True, text=True).stdout.strip()
        results["commit"] = commit or "unknown"
        for n in (1, 3):
            store = pg.create_database(f"bench{n}")
            replicas = [start_replica(store) for _ in range(n)]
            nginx = Nginx([r.port for r in replicas])
            try:
                robots = [Robot(nginx.url, seed=1 + i) for i in range(args.robots)]
                wall, _ = drive(robots, args.plans)
                overheads = [o for r in robots for o in r.overheads]
                texts = [requests.get(r.url + "/metrics", timeout=10).text for r in replicas]
                results["fleets"].append({
                    "replicas": n,
                    "plans": len(overheads),
                    "wall_s": round(wall, 2),
                    "plans_per_s": round(len(overheads) / wall, 2),
                    "plan_overhead_ms_p50": round(statistics.median(overheads), 2),
                    "plan_overhead_ms_p99": round(percentile(overheads, 0.99), 2),
                    "server_plan_overhead_ms_p50_bucket": histogram_quantile(
                        texts, "npfkct_plan_overhead_seconds", 0.5),
                    "server_plan_overhead_ms_p99_bucket": histogram_quantile(
                        texts, "npfkct_plan_overhead_seconds", 0.99),
                    # The store's part of each :plan: a refresh, then a save.
                    "store_refresh_ms_p50_bucket": histogram_quantile(
                        texts, "npfkct_store_operation_seconds", 0.5, 'op="refresh",'),
                    "store_save_ms_p50_bucket": histogram_quantile(
                        texts, "npfkct_store_operation_seconds", 0.5, 'op="save",'),
                    "store_save_ms_p99_bucket": histogram_quantile(
                        texts, "npfkct_store_operation_seconds", 0.99, 'op="save",'),
                })
                print(json.dumps(results["fleets"][-1]), file=sys.stderr)
            finally:
                for r in replicas:
                    if r.alive():
                        r.stop()
                nginx.stop()

        # Failover, --kills rounds: 3 fresh replicas, the robots running, the replica holding
        # the most of their sessions killed.
        probes, next_steps, held_counts, loaded = [], [], [], 0.0

        def kill(robots, replicas, nginx, db):
            while sum(len(r.acked) for r in robots) < 4 * len(robots):
                time.sleep(0.05)
            sessions = {r.session for r in robots}
            owners = {}
            for sid, by in pg.psql("SELECT id, updated_by FROM npfkct_sessions", db=db):
                if sid in sessions:
                    owners.setdefault(int(by.rsplit("/", 1)[1]), []).append(sid)
            pid, held = max(owners.items(), key=lambda kv: len(kv[1]))
            victim = next(r for r in replicas if r.proc.pid == pid)
            moved = [r for r in robots if r.session in held]
            t_kill = time.time()
            victim.kill()

            def probe(sid):
                while True:
                    try:
                        if requests.get(f"{nginx.url}/v1/sessions/{sid}",
                                        timeout=30).status_code == 200:
                            return time.time() - t_kill
                    except requests.RequestException:
                        pass
                    time.sleep(0.005)

            with concurrent.futures.ThreadPoolExecutor(len(held)) as pool:
                probes = list(pool.map(probe, held))
            # Each moved robot's next acknowledged request after the kill.
            deadline = time.time() + 120
            while time.time() < deadline and \
                    not all(any(t > t_kill for t in r.acked) for r in moved):
                time.sleep(0.01)
            next_step = [min(t for t in r.acked if t > t_kill) - t_kill for r in moved
                         if any(t > t_kill for t in r.acked)]
            return {"sessions_on_killed_replica": len(held), "probe_s": probes,
                    "next_step_s": next_step}

        for round_ in range(args.kills):
            store = pg.create_database(f"failover{round_}")
            replicas = [start_replica(store) for _ in range(3)]
            nginx = Nginx([r.port for r in replicas])
            db = store.rsplit("/", 1)[1]
            try:
                robots = [Robot(nginx.url, seed=1 + 100 * round_ + i) for i in range(args.robots)]
                _, failover = drive(robots, args.failover_plans,
                                    kill=lambda robots: kill(robots, replicas, nginx, db))
                probes += failover["probe_s"]
                next_steps += failover["next_step_s"]
                held_counts.append(failover["sessions_on_killed_replica"])
                texts = [requests.get(r.url + "/metrics", timeout=10).text for r in replicas
                         if r.alive()]
                loaded += sum(float(line.split()[-1]) for t in texts for line in t.splitlines()
                              if line.startswith("npfkct_sessions_loaded_total "))
            finally:
                for r in replicas:
                    if r.alive():
                        r.stop()
                nginx.stop()
        results["failover"] = {
            "replicas": 3,
            "kills": args.kills,
            "sessions_on_killed_replica": held_counts,
            "probe_s_median": round(statistics.median(probes), 3),
            "probe_s_max": round(max(probes), 3),
            "next_step_s_median": round(statistics.median(next_steps), 3),
            "next_step_s_max": round(max(next_steps), 3),
            "sessions_loaded_by_survivors": loaded,
            "probe_s": [round(p, 3) for p in probes],
            "next_step_s": [round(p, 3) for p in next_steps],
        }
    finally:
        pg.remove()
    results["load_average_at_end"] = os.getloadavg()
    text = json.dumps(results, indent=1)
    print(text)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
