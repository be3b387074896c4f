#!/usr/bin/env python3
"""Builds the benchmark tables from npfkct-bench JSON lines, and docs/benchmarks.md from them.

  results_table.py docs [--write]  The whole of docs/benchmarks.md from the files in
                                   bench/results (to stdout; --write writes the file):
                                   every table below, each with the commands that make its cells.

  results_table.py table1 DIR [DIR ...]
                                   Table 1 from DIR/SCENE/PLANNER.jsonl (bench/bench_table1.sh):
                                   reward ± 95% CI | steps ± 95% CI | success, and each planner's
                                   mean reward as a share of the oracle's in the same scene. With
                                   several runs a cell comes from the first DIR that has it, and
                                   a last column names each planner's run(s).
  results_table.py generated DIR [SCENES]
                                   The held-out generated scenes (bench/bench_generated.sh): per
                                   planner, the mean over scenes of its share of the oracle's
                                   reward with a Student's t interval over the scenes, success rate
                                   and mean steps over every trial; with SCENES (the folder of
                                   the gen-SEED.json files) the same shares and steps per
                                   placement of the target (in the open, hidden, covered), which
                                   each scene's description names.
  results_table.py ablation DIR    The ablation (bench/bench_ablation.sh): rows from
                                   DIR/ROW/SCENE.jsonl in the script's order, a column per scene
                                   and the mean reward over the scenes; with an oracle row (the
                                   generated scenes) each row's share of the oracle's reward and
                                   its change against the row above, paired over the scenes.
  results_table.py sensitivity DIR The sensitivity of the defaults (bench/bench_sensitivity.sh):
                                   per row of DIR/ROW/SEED.jsonl its share of the oracle's reward
                                   and its change against the row "defaults", paired over scenes.
  results_table.py estimator DIR [SCENES]
                                   The estimator experiments on the v2 tuning scenes
                                   (bench/bench_estimator.sh): per row of DIR/ROW/SEED.jsonl its
                                   share of the oracle's reward, target-only share, steps and
                                   success, and the changes against the row "defaults", paired
                                   over the scenes; with the scene files, steps per placement.
  results_table.py mirror DIR      Paper scenes beside their mirror images
                                   (bench/bench_mirror.sh): per planner and scene the reward,
                                   steps and how many trials' first view saw the target
                                   (DIR/SCENE/PLANNER.first-views, the step-1 lines of --trace).
  results_table.py trace FILE      What the trials of an npfkct-bench --trace file did, per scene
                                   and planner: steps, moves, moves made while an object the
                                   trial removes later could already be declared, obstacles
                                   declared and how many of them were removed later, means per
                                   trial.
  results_table.py steps DIR SCENES
                                   Where the steps go, per row of DIR/ROW.trace.gz
                                   (bench/bench_estimator.sh with TRACE=1) and per placement of
                                   the target: the trace figures above, obstacles declared and
                                   never removed, and success.
  results_table.py compare A B     Whether two runs of the same cells agree: each mean inside the
                                   other run's 95% interval.
  results_table.py flat FILE       A table from one file of JSON lines (rows planners, columns
                                   scenarios), as written by --observe comparisons.
  results_table.py threads ONE TWO The thread scaling (bench/bench_threads.sh): simulations per
                                   second with 1 and 2 search threads, and the rewards.
  results_table.py model-speed DIR The model's simulation speed, base and new builds
                                   (bench/bench_model_speed.sh, DIR/{base,new}-rN.jsonl).
  results_table.py classic FILE    The classic problems beside their published results
                                   (bench/bench_classic.sh, bench/results/classic.jsonl).
  results_table.py classic-paired FILE [BASE_PLANNER]
                                   Runs on a classic problem with one seed compared episode by
                                   episode (npfkct-bench's episode_returns): each against the run
                                   of its group with the fewest options; with BASE_PLANNER,
                                   every planner's runs against that planner's; then each
                                   comparison made on several seeds, pooled.
  results_table.py lightdark-leaf FILE [FILE ...]
                                   SimpleLightDark's leaf values (bench/bench_classic.sh
                                   lightdark-leaf): the first file's runs; episode by episode,
                                   each run with the detour leaf against the fully observable one
                                   of the same planner, seed, episodes and budget (any file), and
                                   each fully observable run against the one before it (more
                                   search).
  results_table.py lightdark-optimum FILE
                                   SimpleLightDark's reference (bench/bench_classic.sh
                                   lightdark-optimum): the last perseus-binned record of FILE,
                                   its bounds and policy, the lookaheads by leaf value, and the
                                   traced planner's decisions scored against it.
  results_table.py despot FILE     The solver beside the authors' DESPOT on RockSample(7,8)
                                   (bench/bench_despot.sh, one JSON line per planner and episode):
                                   return ± standard error, steps, trials per step, and each
                                   planner's difference to the original.
  results_table.py filter EVAL BENCH
                                   The neural filter's accuracy and time (tools/train_filter.sh:
                                   filter_eval.json, filter_bench.json).
  results_table.py perception-stages FILE
                                   The perception pipeline's time per stage
                                   (npfkct-perception-bench, perception_stages.json).
  results_table.py load FILE       One server under many sessions (bench/load_bench.py).
  results_table.py maps DIR        A SLAM map against the hand-written one, and raw frames on a
                                   house-sized map (bench/bench_maps.py, bench_house_map.py).
  results_table.py fleet FILE      A fleet's throughput and failover (bench/fleet_bench.py).

Intervals are two-sided 95% Student's t intervals of the mean (n - 1 degrees of freedom); the bench
writes them per cell, and this script computes them the same way for derived figures.
"""

import contextlib
import glob
import gzip
import io
import json
import math
import os
import re
import statistics
import sys

PAPER_SCENES = ["Loose1", "Loose2", "Hidden1", "Covered1", "Complex1", "Fig16"]
PLANNER_ORDER = ["oracle", "oracle-cover-unknown", "npfkct", "npfkct-paper", "kct", "pomcp",
                 "gpomcp", "pomcp-joint", "pomcpow", "vomcpow", "advt"]


def _beta_cf(x, a, b):
    tiny, eps = 1e-300, 1e-15
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * x / qap
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 501):
        m2 = 2 * m
        for aa in (m * (b - m) * x / ((qam + m2) * (a + m2)),
                   -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))):
            d = 1.0 + aa * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + aa / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1.0) < eps:
            break
    return h


def _ibeta(x, a, b):
    if x <= 0:
        return 0.0
    if x >= 1:
        return 1.0
    front = math.exp(math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b)
                     + a * math.log(x) + b * math.log1p(-x))
    if x < (a + 1) / (a + b + 2):
        return front * _beta_cf(x, a, b) / a
    return 1.0 - front * _beta_cf(1 - x, b, a) / b


def t_quantile(p, df):
    """The p-quantile of Student's t with df degrees of freedom (p > 0.5)."""
    def cdf(t):
        return 1.0 - 0.5 * _ibeta(df / (df + t * t), 0.5 * df, 0.5)
    lo, hi = 0.0, 1.0
    while cdf(hi) < p:
        hi *= 2
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if cdf(mid) < p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def mean_ci(values):
    n = len(values)
    if n == 0:
        return float("nan"), 0.0
    m = sum(values) / n
    if n < 2:
        return m, 0.0
    sd = math.sqrt(sum((v - m) ** 2 for v in values) / (n - 1))
    return m, t_quantile(0.975, n - 1) * sd / math.sqrt(n)


def paired_difference(new, base):
    """Per key both dicts have (a scene), new minus base: the mean, its 95% t interval, and how
    many keys it is over."""
    diffs = [new[k] - base[k] for k in new if k in base]
    m, ci = mean_ci(diffs)
    return m, ci, len(diffs)


def json_lines(path):
    """The JSON objects of a JSON-lines file, blank lines skipped."""
    with open(path, encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]


def load_cells(root, key=lambda path, r: (r["scenario"], r["planner"])):
    """{key(path, record): record} from ROOT/*/*.jsonl; by default keyed (scene, planner)."""
    cells = {}
    for path in sorted(glob.glob(os.path.join(root, "*", "*.jsonl"))):
        with open(path, encoding="utf-8") as f:
            line = f.readline()
        if line.strip():
            r = json.loads(line)
            cells[key(path, r)] = r
    return cells


def load_row_cells(root):
    """Cells of DIR/ROW/SCENE.jsonl (the ablation and the sensitivity), keyed (row, scenario): the
    row is the record's folder."""
    return load_cells(root, key=lambda path, r: (os.path.basename(os.path.dirname(path)),
                                                 r["scenario"]))


def order(names, preferred):
    return [n for n in preferred if n in names] + sorted(n for n in names if n not in preferred)


def cell_text(r):
    return (f"{r['mean_discounted_reward']:.1f} ± {r['ci95']:.1f} \\| "
            f"{r['mean_steps']:.1f} ± {r['ci95_steps']:.1f} \\| {100 * r['success_rate']:.0f}%")


def planner_table(planners, columns, cell):
    """Prints a Markdown table with a row per planner and a column per header in COLUMNS;
    cell(planner, column) is a cell's text, or None for a missing cell (printed "–")."""
    print("| Planner |" + "".join(f" {c} |" for c in columns))
    print("|---|" + "---|" * len(columns))
    for p in planners:
        texts = (cell(p, c) for c in columns)
        print(f"| {p} |" + "".join(" – |" if t is None else f" {t} |" for t in texts))


def table1(*roots):
    cells, runs = {}, {}
    for root in roots:
        for key, r in load_cells(root).items():
            if key not in cells:
                cells[key] = r
                runs.setdefault(key[1], set()).add(os.path.basename(os.path.normpath(root)))
    scenes = order({s for s, _ in cells}, PAPER_SCENES)
    planners = order({p for _, p in cells}, PLANNER_ORDER)
    budget = {(r["cpu_ms"], r["trials"]) for r in cells.values()}
    print(f"Cells: discounted reward ± 95% t interval \\| steps ± 95% t interval \\| success "
          f"rate; budgets and trials (cpu_ms, trials): {sorted(budget)}.\n")
    sims = "sims/CPU-s (Complex1)"
    run_column = ["Run"] if len(roots) > 1 else []

    def reward_cell(p, s):
        if s == "Run":
            return ", ".join(sorted(runs[p]))
        if s == sims:
            r = cells.get(("Complex1", p))
            return None if r is None or p == "oracle" else f"{r['median_sims_per_cpu_second']:.0f}"
        r = cells.get((s, p))
        return None if r is None else cell_text(r)

    planner_table(planners, scenes + [sims] + run_column, reward_cell)
    print("\nMean reward as a share of the oracle's in the same scene:\n")

    def share_cell(p, s):
        r, o = cells.get((s, p)), cells.get((s, "oracle"))
        if r is None or o is None or o["mean_discounted_reward"] <= 0:
            return None
        return f"{100 * r['mean_discounted_reward'] / o['mean_discounted_reward']:.0f}%"

    planner_table([p for p in planners if p != "oracle"], scenes, share_cell)


def oracle_summary(cells, groups, scenes):
    """Per group (planner or ablation row): the mean over scenes of its share of the oracle's reward
    (t interval over scenes), success rate and mean steps over every trial, and the per-scene shares.
    `cells` is keyed (group, scene) and holds the oracle as the group "oracle"."""
    out = {}
    for g in groups:
        shares, target_shares, successes, steps, n = {}, {}, [], [], 0
        for s in scenes:
            r, o = cells.get((g, s)), cells.get(("oracle", s))
            if r is None:
                continue
            n += 1
            successes += r.get("successes", [])
            steps += r.get("steps", [])
            if o is not None and o["mean_discounted_reward"] > 0:
                shares[s] = r["mean_discounted_reward"] / o["mean_discounted_reward"]
            # The reward without what obstacle declarations earned beyond a step's cost.
            if o is not None and r.get("target_rewards") and o.get("target_rewards"):
                mine, its = statistics.mean(r["target_rewards"]), statistics.mean(o["target_rewards"])
                if its > 0:
                    target_shares[s] = mine / its
        m, ci = mean_ci(list(shares.values()))
        tm, tci = mean_ci(list(target_shares.values()))
        sm, sci = mean_ci(steps)
        succ = 100 * sum(successes) / len(successes) if successes else float("nan")
        out[g] = {"share": m, "share_ci": ci, "target_share": tm, "target_share_ci": tci,
                  "success": succ, "steps": sm, "steps_ci": sci, "scenes": n, "shares": shares}
    return out


PLACEMENTS = [("in the open", "open"), ("hidden behind", "hidden"), ("covered by", "covered")]


def scene_placement(path):
    """The target's placement (open, hidden or covered) that npfkct-scenegen's description of the
    scene names, or None."""
    with open(path, encoding="utf-8") as f:
        description = json.load(f).get("description", "")
    for phrase, name in PLACEMENTS:
        if "the target " + phrase in description:
            return name
    return None


def by_placement(cells, planners, scenes, scenes_dir):
    """Prints each planner's share of the oracle's reward (t interval over the scenes of the
    group) and mean steps per placement of the target; cells keyed (planner, scene)."""
    groups = {}
    for s in scenes:
        path = os.path.join(scenes_dir, s + ".json")
        placement = scene_placement(path) if os.path.exists(path) else None
        groups.setdefault(placement or "unknown", []).append(s)
    names = order(set(groups), [name for _, name in PLACEMENTS])
    print("\nBy placement of the target (share of the oracle's reward ± 95% t interval over the "
          "group's scenes; mean steps over its trials):\n")
    column_group = {f"{name} ({len(groups[name])} scenes)": name for name in names}
    summaries = {name: oracle_summary(cells, planners, groups[name]) for name in names}

    def cell(p, column):
        x = summaries[column_group[column]][p]
        if x["scenes"] == 0:
            return None
        steps = f"{x['steps']:.1f} steps"
        if p == "oracle":
            return steps
        return f"{100 * x['share']:.1f}% ± {100 * x['share_ci']:.1f}, {steps}"

    planner_table(planners, list(column_group), cell)


