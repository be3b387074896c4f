#!/usr/bin/env python3
"""Builds the README's benchmark tables from npfkct-bench JSON lines.

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
  results_table.py mirror DIR      Paper scenes beside their mirror images
                                   (bench/bench_mirror.sh): per planner and scene the reward,
                                   steps and how many trials' first view saw the target
                                   (DIR/SCENE/PLANNER.first-views, the step-1 lines of --trace).
  results_table.py trace FILE      What the trials of an npfkct-bench --trace file did, per scene
                                   and planner: steps, moves, moves made while an object the
                                   trial removes later could already be declared, obstacles
                                   declared and how many of them were removed later, means per
                                   trial.
  results_table.py compare A B     Whether two runs of the same cells agree: each mean inside the
                                   other run's 95% interval.
  results_table.py flat FILE       A table from one file of JSON lines (rows planners, columns
                                   scenarios), as written by --observe comparisons.

Intervals are two-sided 95% Student's t intervals of the mean (n - 1 degrees of freedom); the bench
writes them per cell, and this script computes them the same way for derived figures.
"""

import glob
import json
import math
import os
import re
import sys

PAPER_SCENES = ["Loose1", "Loose2", "Hidden1", "Covered1", "Complex1", "Fig16"]
PLANNER_ORDER = ["oracle", "oracle-cover-unknown", "npfkct", "kct", "pomcp", "gpomcp",
                 "pomcp-joint", "pomcpow", "vomcpow", "advt"]


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
        shares, successes, steps, n = {}, [], [], 0
        for s in scenes:
            r, o = cells.get((g, s)), cells.get(("oracle", s))
            if r is None:
                continue
            n += 1
            successes += r.get("successes", [])
            steps += r.get("steps", [])
            if o is not None and o["mean_discounted_reward"] > 0:
                shares[s] = r["mean_discounted_reward"] / o["mean_discounted_reward"]
        m, ci = mean_ci(list(shares.values()))
        sm, sci = mean_ci(steps)
        succ = 100 * sum(successes) / len(successes) if successes else float("nan")
        out[g] = {"share": m, "share_ci": ci, "success": succ, "steps": sm, "steps_ci": sci,
                  "scenes": n, "shares": shares}
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
    print("| Planner | Share of the oracle's reward | Success | Steps | Scenes |")
    print("|---|---|---|---|---|")
    for p, x in oracle_summary(cells, planners, scenes).items():
        print(f"| {p} | {100 * x['share']:.1f}% ± {100 * x['share_ci']:.1f} | "
              f"{x['success']:.1f}% | {x['steps']:.1f} ± {x['steps_ci']:.1f} | {x['scenes']} |")
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


def print_share_row(cells, summary, scenes, row, base, label):
    """One row of a table over many scenes: its mean share of the oracle's reward and its change
    against the row `base` as a paired difference over the scenes both rows have."""
    x = summary[row]
    change = "–"
    if base is not None:
        a, b = summary[base]["shares"], x["shares"]
        diffs = [b[s] - a[s] for s in scenes if s in a and s in b]
        m, ci = mean_ci(diffs)
        if diffs:
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
        print_share_row(cells, summary, scenes, row, previous, row)
        previous = row
    rejected = [row for row in rows if row in REJECTED_ROWS]
    if rejected:
        print("\nTried and not kept (change: against the kept row it modifies):\n")
        print(SHARE_HEADER)
        for row in rejected:
            base = REJECTED_ROWS[row] if REJECTED_ROWS[row] in summary else None
            label = f"{row} (against {REJECTED_ROWS[row]})"
            print_share_row(cells, summary, scenes, row, base, label)


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
            print_share_row(cells, summary, scenes, row, None if row == base else base, row)


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


def trace(path):
    # (scene, planner, trial) -> [(kind, object, the objects that could be declared after it)];
    # the bench marks an object that can be declared with * after its face counts.
    trials = {}
    for line in open(path, encoding="utf-8"):
        m = TRACE_LINE.match(line)
        if m:
            known = line.rsplit("|", 1)[-1].split()
            ready = {t.rsplit(":", 1)[0] for t in known if t.endswith("*")}
            trials.setdefault((m[1], m[2], int(m[3])), []).append((m[5], m[6], ready))
    groups = {}
    for (scene, planner, _), actions in trials.items():
        declared = {o for k, o, _ in actions if k == "declare obstacle"}
        removed = {o for k, o, _ in actions if k == "remove"}
        # A move made while an object the trial removes later could already be declared (after
        # the step before the move): the declaration and removal were due, the move was not.
        idle = sum(k == "move" and bool(actions[i - 1][2] & removed)
                   for i, (k, _, _) in enumerate(actions) if i)
        groups.setdefault((scene, planner), []).append((
            len(actions), sum(k == "move" for k, _, _ in actions), idle, len(declared),
            len(declared & removed)))
    print("| Scene | Planner | Trials | Steps | Moves | of them while an object removed later "
          "could be declared | Obstacles declared | of them removed |")
    print("|---|---|---|---|---|---|---|---|")
    for (scene, planner), rows in sorted(groups.items()):
        means = [sum(r[i] for r in rows) / len(rows) for i in range(5)]
        print(f"| {scene} | {planner} | {len(rows)} | " + " | ".join(f"{m:.2f}" for m in means)
              + " |")


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


def flat(path):
    rows = [json.loads(line) for line in open(path, encoding="utf-8") if line.strip()]
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


def main():
    if len(sys.argv) < 3 or sys.argv[1] not in ("table1", "generated", "ablation", "sensitivity",
                                                 "mirror", "trace", "compare", "flat"):
        print(__doc__)
        sys.exit(2)
    if sys.argv[1] == "table1":
        table1(*sys.argv[2:])
    elif sys.argv[1] == "generated":
        generated(sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else None)
    elif sys.argv[1] == "ablation":
        ablation(sys.argv[2])
    elif sys.argv[1] == "sensitivity":
        sensitivity(sys.argv[2])
    elif sys.argv[1] == "mirror":
        mirror(sys.argv[2])
    elif sys.argv[1] == "trace":
        trace(sys.argv[2])
    elif sys.argv[1] == "compare":
        compare(sys.argv[2], sys.argv[3])
    else:
        flat(sys.argv[2])


if __name__ == "__main__":
    main()
