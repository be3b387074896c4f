#!/usr/bin/env python3
"""Turns npfkct-bench object-search JSON lines into the Markdown table of the README.

Rows are planners (with the observation mode when a file mixes several), columns scenarios; a cell
is 'mean discounted reward ± 95% CI | mean steps ± 95% CI | success rate', as in the paper's
Table 1. A last column gives the median simulations per second on Complex1 when it is present.
Usage: scripts/results_table.py RESULTS.jsonl > TABLE.md
"""

import json
import sys


def main():
    rows = [json.loads(line) for line in open(sys.argv[1], encoding="utf-8") if line.strip()]
    scenarios, planners = [], []
    modes = {r.get("observe", "geometric") for r in rows}
    cells = {}
    for r in rows:
        name = r["planner"] + (f" ({r['observe']})" if len(modes) > 1 else "")
        if r["scenario"] not in scenarios:
            scenarios.append(r["scenario"])
        if name not in planners:
            planners.append(name)
        cells[(name, r["scenario"])] = r
    complex_col = "Complex1" in scenarios
    head = "| Planner |" + "".join(f" {s} |" for s in scenarios)
    head += " sims/s (Complex1) |" if complex_col else ""
    print(head)
    print("|---|" + "---|" * (len(scenarios) + (1 if complex_col else 0)))
    for p in planners:
        line = f"| {p} |"
        for s in scenarios:
            r = cells.get((p, s))
            line += (" – |" if r is None else
                     f" {r['mean_discounted_reward']:.1f} ± {r['ci95']:.1f} \\| "
                     f"{r['mean_steps']:.1f} ± {r['ci95_steps']:.1f} \\| "
                     f"{100 * r['success_rate']:.0f}% |")
        if complex_col:
            r = cells.get((p, "Complex1"))
            line += " – |" if r is None else f" {r['median_sims_per_second']:.0f} |"
        print(line)


if __name__ == "__main__":
    main()