def generated(root, scenes_dir=None):
    cells = {(p, s): r for (s, p), r in load_cells(root).items()}
    scenes = sorted({s for _, s in cells})
    planners = order({p for p, _ in cells}, PLANNER_ORDER)
    budget = {(r["cpu_ms"], r["trials"]) for r in cells.values()}
    print(f"{len(scenes)} held-out generated scenes; budgets and trials (cpu_ms, trials): "
          f"{sorted(budget)}. Share of the oracle: per scene the planner's mean reward over the "
          f"oracle's, then the mean over scenes ± 95% t interval over scenes.\n")
    summary = oracle_summary(cells, planners, scenes)
    with_target = any(x["target_share"] == x["target_share"] for x in summary.values())
    with_nbv = "nbv" in summary
    if with_target:
        print("Target-only share: the same for the reward without what obstacle declarations "
              "earned beyond a step's cost.")
    if with_nbv:
        print("vs nbv: the mean over scenes of the share minus nbv's in the same scene ± 95% t "
              "interval (paired).")
    columns = (["Share of the oracle's reward"] + (["Target-only share"] if with_target else [])
               + ["Success", "Steps"] + (["vs nbv"] if with_nbv else []) + ["Scenes"])
    if with_target or with_nbv:
        print()
    print("| Planner | " + " | ".join(columns) + " |")
    print("|---" * (len(columns) + 1) + "|")
    for p, x in summary.items():
        row = [f"{100 * x['share']:.1f}% ± {100 * x['share_ci']:.1f}"]
        if with_target:
            row.append(f"{100 * x['target_share']:.1f}% ± {100 * x['target_share_ci']:.1f}"
                       if x["target_share"] == x["target_share"] else "")
        row += [f"{x['success']:.1f}%", f"{x['steps']:.1f} ± {x['steps_ci']:.1f}"]
        if with_nbv:
            dm, dci, n = paired_difference(x["shares"], summary["nbv"]["shares"])
            row.append(f"{100 * dm:+.1f} ± {100 * dci:.1f}" if n and p != "nbv" else "")
        row.append(str(x["scenes"]))
        print(f"| {p} | " + " | ".join(row) + " |")
    if "npfkct" in summary and "kct" in summary:
        m, ci, _ = paired_difference(summary["npfkct"]["shares"], summary["kct"]["shares"])
        print(f"\nThe filter's worth, npfkct minus kct paired over the scenes: {100 * m:+.1f} ± "
              f"{100 * ci:.1f} points.")
    if scenes_dir is not None:
        by_placement(cells, planners, scenes, scenes_dir)


ABLATION_ROWS = ["paper", "aimed", "candidates", "sibling", "w2-rule", "filter", "rollout",
                 "ensemble"]
# Changes measured and not kept: each row and the kept row it changes (bench/bench_ablation.sh).
REJECTED_ROWS = {"visits": "sibling", "lcb": "filter"}


def ablation(root):
    cells = load_row_cells(root)
    rows = order({row for row, _ in cells}, ["oracle"] + ABLATION_ROWS + list(REJECTED_ROWS))
    scenes = order({s for _, s in cells}, PAPER_SCENES)
    if "oracle" in rows:
        ablation_shares(cells, rows, scenes)
        return
    print("| Row | Planner and options |" + "".join(f" {s} |" for s in scenes) + " Mean |")
    print("|---|---|" + "---|" * (len(scenes) + 1))
    for row in rows:
        line = f"| {row} | {row_planner(cells, row)} |"
        means = []
        for s in scenes:
            r = cells.get((row, s))
            if r is None:
                line += " – |"
            else:
                line += f" {cell_text(r)} |"
                means.append(r["mean_discounted_reward"])
        line += f" {sum(means) / len(means):.1f} |" if len(means) == len(scenes) else " – |"
        print(line)


def row_planner(cells, row):
    first = next(r for (rw, _), r in cells.items() if rw == row)
    opts = " ".join(first.get("options", []))
    # Cells from before npfkct-bench recorded its rollout ran the greedy one.
    rollout = first.get("rollout", "greedy")
    # The model when it is not the shipped one (cells before c8a7c60 ran the single network that
    # was shipped then, bench/models/filter-single.pt, under the name filter.pt).
    model = first.get("model", "filter.pt")
    model = f" --model {model}" if first["planner"] == "npfkct" and model != "filter.pt" else ""
    return f"`{first['planner']}{' ' + opts if opts else ''} --rollout {rollout}{model}`"


SHARE_HEADER = ("| Row | Planner and options | Share of the oracle's reward | Change | Success | "
                "Steps | Scenes |\n|---|---|---|---|---|---|---|")


def print_share_row(cells, summary, row, base, label):
    """One row of a table over many scenes: its mean share of the oracle's reward and its change
    against the row `base` as a paired difference over the scenes both rows have."""
    x = summary[row]
    change = "–"
    if base is not None:
        m, ci, n = paired_difference(x["shares"], summary[base]["shares"])
        if n:
            change = f"{100 * m:+.1f} ± {100 * ci:.1f}"
    print(f"| {label} | {row_planner(cells, row)} | {100 * x['share']:.1f}% ± "
          f"{100 * x['share_ci']:.1f} | {change} | {x['success']:.1f}% | "
          f"{x['steps']:.1f} ± {x['steps_ci']:.1f} | {x['scenes']} |")


def ablation_shares(cells, rows, scenes):
    """The ablation over many scenes (with an oracle row): each row's mean share of the oracle's
    reward, and the change against the row above as a paired difference over the scenes both
    rows have (mean ± 95% t interval)."""
    summary = oracle_summary(cells, rows, scenes)
    budget = {(r["cpu_ms"], r["trials"]) for r in cells.values()}
    print(f"{len(scenes)} scenes; budgets and trials (cpu_ms, trials): {sorted(budget)}. Change: "
          f"per scene the row's share minus the share of the row above, mean ± 95% t interval "
          f"over the scenes.\n")
    print(SHARE_HEADER)
    previous = None
    for row in rows:
        if row == "oracle" or row in REJECTED_ROWS:
            continue
        print_share_row(cells, summary, row, previous, row)
        previous = row
    rejected = [row for row in rows if row in REJECTED_ROWS]
    if rejected:
        print("\nTried and not kept (change: against the kept row it modifies):\n")
        print(SHARE_HEADER)
        for row in rejected:
            base = REJECTED_ROWS[row] if REJECTED_ROWS[row] in summary else None
            label = f"{row} (against {REJECTED_ROWS[row]})"
            print_share_row(cells, summary, row, base, label)


def estimator_switches(r):
    """The model and belief switches a cell ran with, beyond the planner and its options."""
    parts = []
    if r.get("obstacle_reward", "every") != "every":
        parts.append(f"--obstacle-reward {r['obstacle_reward']}")
    if r.get("grid_sampling", "probability") != "probability":
        parts.append(f"--grid-sampling {r['grid_sampling']}")
    if r.get("clear_macro"):
        parts.append("--clear-macro (not kept)")
    if r.get("plan_r_co") is not None:
        parts.append(f"--plan-r-co {r['plan_r_co']:g}")
    if r.get("min_cover_size"):
        parts.append(f"min_cover_size {r['min_cover_size']:g} (not kept)")
    for key, value in r.get("scene_params", {}).items():
        parts.append(f"scene {key} {value:g}")
    return " ".join(parts)


def estimator(root, scenes_dir=None):
    """The estimator experiments on the v2 tuning scenes (bench/bench_estimator.sh): rows from
    DIR/ROW/SEED.jsonl; per row its share of the oracle's reward, the target-only share, mean steps
    and success, each change against the row "defaults" paired over the scenes; with the scene
    files, the mean steps per placement of the target."""
    cells = load_row_cells(root)
    rows = order({row for row, _ in cells}, ["oracle", "oracle-cover-unknown", "nbv", "kct",
                                              "defaults"])
    scenes = sorted({s for _, s in cells})
    summary = oracle_summary(cells, rows, scenes)
    budget = {(r["cpu_ms"], r["trials"]) for r in cells.values()}
    print(f"{len(scenes)} v2 tuning scenes; budgets and trials (cpu_ms, trials): {sorted(budget)}. "
          f"Change: per scene the row's figure minus that of the defaults, mean ± 95% t interval "
          f"over the scenes the two rows share. Target-only: the reward without what obstacle "
          f"declarations earned beyond a step's cost.\n")
    print("| Row | Planner, options and switches | Share of the oracle's reward | Change | "
          "Target-only share | Steps | Change in steps | Success | Scenes |")
    print("|---|---|---|---|---|---|---|---|---|")

    def scene_steps(row):
        return {s: cells[(row, s)]["mean_steps"] for s in scenes if (row, s) in cells}

    base_steps = scene_steps("defaults") if "defaults" in summary else {}
    for row in rows:
        x = summary[row]
        change = step_change = "–"
        if row != "defaults" and base_steps:
            m, ci, _ = paired_difference(x["shares"], summary["defaults"]["shares"])
            change = f"{100 * m:+.1f} ± {100 * ci:.1f}"
            m, ci, _ = paired_difference(scene_steps(row), base_steps)
            step_change = f"{m:+.1f} ± {ci:.1f}"
        first = next(r for (rw, _), r in cells.items() if rw == row)
        switches = estimator_switches(first)
        planner = row_planner(cells, row)[:-1] + (f" {switches}`" if switches else "`")
        target = (f"{100 * x['target_share']:.1f}%" if x["target_share"] == x["target_share"]
                  else "")
        print(f"| {row} | {planner} | {100 * x['share']:.1f}% ± {100 * x['share_ci']:.1f} | "
              f"{change} | {target} | {x['steps']:.1f} | {step_change} | {x['success']:.1f}% | "
              f"{x['scenes']} |")
    if scenes_dir is not None:
        by_placement({(row, s): r for (row, s), r in cells.items()}, rows, scenes, scenes_dir)


def sensitivity(root):
    """The sensitivity of the defaults (bench/bench_sensitivity.sh): rows from DIR/ROW/SEED.jsonl,
    each row's share of the oracle's reward and its change against the row "defaults"."""
    cells = load_row_cells(root)
    rows = order({row for row, _ in cells}, ["oracle", "defaults"])
    scenes = sorted({s for _, s in cells})
    summary = oracle_summary(cells, rows, scenes)
    budget = {(r["cpu_ms"], r["trials"]) for r in cells.values()}
    print(f"{len(scenes)} tuning scenes; budgets and trials (cpu_ms, trials): {sorted(budget)}. "
          f"Change: per scene the row's share minus the share of the defaults, mean ± 95% t "
          f"interval over the scenes.\n")
    print(SHARE_HEADER)
    base = "defaults" if "defaults" in summary else None
    for row in rows:
        if row != "oracle":
            print_share_row(cells, summary, row, None if row == base else base, row)


def first_view_hits(path):
    """(trials whose first view detected the target, trials) from a file of step-1 trace lines,
    or None without the file. A trace line ends with the known objects after the step."""
    if not os.path.exists(path):
        return None
    lines = [line for line in open(path, encoding="utf-8") if " step  1: " in line]
    hits = sum(1 for line in lines if " target:" in line.rsplit("|", 1)[-1])
    return hits, len(lines)


def mirror(root):
    cells = load_cells(root, key=lambda path, r: (os.path.basename(os.path.dirname(path)),
                                                  r["planner"]))
    scenes = sorted({s for s, _ in cells})
    planners = order({p for _, p in cells}, PLANNER_ORDER)
    print("Cells: discounted reward ± 95% t interval \\| steps ± 95% t interval \\| trials whose "
          "first view saw the target.\n")

    def mirror_cell(p, s):
        r = cells.get((s, p))
        if r is None:
            return None
        hits = first_view_hits(os.path.join(root, s, p + ".first-views"))
        seen = "–" if hits is None else f"{hits[0]}/{hits[1]}"
        return (f"{r['mean_discounted_reward']:.1f} ± {r['ci95']:.1f} \\| "
                f"{r['mean_steps']:.2f} ± {r['ci95_steps']:.2f} \\| {seen}")

    planner_table(planners, scenes, mirror_cell)
    # A scene and its mirror image together: the side of the first view no longer favours
    # one planner's fixed preference.
    pairs = [s for s in scenes if s + "-mirrored" in scenes]
    if not pairs:
        return
    print("\nA scene and its mirror image together: mean reward ± 95% t interval over the trials "
          "of both cells.\n")

    def pooled_cell(p, column):
        s = column.removesuffix(" and mirrored")
        a, b = cells.get((s, p)), cells.get((s + "-mirrored", p))
        if a is None or b is None or "rewards" not in a or "rewards" not in b:
            return None
        m, ci = mean_ci(a["rewards"] + b["rewards"])
        return f"{m:.1f} ± {ci:.1f}"

    planner_table(planners, [s + " and mirrored" for s in pairs], pooled_cell)


TRACE_LINE = re.compile(r"^(\S+) (\S+) trial (\d+) step +(\d+): (move|declare obstacle|"
                        r"declare target|remove) ?(\S*)")


def trace_trials(path):
    """(scene, planner, trial) -> [(kind, object, objects that could be declared after it)] from
    an npfkct-bench --trace file (gzipped when its name ends in .gz); the bench marks an object
    that can be declared with * after its face counts."""
    trials = {}
    opener = gzip.open if path.endswith(".gz") else open
    for line in opener(path, "rt", encoding="utf-8"):
        m = TRACE_LINE.match(line)
        if m:
            known = line.rsplit("|", 1)[-1].split()
            ready = {t.rsplit(":", 1)[0] for t in known if t.endswith("*")}
            trials.setdefault((m[1], m[2], int(m[3])), []).append((m[5], m[6], ready))
    return trials


