#!/usr/bin/env python3
"""Raw frames on a house-sized SLAM map (issue 40's acceptance): sessions whose world is a 40 m x
40 m occupancy grid at 5 cm (640,000 cells, walls on its border) with three traced workspaces
(Loose1's table and two more tables 10-15 m away), each driven through its episode by the
simulated robot of Loose1 sending rendered 640 x 480 RGB-D frames (npfkct-sim-robot --raw) to
the server's perception. Reports the server's CPU time per :observe (the first frame of a
session, and the median of the later ones: JSON, base64, registration, segmentation, SIFT) and
the perception pipeline's own wall-clock time within it (perception.timingsMs.total), and the
server's resident memory per session kept (after the sessions, less before them, over the
sessions).
Writes bench/results/maps/house_grid.json (with --plain, Loose1's own world, the baseline:
plain_room.json).

Usage: bench/bench_house_map.py [--sessions 3] [--steps 8] [--plain]   (env: BUILD_DIR)"""
import argparse
import base64
import json
import os
import statistics
import subprocess
import sys

import requests

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.environ.get("BUILD_DIR", os.path.join(ROOT, "build"))
sys.path.insert(0, os.path.join(ROOT, "clients", "python"))
from npfkct_client import traced_workspaces  # noqa: E402
from npfkct_client import World  # noqa: E402

SIDE, RES = 40.0, 0.05


def cpu_seconds(pid):
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def rss_mb(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS"):
            return int(line.split()[1]) / 1024
    return 0.0


def house_world():
    loose1 = World.from_scenario(os.path.join(ROOT, "scenarios", "loose1.json"))
    n = round(SIDE / RES)
    cells = bytearray(n * n)
    for i in range(n):
        for k in (0, n - 1):
            cells[k * n + i] = cells[i * n + k] = 100
    tables = traced_workspaces(loose1)
    for name, (x, y) in (("kitchen", (10.0, 10.0)), ("desk", (-12.0, 5.0))):
        tables.append({"name": name, "height": 0.75,
                       "polygon": [[x - 0.6, y - 0.4], [x + 0.6, y - 0.4], [x + 0.6, y + 0.4],
                                   [x - 0.6, y + 0.4]]})
    return {"robot": loose1["robot"], "start": loose1["start"], "workspaces": tables,
            "occupancyGrid": {"resolution": RES, "origin": [-SIDE / 2, -SIDE / 2, 0.0],
                              "width": n, "height": n,
                              "data": base64.b64encode(bytes(cells)).decode()}}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sessions", type=int, default=3)
    parser.add_argument("--steps", type=int, default=8)
    parser.add_argument("--plain", action="store_true",
                        help="Loose1's own 7 m x 6.5 m world instead (the baseline)")
    args = parser.parse_args()
    robot_bin = os.path.join(BUILD, "bin", "npfkct-sim-robot")
    scenario = os.path.join(ROOT, "scenarios", "loose1.json")
    photos = json.loads(subprocess.run([robot_bin, "--scenario", scenario, "--target-photos"],
                                       check=True, capture_output=True, text=True).stdout)
    server = subprocess.Popen([os.path.join(BUILD, "bin", "npfkct-server"), "--port", "0",
                               "--log-level", "warn"], stdout=subprocess.PIPE, text=True)
    url = "http://" + server.stdout.readline().split()[-1]
    pid = server.pid
    world = (World.from_scenario(scenario) if args.plain else house_world())
    first, later, kept, pipeline = [], [], [], []
    try:
        base = rss_mb(pid)
        for s in range(args.sessions):
            before = rss_mb(pid)
            r = requests.post(url + "/v1/sessions", json={
                "world": world, "seed": s + 1, "target": {"photos": photos}}, timeout=60)
            r.raise_for_status()
            sid = r.json()["id"]
            robot = subprocess.Popen([robot_bin, "--scenario", scenario, "--seed", str(s + 1),
                                      "--raw"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     text=True)
            frames = 0
            for _ in range(args.steps):
                plan = requests.post(f"{url}/v1/sessions/{sid}:plan",
                                     json={"budget": {"simulations": 200}}, timeout=60).json()
                robot.stdin.write(json.dumps(plan["action"]) + "\n")
                robot.stdin.flush()
                reply = json.loads(robot.stdout.readline())
                body = dict(reply["observation"], actionId=plan["actionId"])
                cpu = cpu_seconds(pid)
                o = requests.post(f"{url}/v1/sessions/{sid}:observe", json=body, timeout=60)
                o.raise_for_status()
                if "pointCloud" in body:
                    (first if frames == 0 else later).append(1000 * (cpu_seconds(pid) - cpu))
                    if frames > 0:
                        pipeline.append(o.json()["perception"]["timingsMs"])
                        if os.environ.get("VERBOSE"):
                            p = o.json()["perception"]
                            print(p["registration"], p["fitness"], p["clusters"],
                                  {k: round(v) for k, v in p["timingsMs"].items()}, flush=True)
                    frames += 1
                if o.json()["done"]:
                    break
            robot.stdin.close()
            robot.wait()
            kept.append(rss_mb(pid) - before)
            print(f"session {s + 1}: {frames} frames, first {first[-1]:.0f} ms of CPU, "
                  f"resident memory +{kept[-1]:.1f} MB", flush=True)
        total = rss_mb(pid) - base
    finally:
        server.terminate()
        server.wait()
    summary = {"map": "Loose1's own world" if args.plain else
               "40 m x 40 m occupancy grid at 5 cm, three workspaces",
               "frames": "640x480 rendered RGB-D (npfkct-sim-robot --raw, Loose1)",
               "first_frame_cpu_ms": first, "median_later_frame_cpu_ms": statistics.median(later),
               "later_frames": len(later),
               "median_later_frame_pipeline_ms": {
                   stage: statistics.median(t[stage] for t in pipeline)
                   for stage in ("registration", "segmentation", "association", "detection",
                                 "total")},
               "kept_mb_per_session": kept,
               "kept_mb_per_session_mean": total / args.sessions}
    print(json.dumps({k: v for k, v in summary.items() if k != "frames"}, indent=1))
    out = os.path.join(ROOT, "bench", "results", "maps")
    os.makedirs(out, exist_ok=True)
    name = "plain_room.json" if args.plain else "house_grid.json"
    with open(os.path.join(out, name), "w", encoding="utf-8") as f:
        json.dump(summary, f, indent=1)


if __name__ == "__main__":
    main()
