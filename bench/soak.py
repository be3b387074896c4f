#!/usr/bin/env python3
"""Production soak: simulated robots against one npfkct-server for a long run, with faults.

Starts npfkct-server (with an API key, its state directory on a tmpfs of --disk-mb so that the
disk can be filled) and --robots robots, each a thread playing episodes with npfkct-sim-robot
(plan with a CPU budget, execute, observe; a new session when one ends), as a robot controller
would: HTTP errors are retried with backoff, and a plan or observation whose reply was lost is
recovered from the session (its pending action, its step). Faults, each at its share of
--minutes:
  kill      0.25: the server is killed with SIGKILL and started again on the same state
  disk      0.45: the state disk is filled for 60 s (saves fail: 503), then freed
  idle      0.55-0.65: 200 idle connections without a key held open
  slow      0.55-0.65: 100 clients sending a request head a byte a second
  flood     0.75-0.8: unauthenticated connections opened as fast as one thread can, 1,000 held
Measured:
  rss           the server's resident memory every 10 s; from 10 minutes after the restart on (the
                process that served the rest of the run): its spread (max - min) / min, that of
                its 5-minute medians, and its trend in MB per hour
  5xx           responses with a status of 500 or more, by status (503 expected while the disk is
                full and while the server restarts)
  steps         per session, at the end of its episode, the steps the robot saw acknowledged
                against the server's count: lost (server below) and doubled (server above what
                the robot sent); then the robot deletes the session, as the SDK's `with` does
  plan latency  :plan round trips of the robots, p50 / p99 / max, by phase
  flood         whether the robots' calls were served while the flood ran

Usage: bench/soak.py [--minutes 60] [--robots 8] [--cpu-ms 100] [--disk-mb 64] [--build build]
                     [--out bench/results/soak/soak.json]
Needs root (the tmpfs). Prints the summary and writes it, with the RSS samples, as JSON.
"""

import argparse
import collections
import json
import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "clients", "python"))
from npfkct_client import ApiError, NpfkctClient, World  # noqa: E402

KEY = "soak-key"
SCENES = ("loose1", "loose2", "hidden1", "covered1", "complex1")