STEP_COLUMNS = ["Steps", "Moves", "of them while an object removed later could be declared",
                "Obstacles declared", "of them removed", "Obstacles declared, never removed"]


def trial_steps(actions):
    """One traced trial's steps, moves, idle moves (made while an object the trial removes later
    could already be declared: the declaration and removal were due, the move was not),
    obstacles declared, of them removed later, and declared but never removed."""
    declared = {o for k, o, _ in actions if k == "declare obstacle"}
    removed = {o for k, o, _ in actions if k == "remove"}
    idle = sum(k == "move" and bool(actions[i - 1][2] & removed)
               for i, (k, _, _) in enumerate(actions) if i)
    return (len(actions), sum(k == "move" for k, _, _ in actions), idle, len(declared),
            len(declared & removed), len(declared - removed))


def trace(path):
    groups = {}
    for (scene, planner, _), actions in trace_trials(path).items():
        groups.setdefault((scene, planner), []).append(trial_steps(actions))
    print("| Scene | Planner | Trials | " + " | ".join(STEP_COLUMNS[:5]) + " |")
    print("|---|---|---|---|---|---|---|---|")
    for (scene, planner), rows in sorted(groups.items()):
        means = [sum(r[i] for r in rows) / len(rows) for i in range(5)]
        print(f"| {scene} | {planner} | {len(rows)} | " + " | ".join(f"{m:.2f}" for m in means)
              + " |")


STEPS_ROW_ORDER = ["oracle", "oracle-cover-unknown", "nbv", "kct", "defaults", "covers"]


