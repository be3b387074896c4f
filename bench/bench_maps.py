#!/usr/bin/env python3
"""A prior map from SLAM against the hand-written one: Loose1 driven by npfkct-drive N times with
the session created from the scenario's furniture and base regions, and N times (the same seeds)
from the same room rasterised into map_server's YAML + PGM pair (npfkct_client.write_map_files),
the table traced as a polygon with its height and no base regions (the server places them around
it). The simulated robot sees the scenario's truth either way. Prints mean discounted reward and
steps with two-sided 95% Student's t intervals, and the paired difference; writes them to
bench/results/maps/SCENARIO.json.

Usage: bench/bench_maps.py [--scenario loose1] [--trials 20] [--cpu-ms 250] [--planner npfkct]
(env: BUILD_DIR, default build/)"""
import argparse
import json
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.environ.get("BUILD_DIR", os.path.join(ROOT, "build"))
sys.path.insert(0, os.path.join(ROOT, "clients", "python"))
from npfkct_client import slam_world, write_map_files  # noqa
from npfkct_client import World  # noqa

# Two-sided 95% quantiles of Student's t by degrees of freedom (30 and more: 2.0).
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
       9: 2.262, 10: 2.228, 11: 2.201, 12: 2.179, 13: 2.160, 14: 2.145, 15: 2.131, 16: 2.120,
       17: 2.110, 18: 2.101, 19: 2.093, 20: 2.086, 24: 2.064, 29: 2.045}


def interval(values):
    n = len(values)
    if n < 2:
        return statistics.mean(values), float("nan")
    t = T95.get(n - 1) or (2.0 if n > 30 else T95[max(k for k in T95 if k <= n - 1)])
    return statistics.mean(values), t * statistics.stdev(values) / math.sqrt(n)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="loose1")
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--cpu-ms", type=float, default=250)
    parser.add_argument("--planner", default="npfkct")
    args = parser.parse_args()
    scenario = os.path.join(ROOT, "scenarios", args.scenario + ".json")
    world = World.from_scenario(scenario)
    scratch = tempfile.mkdtemp(prefix="npfkct-maps-")
    slam = slam_world(world, write_map_files(world, scratch))
    slam_path = os.path.join(scratch, "world.json")
    with open(slam_path, "w", encoding="utf-8") as f:
        json.dump(slam, f)

    server = subprocess.Popen([os.path.join(BUILD, "bin", "npfkct-server"), "--port", "0",
                               "--log-level", "warn"], stdout=subprocess.PIPE, text=True)
    url = "http://" + server.stdout.readline().split()[-1]
    results = {"hand-written": [], "slam-map": []}
    try:
        for seed in range(1, args.trials + 1):
            for form, extra in (("hand-written", []), ("slam-map", ["--world", slam_path])):
                out = subprocess.run(
                    [os.path.join(BUILD, "bin", "npfkct-drive"), "--server", url, "--scenario",
                     scenario, "--planner", args.planner, "--cpu-ms", str(args.cpu_ms),
                     "--seed", str(seed), "--quiet", *extra],
                    capture_output=True, text=True, timeout=900, check=True).stdout
                m = re.search(r"after (\d+) steps, discounted reward (-?[\d.]+)", out)
                found = "target removed" in out
                results[form].append({"seed": seed, "steps": int(m.group(1)) if m else None,
                                      "reward": float(m.group(2)) if m else None,
                                      "success": found})
    finally:
        server.terminate()
        server.wait()
    summary = {"scenario": args.scenario, "planner": args.planner, "cpu_ms": args.cpu_ms,
               "trials": args.trials, "interval": "two-sided 95% Student's t", "forms": {}}
    for form, trials in results.items():
        reward = interval([t["reward"] for t in trials])
        steps = interval([t["steps"] for t in trials])
        summary["forms"][form] = {"mean_reward": reward[0], "ci95": reward[1],
                                  "mean_steps": steps[0], "ci95_steps": steps[1],
                                  "success_rate": sum(t["success"] for t in trials) / len(trials),
                                  "trials": trials}
        print(f"{form:13s} reward {reward[0]:9.1f} ± {reward[1]:7.1f}  steps {steps[0]:5.2f} ± "
              f"{steps[1]:4.2f}  success {summary['forms'][form]['success_rate']:.0%}")
    diff = interval([b["reward"] - a["reward"]
                     for a, b in zip(results["hand-written"], results["slam-map"])])
    summary["paired_reward_difference"] = {"mean": diff[0], "ci95": diff[1]}
    print(f"slam-map - hand-written, paired by seed: {diff[0]:.1f} ± {diff[1]:.1f}")
    out_dir = os.path.join(ROOT, "bench", "results", "maps")
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, args.scenario + ".json"), "w", encoding="utf-8") as f:
        json.dump(summary, f, indent=1)


if __name__ == "__main__":
    main()