def rss_summary(samples, warm):
    """The resident memory from `warm` seconds on: its range, the spread (max - min) / min of the
    raw 10 s samples and of their 5-minute medians (plans come and go: a sample is one moment of
    eight search trees), and the least-squares trend in MB per hour."""
    kept = [(t, m) for t, m in samples if m is not None and t >= warm]
    if len(kept) < 2:
        return {"warm_from_s": round(warm), "samples": len(kept)}
    values = [m for _, m in kept]
    windows = collections.defaultdict(list)
    for t, m in kept:
        windows[int((t - warm) // 300)].append(m)
    medians = [sorted(v)[len(v) // 2] for _, v in sorted(windows.items())]
    mean_t = sum(t for t, _ in kept) / len(kept)
    mean_m = sum(values) / len(values)
    slope = (sum((t - mean_t) * (m - mean_m) for t, m in kept) /
             max(1e-9, sum((t - mean_t) ** 2 for t, _ in kept)))
    return {"warm_from_s": round(warm), "samples": len(kept), "min": min(values),
            "max": max(values), "spread": (max(values) - min(values)) / min(values),
            "five_minute_medians": medians,
            "median_spread": (max(medians) - min(medians)) / min(medians),
            "trend_mb_per_hour": slope * 3600.0}


def percentile(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, int(round(q * (len(values) - 1))))] if values else None


class Server:
    """npfkct-server on a port, restartable on the same state directory."""

    def __init__(self, binary, state, port):
        self.binary, self.state, self.port, self.proc = binary, state, port, None
        self.url = f"http://127.0.0.1:{port}"

    def start(self):
        self.proc = subprocess.Popen(
            [self.binary, "--port", str(self.port), "--state-dir", self.state, "--api-key", KEY,
             "--log-level", "warn"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        client = NpfkctClient(self.url, api_key=KEY, timeout=5)
        for _ in range(600):
            try:
                client.health()
                return
            except Exception:  # noqa: BLE001 - not up yet
                time.sleep(0.1)
        raise RuntimeError("the server did not start")

    def kill(self):
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait()

    def stop(self):
        self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait()

    def rss_mb(self):
        try:
            with open(f"/proc/{self.proc.pid}/status", encoding="ascii") as f:
                for line in f:
                    if line.startswith("VmRSS:"):
                        return int(line.split()[1]) / 1024
        except OSError:
            return None
        return None


class Tally:
    """What the robots saw, shared by their threads."""

    def __init__(self):
        self.lock = threading.Lock()
        self.statuses = collections.Counter()  # HTTP status of every failed call
        self.messages = {}  # status -> the first message seen with it
        self.latency = collections.defaultdict(list)  # phase -> [plan round trip s]
        self.sessions = []  # (session id, steps acknowledged, observes sent unacknowledged)
        self.episodes = 0
        self.phase = "steady"
        self.calls_in_flood = 0

    def error(self, e):
        status = getattr(e, "http_status", 0) or "connection"
        with self.lock:
            self.statuses[status] += 1
            self.messages.setdefault(status, f"{self.phase}: {str(e)[:160]}")


class Robot(threading.Thread):
    def __init__(self, index, server, args, tally, stop):
        super().__init__(daemon=True)
        self.index, self.server, self.args, self.tally, self.stop = index, server, args, tally, stop
        self.client = NpfkctClient(server.url, api_key=KEY, timeout=120)
        self.rng = random.Random(index)

    def call(self, fn):
        """fn() until it answers: connection errors, 429 and 503 are waited out (a robot keeps
        going); other errors are raised."""
        delay = 0.2
        while not self.stop.is_set():
            try:
                return fn()
            except ApiError as e:
                self.tally.error(e)
                if e.http_status not in (0, 429, 503):
                    raise
            except OSError as e:
                self.tally.error(e)
            time.sleep(delay)
            delay = min(5.0, delay * 2)
        raise RuntimeError("stopped")

    def run(self):
        while not self.stop.is_set():
            try:
                self.episode()
            except RuntimeError:
                return

    def episode(self):
        scene = self.rng.choice(SCENES)
        seed = self.rng.randrange(1, 10**6)
        world = World.from_scenario(os.path.join(ROOT, "scenarios", scene + ".json"))
        session = self.call(lambda: self.client.create_session(world, planner="npfkct",
                                                               seed=seed))
        sim = subprocess.Popen([os.path.join(self.args.build, "bin", "npfkct-sim-robot"),
                                "--scenario", os.path.join(ROOT, "scenarios", scene + ".json"),
                                "--seed", str(seed)], stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE, text=True)
        acknowledged, unknown = 0, 0
        try:
            for _ in range(50):
                if self.stop.is_set():
                    break
                t0 = time.monotonic()
                try:
                    plan = self.call(lambda: self.client.plan(session.id, cpu_ms=self.args.cpu_ms))
                    action_id, action = plan.action_id, plan.action.to_json()
                except ApiError as e:
                    if e.status != "FAILED_PRECONDITION":
                        raise
                    # A plan whose reply was lost left its action pending: execute that one.
                    pending = self.call(lambda: self.client.get_session(session.id)).raw.get(
                        "pendingAction")
                    if not pending:
                        raise
                    action_id, action = pending["actionId"], pending["action"]
                with self.tally.lock:
                    self.tally.latency[self.tally.phase].append(time.monotonic() - t0)
                sim.stdin.write(json.dumps(action) + "\n")
                sim.stdin.flush()
                reply = json.loads(sim.stdout.readline())
                try:
                    observed = self.call(lambda: self.client.observe(
                        session.id, action_id, body=reply["observation"]))
                    acknowledged += 1
                    done = observed.done
                except ApiError as e:
                    if e.status != "FAILED_PRECONDITION":
                        raise
                    # The observation had reached the server: its step is taken.
                    now = self.call(lambda: self.client.get_session(session.id))
                    if now.pending_action_id == action_id:
                        raise
                    unknown += 1
                    done = now.state == "DONE"
                if done:
                    break
        except ApiError as e:
            self.tally.error(e)
        finally:
            sim.stdin.close()
            sim.wait()
        # As a robot using the SDK does (with ... as session): the session goes when the episode
        # ends, after its step count was checked against what this robot sent.
        try:
            step = self.call(lambda: self.client.get_session(session.id)).step
            self.call(lambda: self.client.delete_session(session.id))
        except (ApiError, RuntimeError):
            step = None
        with self.tally.lock:
            self.tally.sessions.append((session.id, acknowledged, unknown, step))
            self.tally.episodes += 1


def connections(url, count):
    """Up to `count` connections to the server, opened and left without a byte."""
    port = int(url.rsplit(":", 1)[1])
    held = []
    for _ in range(count):
        try:
            held.append(socket.create_connection(("127.0.0.1", port), timeout=5))
        except OSError:
            pass
    return held


def hold_idle(url, count, seconds, stop):
    held = connections(url, count)
    stop.wait(seconds)
    for s in held:
        s.close()


def slow_heads(url, count, seconds, stop):
    held = connections(url, count)
    head = b"GET /v1/sessions HTTP/1.1\r\nHost: x\r\n" + b"X: " + b"a" * 200
    end = time.monotonic() + seconds
    i = 0
    while time.monotonic() < end and not stop.is_set():
        for s in list(held):
            try:
                s.send(head[i % len(head):i % len(head) + 1])
            except OSError:
                held.remove(s)
        i += 1
        stop.wait(1.0)
    for s in held:
        s.close()


def flood(url, seconds, stop, opened):
    port = int(url.rsplit(":", 1)[1])
    held = collections.deque()
    end = time.monotonic() + seconds
    while time.monotonic() < end and not stop.is_set():
        try:
            held.append(socket.create_connection(("127.0.0.1", port), timeout=2))
            opened[0] += 1
        except OSError:
            time.sleep(0.01)
        while len(held) > 1000:
            held.popleft().close()
    for s in held:
        s.close()


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--robots", type=int, default=8)
    parser.add_argument("--cpu-ms", type=float, default=100.0)
    parser.add_argument("--disk-mb", type=int, default=64)
    parser.add_argument("--build", default=os.path.join(ROOT, "build"))
    parser.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "soak",
                                                      "soak.json"))
    parser.add_argument("--summarize", metavar="JSON",
                        help="recompute the RSS summary of a soak's JSON (in place) and exit")
    args = parser.parse_args()
    if args.summarize:
        with open(args.summarize, encoding="utf-8") as f:
            summary = json.load(f)
        restarted = next((t for t, what in summary["events"] if what == "restarted"), 0.0)
        warm = restarted + min(600.0, summary["minutes"] * 10.0)
        summary["rss_mb"] = dict(rss_summary(summary["rss_samples"], warm),
                                 first=summary["rss_samples"][0][1],
                                 last=summary["rss_samples"][-1][1])
        with open(args.summarize, "w", encoding="utf-8") as f:
            json.dump(summary, f, indent=1)
        print(json.dumps(summary["rss_mb"], indent=1))
        return
    if os.geteuid() != 0:
        sys.exit("soak.py: needs root (the state directory is a tmpfs that it fills)")
    total = args.minutes * 60.0
    work = tempfile.mkdtemp(prefix="npfkct-soak-")
    state = os.path.join(work, "state")
    os.makedirs(state)
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={args.disk_mb}m", "tmpfs", state],
                   check=True)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = Server(os.path.join(args.build, "bin", "npfkct-server"), state, port)
    server.start()
    tally, stop = Tally(), threading.Event()
    robots = [Robot(i, server, args, tally, stop) for i in range(args.robots)]
    for r in robots:
        r.start()
    start = time.monotonic()
    rss, events, fault_stop = [], [], threading.Event()
    done = {"kill": False, "disk": False, "idle": False, "flood": False}
    filler = os.path.join(state, "filler")
    flood_opened = [0]
    probe = NpfkctClient(server.url, api_key=KEY, timeout=10)
    flood_probe = {"ok": 0, "failed": 0}
    try:
        while (elapsed := time.monotonic() - start) < total:
            share = elapsed / total
            if share >= 0.25 and not done["kill"]:
                done["kill"] = True
                server.kill()
                events.append((elapsed, "kill -9"))
                tally.phase = "restart"
                server.start()
                events.append((time.monotonic() - start, "restarted"))
                tally.phase = "steady"
            if share >= 0.45 and not done["disk"]:
                done["disk"] = True
                tally.phase = "disk full"
                events.append((elapsed, "disk full"))
                subprocess.run(["dd", "if=/dev/zero", f"of={filler}", "bs=1M",
                                f"count={args.disk_mb}"], stderr=subprocess.DEVNULL)
                time.sleep(60)
                os.remove(filler)
                events.append((time.monotonic() - start, "disk freed"))
                tally.phase = "steady"
            if share >= 0.55 and not done["idle"]:
                done["idle"] = True
                seconds = 0.1 * total
                events.append((elapsed, "idle and slow clients"))
                for fn, n in ((hold_idle, 200), (slow_heads, 100)):
                    threading.Thread(target=fn, args=(server.url, n, seconds, fault_stop),
                                     daemon=True).start()
            if share >= 0.75 and not done["flood"]:
                done["flood"] = True
                tally.phase = "flood"
                events.append((elapsed, "unauthenticated flood"))
                t = threading.Thread(target=flood,
                                     args=(server.url, 0.05 * total, fault_stop, flood_opened),
                                     daemon=True)
                t.start()
                while t.is_alive():
                    try:
                        probe.list_sessions(page_size=1)
                        flood_probe["ok"] += 1
                    except (ApiError, OSError):
                        flood_probe["failed"] += 1
                    time.sleep(1.0)
                events.append((time.monotonic() - start, "flood over"))
                tally.phase = "steady"
            rss.append((round(time.monotonic() - start, 1), server.rss_mb()))
            time.sleep(10.0)
    finally:
        stop.set()
        fault_stop.set()
        for r in robots:
            r.join(timeout=180)
    # Lost and doubled steps: each session's server count against what its robot sent.
    lost = doubled = checked = 0
    for _, acknowledged, unknown, step in tally.sessions:
        if step is None:
            continue
        checked += 1
        lost += step < acknowledged
        doubled += step > acknowledged + unknown
    exit_code = server.stop()
    subprocess.run(["umount", state], check=False)
    # Flat after a warm-up of 10 minutes (a sixth of a shorter run) of the process that served
    # the rest of the run, the one started after the kill.
    restarted = next((t for t, what in events if what == "restarted"), 0.0)
    warm = restarted + min(600.0, total / 6)
    summary = {
        "minutes": args.minutes, "robots": args.robots, "cpu_ms": args.cpu_ms,
        "episodes": tally.episodes, "sessions_checked": checked, "lost_steps": lost,
        "doubled_steps": doubled,
        "errors_by_status": {str(k): v for k, v in sorted(tally.statuses.items(), key=str)},
        "error_messages": {str(k): v for k, v in tally.messages.items()},
        "rss_mb": dict(rss_summary(rss, warm), first=rss[0][1] if rss else None,
                       last=rss[-1][1] if rss else None),
        "plan_latency_s": {phase: {"n": len(v), "p50": percentile(v, 0.5),
                                   "p99": percentile(v, 0.99), "max": max(v)}
                           for phase, v in tally.latency.items()},
        "flood": {"connections_opened": flood_opened[0], "robot_calls": flood_probe},
        "events": events, "server_exit": exit_code,
        "load_average": os.getloadavg(), "rss_samples": rss,
    }
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w", encoding="utf-8") as f:
        json.dump(summary, f, indent=1)
    print(json.dumps({k: v for k, v in summary.items() if k != "rss_samples"}, indent=1))


if __name__ == "__main__":
    main()