def steps(root, scenes_dir):
    """Where the steps go: per row of ROOT/ROW.trace.gz (bench_estimator.sh with TRACE=1) and
    per placement of the target, the mean per trial of each trial_steps figure, and success."""
    rows = {}
    for name in os.listdir(root):
        if name.endswith(".trace.gz"):
            rows[name[:-len(".trace.gz")]] = trace_trials(os.path.join(root, name))
    placements = {}
    table = {}
    for row, trials in rows.items():
        for (scene, _, _), actions in trials.items():
            if scene not in placements:
                path = os.path.join(scenes_dir, scene + ".json")
                placements[scene] = (scene_placement(path) if os.path.exists(path) else None) \
                    or "unknown"
            done = bool(actions) and actions[-1][0] == "remove" and \
                not any(k == "declare obstacle" and o == actions[-1][1] for k, o, _ in actions)
            for group in ("all", placements[scene]):
                table.setdefault((row, group), []).append(trial_steps(actions) + (done,))
    groups = order({g for _, g in table} - {"all"}, [name for _, name in PLACEMENTS]) + ["all"]
    scenes = {g: len({s for s, p in placements.items() if p == g or g == "all"}) for g in groups}
    print("Means per trial. Idle moves: " + STEP_COLUMNS[2] + " (the declaration and removal "
          "were due, the move was not). Success: the trial's last step removed the target.\n")
    print("| Row | Target | Trials | " + " | ".join(STEP_COLUMNS[:2]) + " | Idle moves | " +
          " | ".join(STEP_COLUMNS[3:]) + " | Success |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for row in order(set(rows), STEPS_ROW_ORDER):
        for g in groups:
            r = table.get((row, g))
            if not r:
                continue
            means = [sum(x[i] for x in r) / len(r) for i in range(6)]
            success = 100 * sum(x[6] for x in r) / len(r)
            print(f"| {row} | {g} ({scenes[g]} scenes) | {len(r)} | " +
                  " | ".join(f"{m:.1f}" for m in means) + f" | {success:.0f}% |")


def classic_paired(path, base_planner=None):
    """Runs of npfkct-bench on a classic problem compared episode by episode: within each group of
    runs with one problem, planner, seed, episodes, budget and rollout that list their episodes,
    every run against the group's run with the fewest options (its base; the first such run):
    the mean of the per-episode differences of return and of steps with their 95% t intervals;
    then each comparison made on several seeds once more, its episodes pooled.
    With `base_planner` the groups span planners and the base is that planner's run with the
    fewest options."""
    groups = {}
    for line in open(path, encoding="utf-8"):
        if not line.strip():
            continue
        r = json.loads(line)
        if "episode_returns" not in r:
            continue
        key = tuple(r.get(k) for k in ("problem", "planner", "seed", "episodes", "cpu_ms",
                                      "time_ms", "sims", "rollout", "max_steps")
                    if not (base_planner and k == "planner"))
        groups.setdefault(key, []).append(r)
    def header(seed_column):
        print(f"| Problem | Planner | {seed_column} | Episodes | Base options | "
              "Options beside the base | Base return | Return | Difference ± 95% | "
              "Steps difference ± 95% |")
        print("|---|---|---|---|---|---|---|---|---|---|")

    header("Seed")
    # The same comparison on several seeds, pooled: (problem, planner, budget, rollout, episode
    # length, base and extra options) -> its seeds and episodes.
    pooled = {}
    for runs in groups.values():
        candidates = [r for r in runs if not base_planner or r["planner"] == base_planner]
        if not candidates:
            continue
        base = min(candidates, key=lambda r: len(r["options"]))
        problem, seed, episodes = base["problem"], base["seed"], base["episodes"]
        for r in runs:
            if r is base:
                continue
            planner = r["planner"]
            if planner != base["planner"]:
                planner = f"{planner} (base: {base['planner']})"
            base_options = ", ".join(base["options"]) or "–"
            extra = ", ".join(o for o in r["options"] if o not in base["options"]) or "–"
            d_returns = [a - b for a, b in zip(r["episode_returns"], base["episode_returns"])]
            d_steps = [a - b for a, b in zip(r["episode_steps"], base["episode_steps"])]
            dr, cr = mean_ci(d_returns)
            ds, cs = mean_ci(d_steps)
            print(f"| {problem} | {planner} | {seed} | {episodes} | {base_options} | {extra} | "
                  f"{base['mean_discounted_return']:.2f} | {r['mean_discounted_return']:.2f} | "
                  f"{dr:+.2f} ± {cr:.2f} | {ds:+.1f} ± {cs:.1f} |")
            key = (problem, planner, r.get("cpu_ms"), r.get("time_ms"), r.get("sims"),
                   r.get("rollout"), r.get("max_steps"), base_options, extra)
            p = pooled.setdefault(key, {"seeds": [], "base": [], "run": [], "returns": [],
                                        "steps": []})
            p["seeds"].append(seed)
            p["base"].extend(base["episode_returns"])
            p["run"].extend(r["episode_returns"])
            p["returns"].extend(d_returns)
            p["steps"].extend(d_steps)
    pooled = {k: p for k, p in pooled.items() if len(p["seeds"]) > 1}
    if not pooled:
        return
    print("\nThe same comparisons pooled over their seeds (95% t of the per-episode differences):\n")
    header("Seeds")
    for (problem, planner, *_, base_options, extra), p in pooled.items():
        dr, cr = mean_ci(p["returns"])
        ds, cs = mean_ci(p["steps"])
        print(f"| {problem} | {planner} | {', '.join(str(x) for x in sorted(p['seeds']))} | "
              f"{len(p['returns'])} | {base_options} | {extra} | "
              f"{sum(p['base']) / len(p['base']):.2f} | {sum(p['run']) / len(p['run']):.2f} | "
              f"{dr:+.2f} ± {cr:.2f} | {ds:+.1f} ± {cs:.1f} |")

def lightdark_leaf(*paths):
    """SimpleLightDark's leaf values (bench/bench_classic.sh lightdark-leaf): every SimpleLightDark
    run of the first file with its return ± standard error, steps, success and simulations per
    step; then, episode by episode, each run with the detour leaf against the run with the fully
    observable leaf of the same planner, options, seed, episodes and budget (in any of the files),
    each fully observable run against the one before it in the first file with the same planner,
    options, seed and episodes (more search), and each run with options against the run without
    them of the same leaf, budget and seed."""
    files = [[r for r in json_lines(path) if r.get("problem") == "lightdark"] for path in paths]
    runs, mine = [r for f in files for r in f], files[0]
    leaf = lambda r: "localize" if r.get("rollout") == "localize" else "fo"
    budget = lambda r: (f"{r['cpu_ms']} ms CPU" if r.get("cpu_ms") else
                        f"{r['sims']:,} sims" if r.get("sims") else f"{r['time_ms']} ms")
    episodes = lambda r: (r["planner"], r["seed"], r["episodes"], tuple(r.get("options", [])))
    print("| Planner | Leaf value | Options | Budget | Seed | Episodes | Return ± s.e. | Steps | "
          "Success | Median sims/step |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in mine:
        print(f"| {r['planner']} | {leaf(r)} | {', '.join(r.get('options', [])) or '–'} | "
              f"{budget(r)} | {r['seed']} | {r['episodes']} | "
              f"{r['mean_discounted_return']:.2f} ± {r['stderr']:.2f} | {r['mean_steps']:.2f} | "
              f"{100 * r['success_rate']:.1f}% | {r['median_sims_per_step']:,.0f} |")
    pairs = []
    for r in mine:
        if leaf(r) == "localize":
            base = next((b for b in runs if leaf(b) == "fo" and episodes(b) == episodes(r) and
                         budget(b) == budget(r) and "episode_returns" in b), None)
            if base is not None:
                pairs.append(("the detour leaf", base, r))
    fo = [r for r in mine if leaf(r) == "fo"]
    for i, r in enumerate(fo):
        before = [b for b in fo[:i] if episodes(b) == episodes(r)]
        if before:
            pairs.append(("more search", before[-1], r))
    for r in mine:
        if r.get("options"):
            base = next((b for b in mine if not b.get("options") and leaf(b) == leaf(r) and
                         budget(b) == budget(r) and episodes(b)[:3] == episodes(r)[:3]), None)
            if base is not None:
                pairs.append((", ".join(r["options"]), base, r))
    print("\nEpisode by episode (the same initial states; 95% t of the differences):\n")
    print("| Change | Planner | Seed | Episodes | Base | Base return | Run | Return | "
          "Difference ± 95% | Steps difference ± 95% | Episodes that differ |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for change, base, r in pairs:
        d_returns = [a - b for a, b in zip(r["episode_returns"], base["episode_returns"])]
        dr, cr = mean_ci(d_returns)
        ds, cs = mean_ci([a - b for a, b in zip(r["episode_steps"], base["episode_steps"])])
        print(f"| {change} | {r['planner']} | {r['seed']} | {r['episodes']} | "
              f"{leaf(base)}, {budget(base)} | {base['mean_discounted_return']:.2f} | "
              f"{leaf(r)}, {budget(r)} | {r['mean_discounted_return']:.2f} | "
              f"{dr:+.2f} ± {cr:.2f} | {ds:+.2f} ± {cs:.2f} | "
              f"{sum(d != 0 for d in d_returns)} |")


def lightdark_optimum(path):
    """SimpleLightDark's reference (bench/bench_classic.sh lightdark-optimum): the last
    perseus-binned record of `path`, its bounds and policy; every lookahead record of `path` (the
    exact-belief lookaheads by leaf value); then the traced planner's decisions scored against the
    reference, their regret summed by the belief's spread at the decision."""
    lines = [x for x in json_lines(path) if x.get("problem") == "lightdark"]
    solved = [x for x in lines if x.get("planner") == "perseus-binned"]
    if not solved:
        sys.exit(f"{path}: no lightdark perseus-binned record")
    r = solved[-1]
    print("| Observation bins | Beliefs | Alpha-vectors | Solve, CPU s | First action | "
          "Lower bound at b0 | Its policy: return ± s.e. | Episodes | Steps | Success | "
          "QMDP upper bound |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    print(f"| {r['bins']} ({r['bin']:g} wide near the light) | {r['beliefs']:,} | "
          f"{r['alpha_vectors']:,} | {r['solve_cpu_seconds']:,.0f} | {r['first_action']} | "
          f"{r['lower_bound']:.2f} | {r['mean_discounted_return']:.2f} ± {r['stderr']:.2f} | "
          f"{r['episodes']:,} | {r['mean_steps']:.2f} | {100 * r['success_rate']:.1f}% | "
          f"{r['upper_bound_qmdp']:.2f} |")
    looks = [x for x in lines if x.get("planner", "").startswith("lookahead-")]
    if looks:
        print("\nSparse-sampling lookahead on the exact belief (`--lookahead LEAF`), by the leaf "
              "value: fo, the fully observable value averaged over the belief (what the trees' "
              "leaves estimate); plan, the best return of one position's fully observable plan "
              "followed blind:\n")
        print("| Leaf | Depth | Observations sampled per move | Episodes | Return ± s.e. | Steps | "
              "Success | CPU s |")
        print("|---|---|---|---|---|---|---|---|")
        for x in sorted(looks, key=lambda x: (x["depth"], -x["width"], x["planner"])):
            print(f"| {x['planner'].split('-', 1)[1]} | {x['depth']} | {x['width']} | "
                  f"{x['episodes']} | {x['mean_discounted_return']:.2f} ± {x['stderr']:.2f} | "
                  f"{x['mean_steps']:.2f} | {100 * x['success_rate']:.1f}% | "
                  f"{x['cpu_seconds']:,.0f} |")
    s = r.get("scored")
    if not s:
        return
    groups = list(s["regret_by_group"])
    print(f"\n{s['planner']}'s traced episodes ({s['traced_episodes']}, return "
          f"{s['traced_mean_discounted_return']:.2f}) scored against the reference: the mean "
          "discounted regret per episode, Q(b, best) - Q(b, taken), by the belief's spread "
          "(standard deviation of the position) at the decision:\n")
    print("| Planner | Regret per episode | " +
          " | ".join(f"{g} (decisions)" for g in groups) + " | Decisions as the reference |")
    print("|---|---|" + "---|" * len(groups) + "---|")
    print(f"| {s['planner']} | {s['mean_discounted_regret']:.2f} | " +
          " | ".join(f"{s['regret_by_group'][g]:.2f} ({s['decisions_by_group'][g]:,})"
                     for g in groups) +
          f" | {100 * s['share_of_decisions_as_reference']:.1f}% |")


def compare(a_root, b_root):
    a, b = load_cells(a_root), load_cells(b_root)
    keys = [k for k in a if k in b]
    scenes = order({s for s, _ in keys}, PAPER_SCENES)
    planners = order({p for _, p in keys}, PLANNER_ORDER)
    print(f"| Scene | Planner | {os.path.basename(a_root)} | {os.path.basename(b_root)} | "
          "Each mean inside the other's interval |")
    print("|---|---|---|---|---|")
    agree = 0
    for s in scenes:
        for p in planners:
            if (s, p) not in a or (s, p) not in b:
                continue
            ra, rb = a[(s, p)], b[(s, p)]
            ma, ca = ra["mean_discounted_reward"], ra["ci95"]
            mb, cb = rb["mean_discounted_reward"], rb["ci95"]
            ok = abs(ma - mb) <= min(ca, cb) + 1e-6
            agree += ok
            print(f"| {s} | {p} | {ma:.1f} ± {ca:.1f} | {mb:.1f} ± {cb:.1f} | "
                  f"{'yes' if ok else 'no'} |")
    print(f"\n{agree} of {len(keys)} cells agree.")


def inside_count(old_root, new_root):
    """How many of the new run's cell means lie inside the old run's 95% interval of the cell."""
    a, b = load_cells(old_root), load_cells(new_root)
    keys = [k for k in a if k in b]
    inside = sum(abs(b[k]["mean_discounted_reward"] - a[k]["mean_discounted_reward"]) <=
                 a[k]["ci95"] + 1e-6 for k in keys)
    return (f"{inside} of {len(keys)} of {os.path.basename(new_root)}'s means lie inside "
            f"{os.path.basename(old_root)}'s interval of the cell.")


def flat(path):
    rows = json_lines(path)
    modes = {r.get("observe", "geometric") for r in rows}
    scenes, planners, cells = [], [], {}
    for r in rows:
        name = r["planner"] + (f" ({r['observe']})" if len(modes) > 1 else "")
        if r["scenario"] not in scenes:
            scenes.append(r["scenario"])
        if name not in planners:
            planners.append(name)
        cells[(name, r["scenario"])] = r
    planner_table(planners, scenes,
                  lambda p, s: cell_text(cells[(p, s)]) if (p, s) in cells else None)


def threads(one_path, two_path):
    """Thread scaling (bench/bench_threads.sh): per scene the median simulations per second with
    one and two search threads, their ratio, and the rewards."""
    one = json_lines(one_path)
    two = json_lines(two_path)
    print("| Scene | sims/s, 1 thread | sims/s, 2 threads | ratio | reward, 1 thread | "
          "reward, 2 threads |")
    print("|---|---|---|---|---|---|")
    for a, b in zip(one, two):
        ratio = b["median_sims_per_second"] / max(a["median_sims_per_second"], 1e-9)
        print(f"| {a['scenario']} | {a['median_sims_per_second']:.0f} | "
              f"{b['median_sims_per_second']:.0f} | {ratio:.2f}x | "
              f"{a['mean_discounted_reward']:.1f} ± {a['ci95']:.1f} | "
              f"{b['mean_discounted_reward']:.1f} ± {b['ci95']:.1f} |")


def model_speed(root):
    """The model's simulation speed (bench/bench_model_speed.sh): ROOT/{base,new}-rN.jsonl, the
    same cells run by two builds in turn. Fails unless every run gave the same rewards (a change
    that only makes the model faster cannot change a result); per cell the median over rounds of
    the simulations per CPU-second of the planning thread, base and new, and their ratio."""
    def load(path):
        return {(d["scenario"], d["planner"]): d
                for d in map(json.loads, open(path, encoding="utf-8"))}
    rounds = sorted(int(m[1]) for m in (re.match(r"base-r(\d+)\.jsonl$", f)
                                         for f in os.listdir(root)) if m)
    runs = {side: [load(os.path.join(root, f"{side}-r{r}.jsonl")) for r in rounds]
            for side in ("base", "new")}
    cells = list(runs["base"][0])
    for key in cells:
        for run in runs["base"] + runs["new"]:
            if run[key]["rewards"] != runs["base"][0][key]["rewards"]:
                sys.exit(f"{key}: the rewards differ between the runs; the model's results changed")
    print(f"The same rewards in every cell of every run. Simulations per CPU-second of the "
          f"planning thread (median over steps), median over {len(rounds)} rounds:\n")
    print("| Scene | Planner | base | new | new / base |")
    print("|---|---|---|---|---|")
    ratios = []
    for key in cells:
        b, n = (statistics.median(r[key]["median_sims_per_cpu_second"] for r in runs[side])
                for side in ("base", "new"))
        ratios.append(n / b)
        print(f"| {key[0]} | {key[1]} | {b:.0f} | {n:.0f} | {n / b:.2f}x |")
    print(f"\nMedian ratio over the {len(cells)} cells: {statistics.median(ratios):.2f}x")


# The seeds of the 25-episode kCT runs at the VPW paper's VDP Tag configuration, pooled with
# seed 1's 100 episodes (episode i of seed S is seeded S * 1000003 + i: no two runs share one).
VDP_CHUNK_SEEDS = list(range(2, 18))
# The same for VOMCPOW beside it.
VOMCPOW_CHUNK_SEEDS = list(range(2, 10))


def vpw_vdptag(planner, seed=None, episodes=None):
    """The selector of a run of bench_classic.sh vdptag-published (the VPW paper's VDP Tag
    configuration) of one planner; with a seed and episodes, of that run alone; kCT's runs of the
    paper's tree."""
    selector = {"problem": "vdptag", "planner": planner, "cpu_ms": 1000,
                "options": ["search.rollout_first=1", "search.num_particles=100000"]}
    if planner == "kct":
        selector["kct_tree"] = "spheres"
    if seed is not None:
        selector.update(seed=seed, episodes=episodes)
    return selector


# kCT with point children (its defaults since) at the VPW configuration: 25 episodes on each of
# these seeds, run before the records named the tree, their lines kept in their own file.
KCT_POINTS_VDPTAG = "kct-points/vdptag-vpw-1s.jsonl"
KCT_POINTS_SEEDS = list(range(2, 22))


def vpw_vdptag_pooled(planner, seeds):
    """Seed 1's 100 episodes of a planner at the VPW configuration and its 25-episode runs."""
    return [vpw_vdptag(planner, 1, 100)] + [vpw_vdptag(planner, s, 25) for s in seeds]


# The classic problems' rows (bench/bench_classic.sh, bench/results/classic.jsonl): the problem,
# planner and budget as printed, the fields a run must have (the last line that has them is
# taken; several selectors are pooled), and the figure its authors published.
CLASSIC_ROWS = [
    ("Tiger (γ 0.95, 100 steps)", "POMCP", "5,000 sims",
     [{"problem": "tiger", "planner": "pomcp", "sims": 5000, "rollout": ""}],
     "19.25 (the 100-step optimum)",
     "tiger"),
    ("RockSample(7,8)", "POMCP", "1 s",
     [{"problem": "rocksample", "planner": "pomcp", "time_ms": 1000, "threads": 2}],
     "20.71 ± 0.21 (Silver & Veness 2010)",
     "rocksample"),
    ("Tag, seeds 1 and 2 pooled", "DESPOT (`despot`)", "1 s of CPU",
     [{"problem": "tag", "planner": "despot", "cpu_ms": 1000, "seed": 1},
      {"problem": "tag", "planner": "despot", "cpu_ms": 1000, "seed": 2}],
     "-6.26 ± 0.28 (AR-DESPOT; Somani et al. 2013)",
     "tag; SEED=2 tag"),
    ("Tag, seeds 1 and 2 pooled", "POMCP", "1 s of CPU",
     [{"problem": "tag", "planner": "pomcp", "cpu_ms": 1000, "seed": 1},
      {"problem": "tag", "planner": "pomcp", "cpu_ms": 1000, "seed": 2}],
     "-7.14 ± 0.28 (ibid.)",
     "tag; SEED=2 tag"),
    ("SimpleLightDark", "POMCPOW", "1 s",
     [{"problem": "lightdark", "planner": "pomcpow", "time_ms": 1000}],
     "56.1 ± 0.6 (Sunberg & Kochenderfer 2018)",
     "lightdark"),
    ("SimpleLightDark", "POMCP", "0.1 s",
     [{"problem": "lightdark", "planner": "pomcp", "time_ms": 100}],
     "-7.1 ± 1.0 (ibid., at 1 s)",
     "lightdark"),
    ("VDP Tag", "POMCPOW", "0.1 s",
     [{"problem": "vdptag", "planner": "pomcpow", "time_ms": 100}],
     "29.3 ± 0.8 (ibid., at 1 s)",
     "vdptag"),
    ("VDP Tag", "VOMCPOW", "0.1 s",
     [{"problem": "vdptag", "planner": "vomcpow", "time_ms": 100}],
     "above POMCPOW (Lim, Tomlin & Sunberg 2021)",
     "vdptag"),
    ("VDP Tag (ToNextML rollout)", "POMCPOW", "1 s",
     [{"problem": "vdptag", "planner": "pomcpow", "time_ms": 1000, "rollout": "tonextml"}],
     "28.3 ± 1.0 (ibid.)",
     "vdptag"),
    ("VDP Tag (ToNextML rollout)", "VOMCPOW", "1 s",
     [{"problem": "vdptag", "planner": "vomcpow", "time_ms": 1000, "rollout": "tonextml"}],
     "33.2 ± 0.9 (ibid.)",
     "vdptag"),
    ("SimpleLightDark", "kCT", "1 s of CPU",
     [{"problem": "lightdark", "planner": "kct", "cpu_ms": 1000, "seed": 1}], "–",
     "kct-lightdark"),
    ("SimpleLightDark, seeds 1-3 pooled", "kCT", "1 s of CPU",
     [{"problem": "lightdark", "planner": "kct", "cpu_ms": 1000, "seed": 1},
      {"problem": "lightdark", "planner": "kct", "cpu_ms": 1000, "seed": 2, "episodes": 200},
      {"problem": "lightdark", "planner": "kct", "cpu_ms": 1000, "seed": 3, "episodes": 100}],
     "61.06 ± 0.40 (the best published: a discretised POMCP; "
     "ContinuousPOMDPTreeSearchExperiments.jl)",
     "kct-lightdark; SEED=2 PLANNERS=kct kct-lightdark; "
     "SEED=3 PLANNERS=kct EPISODES=100 kct-lightdark"),
    ("SimpleLightDark", "POMCPOW", "1 s of CPU",
     [{"problem": "lightdark", "planner": "pomcpow", "cpu_ms": 1000}],
     "56.1 ± 0.6 (Sunberg & Kochenderfer 2018)",
     "kct-lightdark"),
    ("SimpleLightDark, observations binned (`bench/lightdark_optimum.py`: an offline reference, "
     "a lower bound on the optimum)", "point-based value iteration (Perseus) on the exact belief",
     "offline, about 10 min of CPU",
     [{"problem": "lightdark", "planner": "perseus-binned"}], "–",
     "lightdark-optimum"),
    ("SimpleLightDark, observations in bins of 10^-1.5", "POMCP (`d-pomcp`)", "1 s of CPU",
     [{"problem": "lightdark", "planner": "d-pomcp", "cpu_ms": 1000}],
     "60.99 ± 0.41 (d_pomcp at that width, the best of seven; "
     "ContinuousPOMDPTreeSearchExperiments.jl icaps_2018 raw data)",
     "lightdark-discretised"),
    ("VDP Tag (ToNextML rollout), seeds 1 and 2 pooled", "kCT, the paper's tree",
     "1 s of CPU",
     [{"problem": "vdptag", "planner": "kct", "cpu_ms": 1000, "threads": 1, "seed": 1,
       "kct_tree": "spheres"},
      {"problem": "vdptag", "planner": "kct", "cpu_ms": 1000, "threads": 1, "seed": 2,
       "kct_tree": "spheres"}], "–",
     "THREADS=1 SEED=1 kct-vdptag; THREADS=1 SEED=2 kct-vdptag"),
    ("VDP Tag (ToNextML rollout), seeds 1 and 2 pooled", "VOMCPOW", "1 s of CPU",
     [{"problem": "vdptag", "planner": "vomcpow", "cpu_ms": 1000, "threads": 1, "seed": 1},
      {"problem": "vdptag", "planner": "vomcpow", "cpu_ms": 1000, "threads": 1, "seed": 2}],
     "33.2 ± 0.9 (Lim, Tomlin & Sunberg 2021)",
     "THREADS=1 SEED=1 kct-vdptag; THREADS=1 SEED=2 kct-vdptag"),
    ("VDP Tag, the VPW paper's configuration", "VOMCPOW", "1 s of CPU",
     [vpw_vdptag("vomcpow", 1, 100)], "33.2 ± 0.9 (Lim, Tomlin & Sunberg 2021)",
     "vdptag-published"),
    (f"VDP Tag, the VPW paper's configuration, seeds 1-{VOMCPOW_CHUNK_SEEDS[-1]} pooled",
     "VOMCPOW", "1 s of CPU", vpw_vdptag_pooled("vomcpow", VOMCPOW_CHUNK_SEEDS),
     "33.2 ± 0.9 (Lim, Tomlin & Sunberg 2021)",
     "vdptag-published; PLANNERS=vomcpow EPISODES=25 SEED=S vdptag-published"),
    ("VDP Tag, the VPW paper's configuration", "POMCPOW", "1 s of CPU",
     [vpw_vdptag("pomcpow")], "28.3 ± 1.0 (ibid.)", "vdptag-published"),
    ("VDP Tag, the VPW paper's configuration, seed 1", "kCT, the paper's tree", "1 s of CPU",
     [vpw_vdptag("kct", 1, 100)], "–", "vdptag-published"),
    (f"VDP Tag, the VPW paper's configuration, seeds 1-{VDP_CHUNK_SEEDS[-1]} pooled",
     "kCT, the paper's tree", "1 s of CPU", vpw_vdptag_pooled("kct", VDP_CHUNK_SEEDS), "–",
     "PLANNERS=kct vdptag-published; PLANNERS=kct EPISODES=25 SEED=S vdptag-published"),
    (f"VDP Tag, the VPW paper's configuration, seeds {KCT_POINTS_SEEDS[0]}-"
     f"{KCT_POINTS_SEEDS[-1]} pooled", "kCT (point children: the defaults)", "1 s of CPU",
     [dict(vpw_vdptag("kct", s, 25), kct_tree=None, file=KCT_POINTS_VDPTAG)
      for s in KCT_POINTS_SEEDS], "33.2 ± 0.9 (VOMCPOW; Lim, Tomlin & Sunberg 2021)",
     "PLANNERS=kct EPISODES=25 SEED=S vdptag-published"),
    ("VDP Tag (ToNextML rollout), seed 1", "kCT, the paper's tree",
     "1 s of CPU",
     [{"problem": "vdptag", "planner": "kct", "cpu_ms": 1000, "threads": 1, "seed": 1,
       "kct_tree": "spheres"}], "–",
     "THREADS=1 SEED=1 kct-vdptag"),
    ("VDP Tag (ToNextML rollout), seed 1", "VOMCPOW", "1 s of CPU",
     [{"problem": "vdptag", "planner": "vomcpow", "cpu_ms": 1000, "threads": 1, "seed": 1}], "–",
     "THREADS=1 SEED=1 kct-vdptag"),
    ("VDP Tag (ToNextML rollout), seed 2", "kCT, the paper's tree",
     "1 s of CPU",
     [{"problem": "vdptag", "planner": "kct", "cpu_ms": 1000, "threads": 1, "seed": 2,
       "kct_tree": "spheres"}], "–",
     "THREADS=1 SEED=2 kct-vdptag"),
    ("VDP Tag (ToNextML rollout), seed 2", "VOMCPOW", "1 s of CPU",
     [{"problem": "vdptag", "planner": "vomcpow", "cpu_ms": 1000, "threads": 1, "seed": 2}], "–",
     "THREADS=1 SEED=2 kct-vdptag"),
]
# Defaults of fields older lines of classic.jsonl leave out.
CLASSIC_DEFAULTS = {"cpu_ms": 0, "time_ms": 0, "sims": 0, "seed": 1, "rollout": "",
                    "kct_tree": "spheres"}


def classic_command(sections):
    """The bench command of a classic row: `ENV bench/bench_classic.sh SECTION`, `;`-separated."""
    commands = []
    for part in sections.split(";"):
        words = part.split()
        env = [w for w in words if "=" in w]
        rest = [w for w in words if "=" not in w]
        commands.append("`" + " ".join(env + ["bench/bench_classic.sh"] + rest) + "`")
    return "; ".join(commands)


def despot_runs(paths):
    """bench_despot.sh's files: [(path, its episodes)], and all episodes grouped by planner."""
    runs = []
    by = {}
    for path in paths:
        run = json_lines(path)
        runs.append((path, run))
        for r in run:
            by.setdefault(r["planner"], []).append(r)
    return runs, by


def despot_files(results):
    """The DESPOT side-by-side's files under a results folder, in order."""
    return sorted(glob.glob(os.path.join(results, "despot", "rocksample-0.1s*.jsonl")))


def despot_summary(episodes):
    """Mean discounted return ± standard error (sd / sqrt(n)) of bench_despot.sh episodes."""
    values = [e["discounted_return"] for e in episodes]
    m = statistics.fmean(values)
    se = statistics.stdev(values) / math.sqrt(len(values)) if len(values) > 1 else 0.0
    return m, se


def classic(path):
    """One table of the solver beside its peers: the classic problems with published results
    (bench/bench_classic.sh; mean discounted return ± standard error, runs pooled as independent
    samples: the mean weighted by episodes, the standard error sqrt(sum n_i^2 se_i^2) / sum n_i),
    the VPW paper's LQG (the first action's distance to the optimum) from the same file, and the
    DESPOT side-by-side (bench/bench_despot.sh, the files despot/rocksample-0.1s*.jsonl beside
    `path`, pooled), each row with the command that measures it."""
    lines = json_lines(path)
    files = {path: lines}

    def last(selector):
        """The last run matching the selector: in `path`, or in its "file" beside `path`; a
        field whose selector value is None is not checked."""
        where = path
        if "file" in selector:
            where = os.path.join(os.path.dirname(os.path.abspath(path)), selector["file"])
            if where not in files:
                files[where] = json_lines(where)
        found = [r for r in files[where]
                 if all(v is None or r.get(k, CLASSIC_DEFAULTS.get(k)) == v
                        for k, v in selector.items() if k != "file")]
        if not found:
            sys.exit(f"{where}: no run with {selector}")
        return found[-1]

    print("| Problem | Planner | Budget | Episodes | Measure | Ours ± s.e. | Steps | Success | "
          "Published | Command |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for problem, planner, budget, selectors, published, sections in CLASSIC_ROWS:
        runs = [last(sel) for sel in selectors]
        n = sum(r["episodes"] for r in runs)
        mean = sum(r["episodes"] * r["mean_discounted_return"] for r in runs) / n
        se = math.sqrt(sum((r["episodes"] * r["stderr"]) ** 2 for r in runs)) / n
        steps = sum(r["episodes"] * r["mean_steps"] for r in runs) / n
        rates = [r["success_rate"] for r in runs]
        success = ("–" if any(x is None for x in rates) else
                   f"{100 * sum(r['episodes'] * r['success_rate'] for r in runs) / n:.1f}%")
        print(f"| {problem} | {planner} | {budget} | {n} | return | {mean:.2f} ± {se:.2f} | "
              f"{steps:.1f} | {success} | {published} | {classic_command(sections)} |")
    _, by = despot_runs(despot_files(os.path.dirname(os.path.abspath(path))))
    names = {"despot-original": "DESPOT, the authors' code run here",
             "despot": "DESPOT (`despot`)", "pomcp": "POMCP"}
    for planner in order(by, ["despot-original", "despot", "pomcp"]):
        m, se = despot_summary(by[planner])
        steps = statistics.fmean(e["steps"] for e in by[planner])
        print(f"| RockSample(7,8), episodes interleaved with the authors' DESPOT | "
              f"{names.get(planner, planner)} | 0.1 s of CPU | {len(by[planner])} | return | "
              f"{m:.2f} ± {se:.2f} | {steps:.1f} | – | – | "
              f"`DESPOT_SRC=/path/to/despot bench/bench_despot.sh 60`, again with `FIRST=61` |")
    published = {"vomcpow": "0.246 (RolloutFirst; Lim, Tomlin & Sunberg 2021)",
                 "pomcpow": "0.277 (RolloutFirst; ibid.)"}
    latest = {}
    for r in lines:  # the last LQG run of each planner, options and kCT tree
        if r["problem"] == "lqg":
            tree = r.get("kct_tree", CLASSIC_DEFAULTS["kct_tree"])
            latest[(r["planner"], tuple(r["options"]), tree)] = r
    for (planner, options, tree), r in latest.items():
        name = {"kct": "kCT", "pomcpow": "POMCPOW", "vomcpow": "VOMCPOW"}[planner]
        if planner != "kct":
            name += ", RolloutFirst, the script's constants"
        else:
            name += " (point children: the defaults)" if tree == "points" else ", the paper's tree"
            if options:
                name += ", " + ", ".join(f"`{o}`" for o in options)
        print(f"| The VPW paper's 2-D LQG | {name} | {r['sims']:,} sims | {r['plans']} plans | "
              f"first action's distance to the optimum (lower is better) | "
              f"{r['mean_distance']:.3f} ± {r['stderr']:.3f} | – | – | "
              f"{published.get(planner, '–')} | `bench/bench_classic.sh lqg` |")
    print("\nSimulations per second of POMCP on RockSample(7,8) at 1 s per step (median over "
          "steps):\n")
    print("| Episodes | Episodes at once | Return ± s.e. | Median sims/s | First step sims/s |")
    print("|---|---|---|---|---|")
    for r in lines:
        if r["problem"] == "rocksample" and r["planner"] == "pomcp":
            print(f"| {r['episodes']} | {r['threads']} | {r['mean_discounted_return']:.2f} ± "
                  f"{r['stderr']:.2f} | {r['median_sims_per_second']:,.0f} | "
                  f"{r['median_first_step_sims_per_second']:,.0f} |")


def despot_table(*paths):
    """bench/bench_despot.sh's episodes, its runs pooled: per planner the mean discounted return
    ± standard error (sd / sqrt(episodes)), mean steps, the median over episodes of the median
    trials (DESPOT) or simulations (POMCP) per step, and the difference to the authors' DESPOT ±
    the standard error of a difference of independent means; then each run's means."""
    runs, by = despot_runs(paths)
    names = {"despot-original": "DESPOT, the authors' code (AdaCompNUS/despot)",
             "despot": "DESPOT, ours (`despot`)", "pomcp": "POMCP, ours (`pomcp`)"}

    base = despot_summary(by["despot-original"]) if "despot-original" in by else None
    print("| Planner | Episodes | Return ± s.e. | Steps | Trials (sims) per step | "
          "Minus the original ± s.e. |")
    print("|---|---|---|---|---|---|")
    for planner in order(by, ["despot-original", "despot", "pomcp"]):
        episodes = by[planner]
        m, se = despot_summary(episodes)
        steps = statistics.fmean(e["steps"] for e in episodes)
        trials = [e["median_trials_per_step"] for e in episodes
                  if e.get("median_trials_per_step") is not None]
        trial_text = f"{statistics.median(trials):,.0f}" if trials else "–"
        diff = "–"
        if base and planner != "despot-original":
            diff = f"{m - base[0]:+.2f} ± {math.hypot(se, base[1]):.2f}"
        print(f"| {names.get(planner, planner)} | {len(episodes)} | {m:.2f} ± {se:.2f} | "
              f"{steps:.1f} | {trial_text} | {diff} |")
    if len(runs) > 1:
        print()
        runs.sort(key=lambda run: min(r["episode"] for r in run[1]))
        for path, run in runs:
            episodes = sorted({r["episode"] for r in run})
            means = []
            for planner in order({r["planner"] for r in run}, ["despot-original", "despot", "pomcp"]):
                m, se = despot_summary([r for r in run if r["planner"] == planner])
                means.append(f"{names.get(planner, planner).split(',')[0]}"
                             f"{' (theirs)' if planner == 'despot-original' else ''} "
                             f"{m:.2f} ± {se:.2f}")
            print(f"- `{os.path.basename(path)}` (episodes {episodes[0]}-{episodes[-1]}): "
                  + "; ".join(means))
    commits = {r["commit"] for run in by.values() for r in run if r.get("commit")}
    if commits:
        print(f"\nThe authors' code at commit {', '.join(sorted(commits))}.")


FILTER_TEST_SETS = {"heldout": "Held-out generated scenes (seeds 900001-900030)",
                    "paper": "The paper's six scenes"}


def filter_figures(eval_path, bench_path):
    """The neural filter's accuracy on its test sets (npfkct-train evaluate) and its time on one
    core (npfkct-train bench)."""
    sets = json_lines(eval_path)
    rows = [
        ("Snapshots (16 context and 48 predicted queries each)",
         lambda x: f"{x['test_samples']:,}"),
        ("Queries predicted (efficient: g > 0.05)", lambda x: f"{x['queries']:,} "
                                                              f"({x['efficient']:,})"),
        ("Accuracy (the paper's definition: efficient queries not predicted mu < 0.05)",
         lambda x: f"**{100 * x['accuracy']:.2f}% ± {100 * x['accuracy_ci95']:.2f}**"),
        ("The same among the clearly efficient queries (g > 0.1)",
         lambda x: f"{100 * x['accuracy_clear']:.2f}%"),
        ("Useless queries predicted mu < 0.05", lambda x: f"{100 * x['specificity']:.2f}%"),
        ("Efficient queries kept by Net_sam's rule mu > beta* sigma",
         lambda x: f"{100 * x['kept_efficient']:.2f}%"),
        ("Useless queries dropped by that rule", lambda x: f"{100 * x['dropped_useless']:.2f}%"),
        ("Mean absolute error of mu; share with g within 2 sigma",
         lambda x: f"{x['mean_abs_error']:.3f}; {100 * x['within_2_sigma']:.2f}%"),
    ]
    print("| |" + "".join(f" {FILTER_TEST_SETS.get(x['test_set'], x['test_set'])} |"
                         for x in sets))
    print("|---|" + "---|" * len(sets))
    for label, text in rows:
        print(f"| {label} |" + "".join(f" {text(x)} |" for x in sets))
    with open(bench_path, encoding="utf-8") as f:
        b = json.load(f)
    print(f"\nTime on one core ({b['scenario']} after one step, {b['networks']} networks, median of "
          f"{b['runs']} calls; clock: {b['clock']}):\n")
    print(f"| Network scores of {b['candidates']:,} candidates (scene encoding included) | "
          f"Whole Net_sam call | Scene features | Exact scores of the same candidates |")
    print("|---|---|---|---|")
    print(f"| {b['median_network_ms']:.1f} ms | {b['median_net_sam_ms']:.1f} ms | "
          f"{b['median_scene_features_ms']:.1f} ms | {b['median_exact_score_ms']:.1f} ms |")


def perception_stages(path):
    """The perception pipeline's time per stage (npfkct-perception-bench)."""
    with open(path, encoding="utf-8") as f:
        p = json.load(f)
    stages = ["registration", "segmentation", "association", "detection", "total"]
    print(f"{p['frames']} frames of {p['resolution']}, {p['threads']} thread, wall-clock medians; "
          f"{p['target_detections']} target and {p['other_detections']:,} other detections:\n")
    print("| " + " | ".join(s.capitalize() for s in stages) + " | Target recall | "
          "Others rejected |")
    print("|" + "---|" * (len(stages) + 2))
    print("| " + " | ".join(f"{p['median_ms'][s]:.1f} ms" for s in stages) +
          f" | {p['target_recall']:.3f} | {p['other_rejected']:.3f} |")


def maps_table(directory):
    """A SLAM map against the hand-written one (bench/bench_maps.py, SCENE.json) and raw frames
    on a house-sized map (bench/bench_house_map.py, house_grid.json and plain_room.json)."""
    print("| Scene | hand-written: reward, steps | SLAM map: reward, steps | paired difference |")
    print("|---|---|---|---|")
    for name in sorted(glob.glob(os.path.join(directory, "*.json"))):
        with open(name, encoding="utf-8") as f:
            r = json.load(f)
        if "forms" not in r:
            continue
        cells = []
        for form in ("hand-written", "slam-map"):
            c = r["forms"][form]
            cells.append(f"{c['mean_reward'] / 1000:.1f}k ± {c['ci95'] / 1000:.1f}k, "
                         f"{c['mean_steps']:.2f} ± {c['ci95_steps']:.2f} "
                         f"({c['success_rate']:.0%} success)")
        d = r["paired_reward_difference"]
        print(f"| {r['scenario']} ({r['trials']} seeds, {r['cpu_ms']:.0f} ms) | {cells[0]} | "
              f"{cells[1]} | {d['mean'] / 1000:+.1f}k ± {d['ci95'] / 1000:.1f}k |")
    print()
    print("| Map | first frame (CPU) | later frames, median (CPU) | registration, median "
          "(wall) | memory kept per session |")
    print("|---|---|---|---|---|")
    for name in ("house_grid.json", "plain_room.json"):
        path = os.path.join(directory, name)
        if not os.path.exists(path):
            continue
        with open(path, encoding="utf-8") as f:
            h = json.load(f)
        first = h["first_frame_cpu_ms"]
        stages = h["median_later_frame_pipeline_ms"]
        print(f"| {h['map']} | {min(first):.1f}-{max(first):.1f} ms | "
              f"{h['median_later_frame_cpu_ms']:.1f} ms ({h['later_frames']} frames) | "
              f"{stages['registration']:.1f} ms | {h['kept_mb_per_session_mean']:.1f} MB |")


def load_table(path):
    """The server under many sessions (bench/load_bench.py, one JSON line per run)."""
    print("| Sessions | Plan budget | Plans/s | Plan overhead p50 / p99 (ms) | "
          "Observe p50 / p99 (ms) | Server's own overhead p50 / p99 (histogram bucket, ms) | "
          "RSS per session (MiB) |")
    print("|---|---|---|---|---|---|---|")
    for line in open(path, encoding="utf-8"):
        if not line.strip():
            continue
        r = json.loads(line)
        print(f"| {r['sessions']} | {r['budget_ms']:.0f} ms | {r['throughput_plans_per_s']:.1f} | "
              f"{r['plan_overhead_ms_p50']:.1f} / {r['plan_overhead_ms_p99']:.1f} | "
              f"{r['observe_latency_ms_p50']:.1f} / {r['observe_latency_ms_p99']:.1f} | "
              f"<= {r['server_plan_overhead_ms_p50_bucket']:g} / "
              f"<= {r['server_plan_overhead_ms_p99_bucket']:g} | "
              f"{r['rss_per_session_kib'] / 1024:.1f} |")


def fleet_table(path):
    """A fleet's throughput and failover (bench/fleet_bench.py)."""
    with open(path, encoding="utf-8") as f:
        fl = json.load(f)

    def bucket(x):
        return "–" if x is None else f"<= {x:g}"

    load = ", ".join(f"{x:.1f}" for x in fl["load_average_at_start"][:1] +
                     fl["load_average_at_end"][:1])
    budget = ", ".join(f"{k} {v:g}" for k, v in fl["budget"].items())
    print(f"{fl['robots']} robots ({fl['planner']}, {fl['scenario']}, budget {budget} per plan), "
          f"{fl['plans_per_fleet_size']} plans per fleet size, on a machine of {fl['machine']} "
          f"(1-minute load average at the start and the end: {load}):\n")
    print("| Replicas | Plans measured | Plans/s | Plan overhead p50 / p99 (ms) | Store save p50 / "
          "p99, refresh p50 (ms, histogram bucket) |")
    print("|---|---|---|---|---|")
    for r in fl["fleets"]:
        print(f"| {r['replicas']} | {r['plans']} | {r['plans_per_s']:.1f} | "
              f"{r['plan_overhead_ms_p50']:.1f} / {r['plan_overhead_ms_p99']:.1f} | "
              f"{bucket(r['store_save_ms_p50_bucket'])} / {bucket(r['store_save_ms_p99_bucket'])}, "
              f"{bucket(r['store_refresh_ms_p50_bucket'])} |")
    fo = fl["failover"]
    sessions = sum(fo["sessions_on_killed_replica"])
    print(f"\n| Failover ({fo['replicas']} replicas, {fo['kills']} kills, {sessions} sessions on "
          f"the killed replicas) | median | max |")
    print("|---|---|---|")
    print(f"| SIGKILL to the session served again | {fo['probe_s_median']:.3f} s | "
          f"{fo['probe_s_max']:.3f} s |")
    print(f"| SIGKILL to the robot's next acknowledged plan or observe | "
          f"{fo['next_step_s_median']:.2f} s | {fo['next_step_s_max']:.2f} s |")


def generated_runs(runs):
    """Other runs of the held-out generated scenes: per run (name, folder) and planner its share
    of the oracle's reward, success and steps (the oracle's rows left out)."""
    print("| Run | Planner | Share of the oracle's reward | Success | Steps | Median sims/CPU-s | "
          "Scenes |")
    print("|---|---|---|---|---|---|---|")
    for name, root in runs:
        cells = {(p, s): r for (s, p), r in load_cells(root).items()}
        scenes = sorted({s for _, s in cells})
        planners = [p for p in order({p for p, _ in cells}, PLANNER_ORDER)
                    if not p.startswith("oracle")]
        for p, x in oracle_summary(cells, planners, scenes).items():
            sims = statistics.median(cells[(p, s)]["median_sims_per_cpu_second"] for s in scenes
                                     if (p, s) in cells)
            print(f"| {name} | {p} | {100 * x['share']:.1f}% ± {100 * x['share_ci']:.1f} | "
                  f"{x['success']:.1f}% | {x['steps']:.1f} ± {x['steps_ci']:.1f} | {sims:.0f} | "
                  f"{x['scenes']} |")


def share_series(kind, root, name):
    """{scene: (share of the oracle's reward, median sims per CPU-second)} of one planner of a
    run (kind "cells": ROOT/SCENE/PLANNER.jsonl) or one row of an ablation (kind "rows":
    ROOT/ROW/SCENE.jsonl), each against the oracle of the same folder."""
    if kind == "rows":
        cells = {(s, row): r for (row, s), r in load_row_cells(root).items()}
    else:
        cells = load_cells(root)
    out = {}
    for (s, p), r in cells.items():
        o = cells.get((s, "oracle"))
        if p == name and o is not None and o["mean_discounted_reward"] > 0:
            out[s] = (r["mean_discounted_reward"] / o["mean_discounted_reward"],
                      r.get("median_sims_per_cpu_second"))
    return out


def paired(comparisons, base):
    """Paired comparisons over the scenes two runs share: per scene B's share of the oracle's
    reward minus A's, mean ± 95% t interval, the scenes where B is higher, and each side's median
    simulations per CPU-second. `comparisons`: (label, A, B), each side (kind, folder under
    `base`, planner or row)."""
    print("| Comparison | A | B | B - A (points of the oracle's reward) | B higher in | "
          "Median sims/CPU-s, A / B |")
    print("|---|---|---|---|---|---|")
    for label, a, b in comparisons:
        sa = share_series(a[0], os.path.join(base, a[1]), a[2])
        sb = share_series(b[0], os.path.join(base, b[1]), b[2])
        scenes = sorted(s for s in sa if s in sb)
        m, ci = mean_ci([sb[s][0] - sa[s][0] for s in scenes])
        higher = sum(sb[s][0] > sa[s][0] for s in scenes)
        ma = statistics.median(sa[s][1] for s in scenes)
        mb = statistics.median(sb[s][1] for s in scenes)
        print(f"| {label} | `{a[1]}` {a[2]} | `{b[1]}` {b[2]} | {100 * m:+.1f} ± {100 * ci:.1f} | "
              f"{higher} of {len(scenes)} | {ma:.0f} / {mb:.0f} ({mb / ma:.2f}x) |")


# The paired comparisons of the held-out generated scenes that docs/experiments.md discusses:
# (label, A, B), each side (kind, folder under bench/results, planner or ablation row).
GENERATED_COMPARISONS = [
    ("Aimed rollout against greedy (npfkct, single network)",
     ("cells", "generated/rollout-greedy", "npfkct"), ("rows", "ablation/generated", "rollout")),
    ("Ensemble model against the single network (npfkct, aimed rollout)",
     ("rows", "ablation/generated", "rollout"), ("cells", "generated/rollout-aimed", "npfkct")),
    ("npfkct against kct (aimed rollout)",
     ("cells", "generated/rollout-aimed", "kct"), ("cells", "generated/rollout-aimed", "npfkct")),
    ("1 s of CPU per step against 0.25 s (npfkct, greedy rollout)",
     ("cells", "generated/run2", "npfkct"), ("cells", "generated/budget1000", "npfkct")),
    ("v2 set: npfkct against kct (run 2)",
     ("cells", "generated-v2/run2", "kct"), ("cells", "generated-v2/run2", "npfkct")),
    ("v2 set: the filter's ceiling against kct (npfkct `filter.exact=1`: g computed exactly)",
     ("cells", "generated-v2/run2", "kct"), ("cells", "generated-v2/filter-exact", "npfkct")),
    ("v2 set: the filter's ceiling against the network (npfkct `filter.exact=1` against npfkct)",
     ("cells", "generated-v2/run2", "npfkct"), ("cells", "generated-v2/filter-exact", "npfkct")),
] + [
    (f"Faster model and machine, run 2 against run 1 ({p}, greedy rollout)",
     ("cells", "generated/run1", p), ("cells", "generated/run2", p))
    for p in ["npfkct", "kct", "gpomcp", "pomcp-joint", "vomcpow"]
] + [
    ("Aimed rollout against run 2's greedy one (npfkct, single network)",
     ("cells", "generated/run2", "npfkct"), ("rows", "ablation/generated", "rollout")),
] + [
    (f"Aimed rollout against run 2's greedy one ({p})",
     ("cells", "generated/run2", p), ("cells", "generated/rollout-aimed", p))
    for p in ["kct", "gpomcp", "pomcp-joint", "vomcpow"]
]


DOCS_PREAMBLE = """\
# Benchmarks

<!-- Written by `python3 bench/results_table.py docs > docs/benchmarks.md` from the files in
bench/results. Edit the script, not this file: tests/test_results_table.py fails when they differ.
-->

Every table in this file is computed by `bench/results_table.py` from the raw cells kept in
`bench/results/`. Each section names the script that measures its cells (a bench script run again
measures only the cells that are missing) and the command that prints the table alone. What the
figures mean, and what was tried on the way to them, is in [experiments.md](experiments.md).

## Protocol

- **Budget.** CPU time of the planning thread (`CLOCK_THREAD_CPUTIME_ID`): 1 s per step on the
  paper's six scenes, 0.25 s on generated scenes (`npfkct-bench --cpu-ms`; the server's
  `budget.cpuMs`; the solver's `Budget::cpu_ms`). The paper used 60 s of wall time per step. A
  unit test (`solver/test/termination_test.cc`) holds the budget within 5% while another thread
  burns the same core. CPU time shrinks far less than wall time when other work shares the
  machine, but it is not the same on every machine: a second 2-core machine of the same kind ran
  the same planner at about 0.7x the simulations per CPU-second of the first, and more work
  beside the bench costs a little more (cache sharing). Every cell records its median simulations
  per CPU-second, the commit it was measured at and the machine, so such differences can be seen.
  The bench runs two trials at once on 2 cores. The filter's tensor work runs on the planning
  thread (one libtorch and one OpenBLAS thread), so its time is inside the budget.
- **Trials and seeds.** 20 trials per cell on the paper's scenes, 5 per generated scene; trial i
  is seeded 1000003 + i in every cell, so every planner meets the same world draws, noise and
  particles. Success is the target removed within 50 steps. Generated scenes come from
  `npfkct-scenegen --seed N`: the held-out benchmark uses seeds 900001-900030, the tuning scenes
  910001-910020, the filter's training data 30001-830000 and its validation data 20001-22000; no
  training data comes from seeds above 900000.
- **Intervals.** Two-sided 95% Student's t intervals of the mean with n - 1 degrees of freedom
  (`common/include/npfkct/common/stats.h` in the bench; this script computes derived figures the
  same way). A share of the oracle is, per scene, the planner's mean reward over the oracle's;
  over many scenes, the mean of those shares ± the t interval over the scenes. A paired change
  is the mean of per-scene differences ± their t interval.
- **One model for every planner.** 300 particles, search depth 12, gamma 0.9, the reward table of
  [architecture.md](architecture.md#the-object-search-model), base clearance 0.05 m, and one
  rollout policy, the model's, for every planner (the discrete planners roll out in the same
  hybrid model). The default is the aimed rollout (`SearchRollout::kAimed`, `npfkct-bench
  --rollout aimed`): a legal declare or remove when the particle's odds allow it, else, with
  probability 0.5, a camera aimed at a placement of the target drawn from the grid world (drawn
  again, up to 4 times, while it lies inside a known object still standing), else a uniformly
  random feasible configuration. Where a run or row says greedy, it ran `--rollout greedy`, the
  same without the aimed moves.
- **Starts.** The robot starts in its rest pose (lift, pan and tilt 0) out of view of every
  workspace, so no planner gets a free first look.
- **Files.** A cell is one JSON-lines file (`bench/results/table1/RUN/SCENE/PLANNER.jsonl`,
  `bench/results/generated/RUN/SEED/PLANNER.jsonl`, ...) holding every trial's reward and steps,
  the commit and the machine. The scenario files are in `scenarios/`; generated scenes are written
  into the build folder by the bench scripts.
"""

# Each section of docs/benchmarks.md: (title, hand-written text, the tables), a table being a
# function of the results folder that prints Markdown.
DOCS_SECTIONS = [
    ("Table 1: the paper's six scenes", """\
Every planner of the registry on the paper's scenes, 1 s of CPU per step, 20 trials per cell
(run 4, aimed rollout, the shipped ensemble filter model).

    bench/bench_table1.sh --run run4                                  # the cells
    python3 bench/results_table.py table1 bench/results/table1/run4   # the table
""", [lambda r: table1(os.path.join(r, "table1", "run4"))]),
    ("Repeatability of Table 1", """\
The same cells measured again. Run 2 repeats Loose1 and Complex1 for every planner, and Hidden1
and Covered1 for the planners that beat NPF-kCT there; run 3 is every cell with the greedy
rollout, run 4 (Table 1) every cell with the aimed rollout. A cell agrees when each run's mean
lies inside the other run's 95% interval.

    SCENES="loose1 hidden1" bench/bench_table1.sh --run house         # after the restructure
    SCENES="loose1 complex1" bench/bench_table1.sh --run run2
    SCENES="hidden1 covered1" PLANNERS="oracle npfkct kct pomcp-joint gpomcp" \\
      bench/bench_table1.sh --run run2
    python3 bench/results_table.py compare bench/results/table1/run1 bench/results/table1/run2
""", [lambda r: compare(os.path.join(r, "table1", "run1"), os.path.join(r, "table1", "run2")),
      lambda r: print("\nRun 3 (greedy rollout) against run 4 (aimed rollout; npfkct's cells of "
                      "run 4 are the ensemble's):\n"),
      lambda r: compare(os.path.join(r, "table1", "run3"), os.path.join(r, "table1", "run4")),
      lambda r: print("\nRun 1 against run 3 (both greedy; run 3 with a faster model, on "
                      "another machine), agreement only:\n"),
      lambda r: print(capture(compare, os.path.join(r, "table1", "run1"),
                              os.path.join(r, "table1", "run3")).rstrip().splitlines()[-1]),
      lambda r: print("\nRun house (Loose1 and Hidden1 again after the code was moved into its "
                      "layers and the planners into one registry of factories) against run 4:\n"),
      lambda r: compare(os.path.join(r, "table1", "run4"), os.path.join(r, "table1", "house")),
      lambda r: print(inside_count(os.path.join(r, "table1", "run4"),
                                   os.path.join(r, "table1", "house")))]),
    ("Which side first: paper scenes mirrored", """\
Hidden1, Complex1 and Covered1 beside their mirror images (every object's position mirrored across
the table's short axis), at Table 1's protocol, with the trials whose first view saw the target
(from `--trace`, `bench/results/mirror/SCENE/PLANNER.first-views`).

    bench/bench_mirror.sh
    python3 bench/results_table.py mirror bench/results/mirror
""", [lambda r: mirror(os.path.join(r, "mirror"))]),
    ("Held-out generated scenes", """\
The 30 held-out scenes of `npfkct-scenegen` (seeds 900001-900030), 0.25 s of CPU per step, 5
trials per scene and planner, aimed rollout. `oracle-cover-unknown` is a second ceiling: the oracle
not told which object covers the target.

    bench/bench_generated.sh --run rollout-aimed
    python3 bench/results_table.py generated bench/results/generated/rollout-aimed

The second table (run `regression`) ran `oracle`, `npfkct` and `kct` again with kCT's final
action by regression (the default since 83f8f9b); its other planners' cells are
`rollout-aimed`'s. The scene files are kept in `bench/results/generated/scenes`; they are
`rollout-aimed`'s scenes (the oracle's steps match that run's in 144 of 150 trials; the other six,
all first trials, differ by one step: the oracle changed in between).

    PLANNERS="oracle npfkct kct" bench/bench_generated.sh --run regression  # + the others
    python3 bench/results_table.py generated bench/results/generated/regression \\
      bench/results/generated/scenes
""", [lambda r: generated(os.path.join(r, "generated", "rollout-aimed")),
      lambda r: print(),
      lambda r: generated(os.path.join(r, "generated", "regression"),
                          os.path.join(r, "generated", "scenes"))]),
    ("Held-out v2 generated scenes", """\
The 60 held-out scenes of `npfkct-scenegen --version 2` (seeds 930001-930060: 20 with the target in
the open, 20 hidden behind walls or in pockets, 20 covered, among decoy covers, stacked covers and
immovable boxes; the files are kept in `bench/results/generated-v2/scenes`), 0.25 s of CPU per
step, 5 trials per scene and planner, aimed rollout, the shipped filter. `nbv` is the greedy
next-best view over the same belief, with no tree; `rollout` the model's rollout policy with no
search. `oracle-cover-unknown` is a reference told part of the answer: where every box is, seen
or not, with its views aimed at the true target, but not which box covers it (it clears the
movable box of the largest footprint first). Run 2 ran `npfkct` and `kct` again with kCT's final
action by regression (the default since 83f8f9b), and `oracle-cover-unknown` (at 915dc5f); its
`oracle`, `nbv`, `gpomcp` and `rollout` cells are run 1's, planners that change does not touch.
Run 1 (every planner, the sphere rule) is the second table: a rerun inside its intervals.

    SCENE_VERSION=2 bench/bench_generated.sh --run run1
    SCENE_VERSION=2 PLANNERS="npfkct kct oracle-cover-unknown" bench/bench_generated.sh \
      --run run2  # + run1's others
    python3 bench/results_table.py generated bench/results/generated-v2/run2 \\
      bench/results/generated-v2/scenes
""", [lambda r: generated(os.path.join(r, "generated-v2", "run2"),
                          os.path.join(r, "generated-v2", "scenes")),
      lambda r: print(),
      lambda r: generated_runs([("run1 (sphere rule)", os.path.join(r, "generated-v2", "run1"))])]),
    ("Held-out generated scenes by placement of the target", """\
The same cells grouped by where the generator put the target (in the open, hidden behind tall
boxes, covered by a larger box), as each scene file's description says. The scene files are not
kept in `bench/results` (`bench/bench_generated.sh` writes them into the build folder with
`npfkct-scenegen`), so this table is the one `bench_generated.sh` wrote with them, copied from
`bench/results/generated/rollout-aimed/summary.md`:

    python3 bench/results_table.py generated bench/results/generated/rollout-aimed \\
      build/generated-scenes
""", [lambda r: print(placement_block(os.path.join(r, "generated", "rollout-aimed",
                                                   "summary.md")))]),
    ("Other runs of the held-out generated scenes", """\
Runs 1 and 2 ran every planner with the greedy rollout (run 2 with the faster model, on a faster
machine); `rollout-greedy` is npfkct with the greedy rollout run beside the aimed one;
`budget1000` is npfkct with 1 s of CPU per step instead of 0.25 s (greedy rollout).

    ROLLOUT=greedy bench/bench_generated.sh --run run2
    PLANNERS="oracle npfkct" ROLLOUT=greedy bench/bench_generated.sh --run rollout-greedy
    PLANNERS="oracle npfkct" ROLLOUT=greedy bench/bench_generated.sh --run budget1000 --cpu-ms 1000
""", [lambda r: generated_runs([(name, os.path.join(r, "generated", name))
                                for name in ["run1", "run2", "rollout-greedy", "budget1000"]])]),
    ("Paired comparisons on the held-out generated scenes", """\
Two sets of cells compared scene by scene (each against the oracle of its own folder; `rows` of
`ablation/generated` are the ablation's rows below). The v2 rows are on the 60 v2 held-out scenes;
`generated-v2/filter-exact` holds `npfkct` with `filter.exact=1` (at 0a5c4eb) beside copies of
run 2's `oracle` and `kct` cells:

    SCENE_VERSION=2 PLANNERS=npfkct OPTS=filter.exact=1 bench/bench_generated.sh \\
      --run filter-exact  # + run 2's oracle and kct cells
""", [lambda r: paired(GENERATED_COMPARISONS, r)]),
    ("Ablation", """\
NPF-kCT from the paper's algorithm to the shipped planner, one change per row, each row keeping
the changes above it, on the 30 held-out generated scenes at their protocol. The rows `filter`,
`rollout` and `lcb` ran the single filter network shipped before the ensemble
(`bench/models/filter-single.pt`, under the name `filter.pt`); `ensemble` is the shipped model.
Rows measured and not kept are compared with the kept row they modify.

    bench/bench_ablation.sh --generated
    ROWS="visits lcb" bench/bench_ablation.sh --generated
    python3 bench/results_table.py ablation bench/results/ablation/generated
""", [lambda r: ablation(os.path.join(r, "ablation", "generated"))]),
    ("Sensitivity of kCT's defaults", """\
`npfkct` with its defaults and with one option changed per row, on the 20 tuning scenes
(seeds 910001-910020) at the generated scenes' protocol, greedy rollout; then Net_sam's own
settings with the aimed rollout.

    bench/bench_sensitivity.sh
    python3 bench/results_table.py sensitivity bench/results/sensitivity/run1
    ROWS="oracle defaults filter.confidence=0.3 filter.confidence=0.7 filter.candidates=2000" \\
      bench/bench_sensitivity.sh --run filter
    python3 bench/results_table.py sensitivity bench/results/sensitivity/filter
""", [lambda r: sensitivity(os.path.join(r, "sensitivity", "run1")),
      lambda r: print(),
      lambda r: sensitivity(os.path.join(r, "sensitivity", "filter"))]),
    ("Estimator experiments on the v2 tuning scenes", """\
`npfkct` with one change of its value estimate or belief per row, beside the references, on the 30
v2 tuning scenes (`npfkct-scenegen --version 2`, seeds 850001-850030, kept in
`bench/results/estimator-v2/scenes`), 3 trials per scene, 0.25 s of CPU per step. Rows
`r-co-0` and `obstacle-covers` were stopped after 5 scenes (both far below the defaults there);
`min-cover-0.06` ran a patch that was not kept (a box with an extent under 6 cm neither covers nor
shades the guessed target), the `clear-macro` rows the clear macro of 267939c, reverted; `oracle`, `nbv`, `kct`, `defaults` and `depth30` ran at edca0cc, the
others at the commit each cell records. What the rows mean: docs/experiments.md. The second
table is a later run (`reuse1`; its cells record 8851d9b, 3faa533 and 491accf, which change no
planner) with its own `defaults` row beside the rows it compares; its `oracle` and `nbv` cells
are run1's; its `regression` row ran at 9804c30, before the regressed final action became kCT's
default (the `defaults` row is the sphere rule). The third table (`covers1`, at 74dc901) runs the
defaults with the regressed final action beside the row `covers`, with run1's `oracle` and `nbv`;
its row `covers-grid-free-3` ran later (68efb37; "-dirty" there is an edit of this script), and
later still `filter-exact` (the filter's ceiling: g computed exactly in place of the network)
and `kct` (0a5c4eb).

    bench/bench_estimator.sh
    python3 bench/results_table.py estimator bench/results/estimator-v2/run1 \\
      bench/results/estimator-v2/scenes
    ROWS="defaults reuse rollout-first regression" bench/bench_estimator.sh --run reuse1
    python3 bench/results_table.py estimator bench/results/estimator-v2/reuse1 \\
      bench/results/estimator-v2/scenes
    ROWS="defaults covers covers-grid-free-3 filter-exact kct" bench/bench_estimator.sh \\
      --run covers1
    python3 bench/results_table.py estimator bench/results/estimator-v2/covers1 \\
      bench/results/estimator-v2/scenes
""", [lambda r: estimator(os.path.join(r, "estimator-v2", "run1"),
                          os.path.join(r, "estimator-v2", "scenes")),
      lambda r: print(),
      lambda r: estimator(os.path.join(r, "estimator-v2", "reuse1"),
                          os.path.join(r, "estimator-v2", "scenes")),
      lambda r: print(),
      lambda r: estimator(os.path.join(r, "estimator-v2", "covers1"),
                          os.path.join(r, "estimator-v2", "scenes"))]),
    ("Where the steps go on the v2 tuning scenes", """\
Every step of 2 trials per v2 tuning scene (trials 0 and 1 of the estimator rows, the same world
draws), 0.25 s of CPU per step, from `npfkct-bench --trace` at 915dc5f: the moves, the moves made
while an object the trial removes later could already be declared (idle moves), the obstacles
declared, how many of them were removed later and how many never were. `defaults` is `npfkct`;
`covers` the estimator row of that name (R_co in planning only for declaring what hides the
particle's guessed target; the world still pays it for every obstacle). What the figures say:
[experiments.md](experiments.md#where-do-the-steps-go-on-the-v2-scenes).

    TRACE=1 ROWS="oracle oracle-cover-unknown nbv defaults covers" bench/bench_estimator.sh \\
      --run steps1 --trials 2
    python3 bench/results_table.py steps bench/results/estimator-v2/steps1 \\
      bench/results/estimator-v2/scenes
""", [lambda r: steps(os.path.join(r, "estimator-v2", "steps1"),
                      os.path.join(r, "estimator-v2", "scenes"))]),
    ("Planning on several cores", """\
`npfkct` with 1 and 2 root-parallel search threads, 1 s of wall time per step, trials one after
the other on an otherwise idle 2-core machine, 8 trials per scene.

    bench/bench_threads.sh 8
    python3 bench/results_table.py threads bench/results/threads/npfkct-t1.jsonl \\
      bench/results/threads/npfkct-t2.jsonl
""", [lambda r: threads(os.path.join(r, "threads", "npfkct-t1.jsonl"),
                        os.path.join(r, "threads", "npfkct-t2.jsonl"))]),
    ("Simulation speed", """\
The object-search model's simulation speed against the build before its faster occlusion test
(`base`; the commit is named in `bench/results/model_speed/summary.md`): both builds in turn, 3
rounds, 1,000 simulations per step, 2 trials per cell, the same seeds.

    bench/bench_model_speed.sh BASE_COMMIT
    python3 bench/results_table.py model-speed bench/results/model_speed
""", [lambda r: model_speed(os.path.join(r, "model_speed"))]),
    ("Classic problems with published results", """\
One table of the solver beside its peers: the planners of `solver/` on the problems their authors
published (`solver/include/npfkct/solver/models/`), Tag at the DESPOT papers' protocol, the
DESPOT side-by-side (details in the next section) and the VPW paper's LQG, each row with the
command that measures it. The rows at 1 s of CPU give kCT (the project's defaults) and the planner
beside it the same rollout, run on one machine; the rows above them used wall-clock or simulation
budgets. kCT's rows say which tree ran: "the paper's tree" (every point drawn in a sphere shares its
subtree; the defaults until point children replaced them) or "point children" (each point its own
subtree, the spheres choosing where the next goes: the defaults now; docs/experiments.md, "kCT's
defaults: point children"; its 500 episodes at the VPW configuration ran before the records named
the tree, and their lines are kept in `bench/results/kct-points/vdptag-vpw-1s.jsonl`). Pooled rows
pool runs with new episodes (other seeds) as independent samples. "The VPW paper's configuration" is
VOOTreeSearch.jl's `scripts/VDPTag2/compare.jl`: ToNextML rollouts, the root's first action towards
the belief's mean target's next position (RootToNextMLFirst), 100,000 particles; kCT is given the
same, and with point children VOMCPOW's observation widening (2.5 N^(1/100); the paper's tree ran
with POMCPOW's, 5 N^(1/100)). Standard errors are the sample standard deviation over the square root
of the episodes (or plans).

    bench/bench_classic.sh                     # every section; or name some: tiger rocksample ...
    SEED=2 THREADS=1 bench/bench_classic.sh kct-vdptag
    bench/bench_classic.sh lqg vdptag-published tag
    python3 bench/results_table.py classic bench/results/classic.jsonl
    python3 bench/results_table.py classic-paired FILE [BASE_PLANNER]   # one seed's runs, paired
""", [lambda r: classic(os.path.join(r, "classic.jsonl"))]),
    ("Beside the authors' DESPOT", """\
The solver's planners and the authors' DESPOT (AdaCompNUS/despot, built from a checkout outside
the repository by the script) on RockSample(7,8), run on this machine with episodes interleaved
(episode i of every planner in one job, their order rotating; two jobs at once, one core each),
0.1 s of CPU per step, 90 steps at most. Their DESPOT uses their RockSample defaults (500
scenarios, depth 90, xi 0.95, no pruning, the MDP upper bound, the "go east" lower bound, the
exact belief over the 256 rock sets); ours (`solver/include/npfkct/solver/despot.h`, written
from Somani et al. 2013 and Ye et al. 2017) has the same settings and bounds
(`RockSample::UpperBound`, `DefaultMove`) over a 4,096-particle belief. Both free the tree
outside the search's clock (ours when the step is taken). Trials per step are the median over an
episode's steps, then over episodes, with two episodes running at once.

    DESPOT_SRC=/path/to/despot bench/bench_despot.sh 60
    FIRST=61 OUT=bench/results/despot/rocksample-0.1s-run2.jsonl \\
      DESPOT_SRC=/path/to/despot bench/bench_despot.sh 60
    python3 bench/results_table.py despot bench/results/despot/rocksample-0.1s*.jsonl
""", [lambda r: despot_table(*despot_files(r))]),
    ("What caps kCT on SimpleLightDark", """\
kCT with the project's defaults on SimpleLightDark, 200 episodes a run; the runs of one seed start
from the same initial states. Leaves are valued as the published experiments value them (the fully
observable MDP's value, "fo") or by a hand-written value of the detour the observations make
necessary ("localize": the fewest moves to the light, where an observation is exact, then one move
to 0 and the declaration; `SimpleLightDark::Leaf::kLocalize`, `npfkct-bench --rollout localize`).
"localize" is knowledge of this problem, not a default, and no published figure used it. Budgets
are simulations per step or CPU time of the planning thread per step.

    bench/bench_classic.sh lightdark-leaf
    python3 bench/results_table.py lightdark-leaf bench/results/lightdark-leaf.jsonl \\
      bench/results/classic.jsonl
""", [lambda r: lightdark_leaf(os.path.join(r, "lightdark-leaf.jsonl"),
                               os.path.join(r, "classic.jsonl"))]),
    ("How far is SimpleLightDark's optimum", """\
A reference for the tree searches above: `bench/lightdark_optimum.py` solves SimpleLightDark
offline by point-based value iteration (Perseus) on the exact belief over its 121 positions, with
the observations binned (a bin of +-0.001 at the light, 1 wide in [-20, 40), 4 wide beyond). A
policy that sees only the bins is a policy of the continuous problem, so the alpha-vectors' value
at the initial belief is a lower bound on the continuous optimum; the policy is then played with
the model's continuous observations (standard error: sd / sqrt(episodes)). QMDP (full
observability after the first step) bounds every policy from above. kCT's 200 episodes of seed 11
at 270,000 simulations (the same episodes, action for action, as at 1 s of CPU) are traced by
`npfkct-bench --trace` and each decision is scored on the exact belief: Q(b, best) - Q(b, taken)
with Q from the same alpha-vectors, discounted to the episode's start.

    bench/bench_classic.sh lightdark-optimum
    python3 bench/results_table.py lightdark-optimum bench/results/classic.jsonl
""", [lambda r: lightdark_optimum(os.path.join(r, "classic.jsonl"))]),
    ("The neural process filter", """\
The shipped model (an ensemble of three networks) on test sets of layouts it never saw, 1,500
snapshots each; the interval of an accuracy is the 95% normal interval of the ratio over
snapshots (delta method), a lower bound since snapshots of one scene are not independent.

    MODEL=/tmp/filter.pt tools/train_filter.sh   # data, training, the ensemble, these figures
    python3 bench/results_table.py filter bench/results/filter_eval.json \\
      bench/results/filter_bench.json

`tools/train_filter.sh` writes `bench/results/filter_eval.json` (`npfkct-train evaluate`, one line
per test set) and `filter_bench.json` (`npfkct-train bench`); without `MODEL` it replaces the
shipped `filter/model/filter.pt`.
""", [lambda r: filter_figures(os.path.join(r, "filter_eval.json"),
                               os.path.join(r, "filter_bench.json"))]),
    ("Perception in the loop", """\
Loose1 and Hidden1 with the simulator rendering each view (ray-cast 640x480 RGB-D, the robot
reporting its pose with localization noise) and the perception pipeline making the detections:
`perception` scores the objects by SIFT and colour against the target's photos, `boxes` by a
simulated YOLO-style detector's 2D boxes sent with the depth (no image, no photos; the target
boxed with probability 1 - noise.falseDetection, another object with that probability). Beside
them the simulator's geometric observation (`kct`, 20 trials, 1 s of CPU per step, the same
seeds). Then the pipeline's time per stage on one core over the frames of the manual view set
of Loose1, Hidden1 and Complex1.

    bench/bench_perception.sh
    python3 bench/results_table.py flat bench/results/perception.jsonl
    python3 bench/results_table.py perception-stages bench/results/perception_stages.json
""", [lambda r: flat(os.path.join(r, "perception.jsonl")), lambda r: print(),
      lambda r: perception_stages(os.path.join(r, "perception_stages.json"))]),
    ("Prior maps from SLAM", """\
`bench/bench_maps.py` drives a scene's truth with `npfkct-drive` against a session made from its
hand-written furniture and base regions, and against one made from the same room rasterised
into map_server's YAML + PGM (walls on the border, the furniture's footprints occupied) with the
workspaces traced as polygons and no base regions (npfkct, 0.25 s of CPU per step, the same seeds
for both). `bench/bench_house_map.py` sends rendered 640x480 frames of Loose1's episodes through
the server for three sessions on a 40 m x 40 m grid at 5 cm with three tables, and (`--plain`)
on Loose1's own room: the server's CPU per `:observe`, registration's wall-clock time within it,
and the memory each session keeps.

    bench/bench_maps.py --scenario loose1   (and hidden1, complex1)
    bench/bench_house_map.py; bench/bench_house_map.py --plain
    python3 bench/results_table.py maps bench/results/maps
""", [lambda r: maps_table(os.path.join(r, "maps"))]),
    ("Server load", """\
`bench/load_bench.py` drives N sessions at once against one server, each planning with a 100 ms
budget and observing through the simulated robot, on a 2-core machine. Overhead is the `:plan`
latency the client sees minus the planner's own `elapsedMs`. These rows were measured before
planning admission existed (the script now starts the server with `--plan-queue` equal to the
sessions, so that every session may wait for a slot instead of being refused). With one or two
sessions the resident memory per session is mostly the process's own.

    for n in 1 2 8 32; do bench/load_bench.py --sessions $n; done > bench/results/load.jsonl
    python3 bench/results_table.py load bench/results/load.jsonl
""", [lambda r: load_table(os.path.join(r, "load.jsonl"))]),
    ("Fleet", """\
`bench/fleet_bench.py` starts PostgreSQL (with `fsync=off`, as in the tests), nginx and 1 or 3
replicas (2 planning slots each) on one machine, and drives simulated robots through nginx; then,
5 times, kills with SIGKILL the replica holding the most of their sessions. "Served again" is the
time from the kill until a GET of each of its sessions through nginx answers 200; "next step"
until the robot's next acknowledged request. These figures were measured while two other
benchmark processes ran on the same 2 cores (see [fleet.md](fleet.md)).

    bench/fleet_bench.py --out bench/results/fleet.json
    python3 bench/results_table.py fleet bench/results/fleet.json
""", [lambda r: fleet_table(os.path.join(r, "fleet.json"))]),
]


def capture(function, *args):
    """What `function(*args)` prints, as a string."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        function(*args)
    return out.getvalue()


def placement_block(summary_path):
    """The per-placement table of a generated run's summary.md, as bench_generated.sh wrote it
    (it needs the scene files, which bench/results does not keep)."""
    with open(summary_path, encoding="utf-8") as f:
        text = f.read()
    start = text.find("By placement of the target")
    if start < 0:
        sys.exit(f"{summary_path}: no table by placement")
    return text[start:].strip()


def docs():
    """docs/benchmarks.md, from the results under bench/results beside this script."""
    results = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
    parts = [DOCS_PREAMBLE]
    for title, text, tables in DOCS_SECTIONS:
        body = "".join(capture(table, results) for table in tables).strip()
        parts.append(f"## {title}\n\n{text}\n{body}\n")
    return "\n".join(parts)


def main():
    commands = {"table1": (1, None), "generated": (1, 2), "ablation": (1, 1),
                "sensitivity": (1, 1), "estimator": (1, 2), "mirror": (1, 1), "trace": (1, 1), "steps": (2, 2), "compare": (2, 2),
                "flat": (1, 1), "threads": (2, 2), "model-speed": (1, 1), "classic": (1, 1), "classic-paired": (1, 2),
                "lightdark-leaf": (1, None), "lightdark-optimum": (1, 1),
                "filter": (2, 2), "despot": (1, None), "perception-stages": (1, 1), "load": (1, 1), "fleet": (1, 1),
                "maps": (1, 1),
                "docs": (0, 1)}
    args = sys.argv[2:]
    if len(sys.argv) < 2 or sys.argv[1] not in commands:
        print(__doc__)
        sys.exit(2)
    least, most = commands[sys.argv[1]]
    if len(args) < least or (most is not None and len(args) > most):
        print(__doc__)
        sys.exit(2)
    command = sys.argv[1]
    if command == "docs":
        text = docs()
        if args == ["--write"]:
            path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs",
                                "benchmarks.md")
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
        elif args:
            print(__doc__)
            sys.exit(2)
        else:
            sys.stdout.write(text)
    elif command == "table1":
        table1(*args)
    elif command == "generated":
        generated(*args)
    elif command == "ablation":
        ablation(*args)
    elif command == "sensitivity":
        sensitivity(*args)
    elif command == "estimator":
        estimator(*args)
    elif command == "mirror":
        mirror(*args)
    elif command == "trace":
        trace(*args)
    elif command == "steps":
        steps(*args)
    elif command == "compare":
        compare(*args)
    elif command == "threads":
        threads(*args)
    elif command == "model-speed":
        model_speed(*args)
    elif command == "classic":
        classic(*args)
    elif command == "classic-paired":
        classic_paired(*args)
    elif command == "lightdark-leaf":
        lightdark_leaf(*args)
    elif command == "lightdark-optimum":
        lightdark_optimum(*args)
    elif command == "despot":
        despot_table(*args)
    elif command == "filter":
        filter_figures(*args)
    elif command == "perception-stages":
        perception_stages(*args)
    elif command == "load":
        load_table(*args)
    elif command == "maps":
        maps_table(*args)
    elif command == "fleet":
        fleet_table(*args)
    else:
        flat(*args)


if __name__ == "__main__":
    main()
