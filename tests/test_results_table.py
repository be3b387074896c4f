"""bench/results_table.py, which makes the benchmark tables of docs/benchmarks.md: Student's t
quantiles, the share of the oracle's reward and the ablation's paired change, on cells with known
answers; and docs/benchmarks.md itself, which must be what the script makes of bench/results."""

import gzip
import json
import os
import re
import subprocess
import sys

import pytest

SCRIPTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "bench")
sys.path.insert(0, SCRIPTS)
import results_table  # noqa: E402


def test_t_quantiles_match_the_tables():
    # Two-sided 95%: t(0.975, df) from any statistics table.
    for df, t in [(1, 12.706), (4, 2.776), (19, 2.093), (29, 2.045), (1000, 1.962)]:
        assert results_table.t_quantile(0.975, df) == pytest.approx(t, abs=1e-3)


def test_mean_ci_uses_student_t():
    m, ci = results_table.mean_ci([1.0, 2.0, 3.0, 4.0, 5.0])
    assert m == 3.0
    # sd = sqrt(2.5); t(0.975, 4) = 2.7764
    assert ci == pytest.approx(2.7764 * (2.5 ** 0.5) / 5 ** 0.5, rel=1e-3)


def write_cell(root, row, scene, reward, steps=(5, 5), successes=(1, 1), rollout=None):
    os.makedirs(os.path.join(root, row), exist_ok=True)
    record = {"scenario": scene, "planner": "kct" if row != "oracle" else "oracle",
              "options": [], "cpu_ms": 250, "trials": len(steps),
              "mean_discounted_reward": reward, "ci95": 0.0, "mean_steps": sum(steps) / 2,
              "ci95_steps": 0.0, "success_rate": sum(successes) / len(successes),
              "steps": list(steps), "successes": list(successes)}
    if rollout is not None:
        record["rollout"] = rollout
    with open(os.path.join(root, row, scene + ".jsonl"), "w", encoding="utf-8") as f:
        f.write(json.dumps(record) + "\n")


def test_ablation_with_an_oracle_gives_shares_and_paired_changes(tmp_path):
    root = str(tmp_path)
    # Oracle 100 in scene a, 200 in scene b. Row "paper": shares 0.5 and 0.5. Row "aimed": 0.6 and
    # 0.8, so the paired change is +0.1 and +0.3: mean +20 points, t interval
    # t(0.975, 1) * sd / sqrt(2) = 12.706 * 0.1414 / 1.414 = 1.2706 -> 127.1 points.
    write_cell(root, "oracle", "a", 100.0)
    write_cell(root, "oracle", "b", 200.0)
    write_cell(root, "paper", "a", 50.0, successes=(1, 0))
    write_cell(root, "paper", "b", 100.0)
    write_cell(root, "aimed", "a", 60.0)
    write_cell(root, "aimed", "b", 160.0)
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "ablation",
                          root], check=True, capture_output=True, text=True).stdout
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in out.splitlines() if line.startswith("| ") and "---" not in line}
    assert "oracle" not in rows
    assert rows["paper"][1] == "50.0% ± 0.0"
    assert rows["paper"][2] == "–"
    assert rows["paper"][3] == "75.0%"  # 3 of 4 trials
    assert rows["aimed"][1].startswith("70.0% ± ")
    assert rows["aimed"][2] == "+20.0 ± 127.1"
    assert rows["aimed"][3] == "100.0%"


def test_a_rejected_ablation_row_is_compared_with_the_row_it_modifies(tmp_path):
    root = str(tmp_path)
    # Kept rows paper (0.5, 0.5), aimed (0.6, 0.8), sibling (0.9, 0.9); "visits" changes sibling
    # and scores (0.8, 0.7): its change is against sibling (-0.1, -0.2 -> -15 points), not
    # against the row printed above it, and it is left out of the kept chain.
    for row, (a, b) in {"oracle": (100.0, 200.0), "paper": (50.0, 100.0),
                        "aimed": (60.0, 160.0), "sibling": (90.0, 180.0),
                        "visits": (80.0, 140.0)}.items():
        write_cell(root, row, "a", a)
        write_cell(root, row, "b", b)
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "ablation",
                          root], check=True, capture_output=True, text=True).stdout
    kept = out.split("Tried and not kept")[0]
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in out.splitlines() if line.startswith("| ") and "---" not in line}
    assert "visits" not in kept
    assert rows["sibling"][2].startswith("+20.0 ± ")  # against aimed: +0.3, +0.1
    assert rows["visits (against sibling)"][1].startswith("75.0% ± ")
    assert rows["visits (against sibling)"][2].startswith("-15.0 ± ")


def test_an_ablation_row_names_its_rollout(tmp_path):
    root = str(tmp_path)
    # Cells from before npfkct-bench recorded the rollout ran the greedy one.
    for row, rollout in {"oracle": None, "filter": None, "rollout": "aimed"}.items():
        write_cell(root, row, "a", 100.0, rollout=rollout)
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "ablation",
                          root], check=True, capture_output=True, text=True).stdout
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in out.splitlines() if line.startswith("| ") and "---" not in line}
    assert rows["filter"][0] == "`kct --rollout greedy`"
    assert rows["rollout"][0] == "`kct --rollout aimed`"


def test_sensitivity_compares_every_row_with_the_defaults(tmp_path):
    root = str(tmp_path)
    # Defaults (0.5, 0.5); "w1=1" (0.6, 0.8) and "k=4" (0.4, 0.3), each against the defaults, not
    # against the row printed above it: +20 and -15 points.
    for row, (a, b) in {"oracle": (100.0, 200.0), "defaults": (50.0, 100.0),
                        "w1=1": (60.0, 160.0), "k=4": (40.0, 60.0)}.items():
        write_cell(root, row, "a", a)
        write_cell(root, row, "b", b)
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"),
                          "sensitivity", root], check=True, capture_output=True, text=True).stdout
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in out.splitlines() if line.startswith("| ") and "---" not in line}
    assert "oracle" not in rows
    assert rows["defaults"][1] == "50.0% ± 0.0"
    assert rows["defaults"][2] == "–"
    assert rows["w1=1"][2].startswith("+20.0 ± ")
    assert rows["k=4"][2].startswith("-15.0 ± ")


def test_mirror_counts_the_first_views_that_saw_the_target(tmp_path):
    root = str(tmp_path)
    os.makedirs(os.path.join(root, "hidden1"))
    with open(os.path.join(root, "hidden1", "npfkct.jsonl"), "w", encoding="utf-8") as f:
        f.write(json.dumps({"scenario": "Hidden1", "planner": "npfkct", "trials": 2,
                            "mean_discounted_reward": 100.0, "ci95": 0.0, "mean_steps": 5.0,
                            "ci95_steps": 0.0}) + "\n")
    # Two trials: the first view of trial 0 detected the target, that of trial 1 did not (the
    # word "target" in the action part of the line does not count).
    with open(os.path.join(root, "hidden1", "npfkct.first-views"), "w", encoding="utf-8") as f:
        f.write("Hidden1 npfkct trial 0 step  1: move x=2.69 moved sims 1 value 2.0 |"
                " target:3/1 wall-left:0/2\n")
        f.write("Hidden1 npfkct trial 1 step  1: declare target target sims 1 value 2.0 |"
                " wall-left:0/4\n")
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "mirror",
                          root], check=True, capture_output=True, text=True).stdout
    row = [line for line in out.splitlines() if line.startswith("| npfkct")]
    assert row == ["| npfkct | 100.0 ± 0.0 \\| 5.00 ± 0.00 \\| 1/2 |"]


TRACE_LINES = [
    "S p trial 0 step  1: move x=1 y=2 yaw=0 lift=0 pan=0 tilt=0  moved  sims 1 value 1 "
    "| box-1:0/6* box-2:0/6*",
    "S p trial 0 step  2: declare obstacle box-1     declared  sims 1 value 1 root: move n=3 "
    "q=1, declare obstacle box-1 n=2 q=2 | box-1:0/6 box-2:0/6*",
    "S p trial 0 step  3: declare obstacle box-2     declared  sims 1 value 1 | box-1:0/6",
    "S p trial 0 step  4: remove box-1               removed   sims 1 value 1 | box-2:0/6",
    "S p trial 0 step  5: declare target target      declared  sims 1 value 1 | target:6/0",
    "S p trial 0 step  6: remove target              removed   sims 1 value 1 |",
    "S p trial 1 step  1: move x=1 y=2 yaw=0 lift=0 pan=0 tilt=0  moved  sims 1 value 1 "
    "| box-3:1/6* box-4:0/6*",
    "S p trial 1 step  2: move x=1 y=2 yaw=0 lift=0 pan=0 tilt=0  moved  sims 1 value 1 "
    "| box-3:1/6* box-4:0/6*",
    "S p trial 1 step  3: move x=1 y=2 yaw=0 lift=0 pan=0 tilt=0  moved  sims 1 value 1 "
    "| box-3:1/6*",
    "S p trial 1 step  4: declare obstacle box-4     declared  sims 1 value 1 | box-3:1/6*",
    "S p trial 1 step  5: remove box-4               removed   sims 1 value 1 | box-3:1/6*",
    "npfkct: building every target",
]


def test_trace_counts_moves_and_declared_obstacles_per_trial(tmp_path):
    path = tmp_path / "t.trace"
    path.write_text("\n".join(TRACE_LINES) + "\n", encoding="utf-8")
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "trace",
                          str(path)], check=True, capture_output=True, text=True).stdout
    # Trial 0: 6 steps, 1 move (the first, before anything could be declared), 2 obstacles
    # declared, 1 of them removed; trial 1: 5 steps, 3 moves, the last two while box-4, which it
    # removes later, could be declared (box-3, never removed, does not count), 1 obstacle
    # declared and removed.
    assert "| S | p | 2 | 5.50 | 2.00 | 1.00 | 1.50 | 1.00 |" in out.splitlines()


def test_steps_groups_traced_trials_by_placement_and_counts_success(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    with gzip.open(run / "defaults.trace.gz", "wt", encoding="utf-8") as f:
        f.write("\n".join(TRACE_LINES) + "\n")
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "S.json").write_text(json.dumps(
        {"description": "Generated: 4 objects, the target covered by box-1."}), encoding="utf-8")
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "steps",
                          str(run), str(scenes)], check=True, capture_output=True,
                         text=True).stdout
    # As above, and declared but never removed: box-2 in trial 0, none in trial 1 (0.5 a trial);
    # trial 0 ends by removing the target, trial 1 does not (50%).
    figures = "| 2 | 5.5 | 2.0 | 1.0 | 1.5 | 1.0 | 0.5 | 50% |"
    assert f"| defaults | covered (1 scenes) {figures}" in out.splitlines()
    assert f"| defaults | all (1 scenes) {figures}" in out.splitlines()


def test_mirror_pools_a_scene_with_its_mirror_image(tmp_path):
    root = str(tmp_path)
    for scene, rewards in {"hidden1": [100.0, 110.0], "hidden1-mirrored": [90.0, 100.0]}.items():
        os.makedirs(os.path.join(root, scene))
        with open(os.path.join(root, scene, "npfkct.jsonl"), "w", encoding="utf-8") as f:
            f.write(json.dumps({"scenario": scene, "planner": "npfkct", "trials": 2,
                                "mean_discounted_reward": sum(rewards) / 2, "ci95": 0.0,
                                "mean_steps": 5.0, "ci95_steps": 0.0, "rewards": rewards}) + "\n")
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "mirror",
                          root], check=True, capture_output=True, text=True).stdout
    # Pooled 100, 110, 90, 100: mean 100, sd sqrt(200 / 3), t(0.975, 3) = 3.182.
    pooled = [line for line in out.splitlines() if line.startswith("| npfkct |")][-1]
    half = 3.1824 * (200 / 3) ** 0.5 / 2
    assert pooled == f"| npfkct | 100.0 ± {half:.1f} |"


def test_generated_gives_the_target_only_share_and_the_paired_difference_to_nbv(tmp_path):
    runs = tmp_path / "run"
    # npfkct earns 80 and 60 (of which 20 and 0 from obstacle declarations), nbv 50 and 40, the
    # oracle 100 in both scenes: npfkct's target-only shares 0.6 and 0.6, its paired differences
    # to nbv +0.3 and +0.2 (mean +25 points).
    cells = {"gen-1": [("oracle", 100.0, 100.0), ("npfkct", 80.0, 60.0), ("nbv", 50.0, 50.0)],
             "gen-2": [("oracle", 100.0, 100.0), ("npfkct", 60.0, 60.0), ("nbv", 40.0, 40.0)]}
    for scene, rows in cells.items():
        for planner, reward, target in rows:
            os.makedirs(runs / scene, exist_ok=True)
            record = {"scenario": scene, "planner": planner, "cpu_ms": 250, "trials": 1,
                      "mean_discounted_reward": reward, "target_rewards": [target],
                      "steps": [5], "successes": [1]}
            (runs / scene / (planner + ".jsonl")).write_text(json.dumps(record) + "\n",
                                                              encoding="utf-8")
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "generated",
                          str(runs)], check=True, capture_output=True, text=True).stdout
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in out.splitlines() if line.startswith("| ") and "---" not in line}
    assert rows["Planner"][1] == "Target-only share" and rows["Planner"][4] == "vs nbv"
    assert rows["npfkct"][0].startswith("70.0% ± ")
    assert rows["npfkct"][1] == "60.0% ± 0.0"
    assert rows["npfkct"][4].startswith("+25.0 ± ")
    assert rows["nbv"][4] == ""


def test_estimator_compares_share_and_steps_with_the_defaults(tmp_path):
    root = str(tmp_path)
    # Per scene (reward, steps): the defaults (50, 10) and (100, 20); "depth30" (60, 8) and
    # (160, 12): +20 points and -5 steps on average against the defaults.
    rows_in = {"oracle": [(100.0, 5), (200.0, 6)], "defaults": [(50.0, 10), (100.0, 20)],
               "depth30": [(60.0, 8), (160.0, 12)]}
    for row, cells in rows_in.items():
        for scene, (reward, steps) in zip(["a", "b"], cells):
            os.makedirs(os.path.join(root, row), exist_ok=True)
            record = {"scenario": scene, "planner": "oracle" if row == "oracle" else "npfkct",
                      "cpu_ms": 250, "trials": 1, "mean_discounted_reward": reward,
                      "mean_steps": steps, "steps": [steps], "successes": [1],
                      "options": ["search.max_depth=30"] if row == "depth30" else [],
                      "rollout": "aimed", "grid_sampling": "odds" if row == "depth30" else
                      "probability"}
            with open(os.path.join(root, row, scene + ".jsonl"), "w", encoding="utf-8") as f:
                f.write(json.dumps(record) + "\n")
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"),
                          "estimator", root], check=True, capture_output=True, text=True).stdout
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in out.splitlines() if line.startswith("| ") and "---" not in line}
    assert rows["defaults"][2] == "–" and rows["defaults"][5] == "–"
    assert rows["depth30"][2].startswith("+20.0 ± ")
    assert rows["depth30"][5].startswith("-5.0 ± ")
    assert "--grid-sampling odds" in rows["depth30"][0]
    assert "search.max_depth=30" in rows["depth30"][0]


def test_generated_groups_the_shares_by_the_placement_the_scene_names(tmp_path):
    runs, scenes = tmp_path / "run", tmp_path / "scenes"
    scenes.mkdir()
    placements = {"gen-1": "in the open", "gen-2": "in the open",
                  "gen-3": "covered by a larger box"}
    rewards = {"gen-1": 80.0, "gen-2": 60.0, "gen-3": 25.0}
    for scene, placement in placements.items():
        (scenes / (scene + ".json")).write_text(json.dumps(
            {"description": f"Generated by npfkct-scenegen: 5 objects, the target {placement}."}),
            encoding="utf-8")
        cells = [("oracle", 100.0, (4, 4)), ("npfkct", rewards[scene], (6, 8))]
        for planner, reward, steps in cells:
            os.makedirs(runs / scene, exist_ok=True)
            record = {"scenario": scene, "planner": planner, "cpu_ms": 250, "trials": 2,
                      "mean_discounted_reward": reward, "steps": list(steps), "successes": [1, 1]}
            (runs / scene / (planner + ".jsonl")).write_text(json.dumps(record) + "\n",
                                                              encoding="utf-8")
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "generated",
                          str(runs), str(scenes)], check=True, capture_output=True,
                         text=True).stdout
    lines = out.splitlines()
    assert "| Planner | open (2 scenes) | covered (1 scenes) |" in lines
    assert "| oracle | 4.0 steps | 4.0 steps |" in lines
    # Open: shares 0.8 and 0.6, mean 70% with t(0.975, 1) * sd / sqrt(2) = 12.706 * 0.1 = 127.1
    # points; covered: one scene, 25%, no interval.
    assert "| npfkct | 70.0% ± 127.1, 7.0 steps | 25.0% ± 0.0, 7.0 steps |" in lines
    # Without the scenes' folder, the overall table only.
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "generated",
                          str(runs)], check=True, capture_output=True, text=True).stdout
    assert "By placement" not in out


def test_table1_takes_each_cell_from_the_first_run_that_has_it(tmp_path):
    def cell(run, scene, planner, reward):
        os.makedirs(tmp_path / run / scene, exist_ok=True)
        record = {"scenario": scene, "planner": planner, "cpu_ms": 1000, "trials": 2,
                  "mean_discounted_reward": reward, "ci95": 1.0, "mean_steps": 4.0,
                  "ci95_steps": 0.0, "success_rate": 1.0, "median_sims_per_cpu_second": 10.0}
        (tmp_path / run / scene / (planner + ".jsonl")).write_text(json.dumps(record) + "\n",
                                                                   encoding="utf-8")

    cell("run1", "Loose1", "oracle", 100.0)
    cell("run1", "Loose1", "npfkct", 50.0)
    cell("run1", "Loose1", "advt", 20.0)
    cell("run3", "Loose1", "oracle", 100.0)
    cell("run3", "Loose1", "npfkct", 80.0)
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "table1",
                          str(tmp_path / "run3"), str(tmp_path / "run1")], check=True,
                         capture_output=True, text=True).stdout
    lines = out.splitlines()
    assert "| npfkct | 80.0 ± 1.0 \\| 4.0 ± 0.0 \\| 100% | – | run3 |" in lines
    assert "| advt | 20.0 ± 1.0 \\| 4.0 ± 0.0 \\| 100% | – | run1 |" in lines
    # The shares come from the same merged cells: npfkct 80 of the oracle's 100.
    assert "| npfkct | 80% |" in lines


def test_docs_benchmarks_is_what_the_script_makes_of_the_results():
    # docs/benchmarks.md is written by `python3 bench/results_table.py docs > docs/benchmarks.md`;
    # a new cell in bench/results, or an edit of the file by hand, must show here.
    with open(os.path.join(SCRIPTS, "..", "docs", "benchmarks.md"), encoding="utf-8") as f:
        committed = f.read()
    assert committed == results_table.docs(), (
        "docs/benchmarks.md differs from what bench/results_table.py makes of bench/results: "
        "run python3 bench/results_table.py docs --write")


def test_the_docs_command_prints_the_file(tmp_path):
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "docs"],
                         check=True, capture_output=True, env={**os.environ,
                                                               "PYTHONIOENCODING": "utf-8"}).stdout
    assert out.decode("utf-8") == results_table.docs()


def test_threads_gives_the_ratio_of_simulations_per_second(tmp_path):
    for n, sims, reward in [(1, 100.0, 10.0), (2, 250.0, 12.0)]:
        (tmp_path / f"t{n}.jsonl").write_text(json.dumps(
            {"scenario": "Loose1", "median_sims_per_second": sims, "mean_discounted_reward": reward,
             "ci95": 1.0}) + "\n", encoding="utf-8")
    out = subprocess.run([sys.executable, os.path.join(SCRIPTS, "results_table.py"), "threads",
                          str(tmp_path / "t1.jsonl"), str(tmp_path / "t2.jsonl")], check=True,
                         capture_output=True, text=True).stdout
    assert "| Loose1 | 100 | 250 | 2.50x | 10.0 ± 1.0 | 12.0 ± 1.0 |" in out.splitlines()


def classic_with_rows(path, rows):
    """results_table.classic on `path` with only `rows` of CLASSIC_ROWS."""
    saved = results_table.CLASSIC_ROWS
    results_table.CLASSIC_ROWS = rows
    try:
        return results_table.capture(results_table.classic, str(path))
    finally:
        results_table.CLASSIC_ROWS = saved


def test_classic_pools_runs_as_independent_samples(tmp_path):
    # Two runs of 100 episodes: means 28 and 30, standard errors 3 and 4: pooled 29 ± 2.5.
    path = tmp_path / "classic.jsonl"
    lines = []
    for seed, mean, se in [(1, 28.0, 3.0), (2, 30.0, 4.0)]:
        for planner in ("kct", "vomcpow"):
            lines.append(json.dumps({"problem": "vdptag", "planner": planner, "episodes": 100,
                                     "cpu_ms": 1000, "threads": 1, "seed": seed,
                                     "mean_discounted_return": mean, "stderr": se,
                                     "mean_steps": 10.0, "success_rate": 1.0}))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    rows = [r for r in results_table.CLASSIC_ROWS if r[0].startswith("VDP Tag (ToNextML rollout),")]
    out = classic_with_rows(path, rows)
    pooled = [line for line in out.splitlines() if "pooled | kCT" in line]
    assert len(pooled) == 1 and "| 200 | return | 29.00 ± 2.50 |" in pooled[0]


def test_classic_is_one_table_with_the_lqg_and_the_despot_runs_beside_it(tmp_path):
    # The classic rows, the LQG's last run per planner and options, and the DESPOT episodes of
    # despot/ beside classic.jsonl pooled over its files: rows of one table, each with a command.
    lines = [{"problem": "lightdark", "planner": "kct", "episodes": 10, "cpu_ms": 1000,
              "mean_discounted_return": 60.0, "stderr": 1.0, "mean_steps": 9.0,
              "success_rate": 1.0}]
    for distance in (0.9, 0.06):  # the later run of kct wins
        lines.append({"problem": "lqg", "planner": "kct", "options": [], "plans": 1000,
                      "sims": 1000, "mean_distance": distance, "stderr": 0.006})
    (tmp_path / "classic.jsonl").write_text("\n".join(json.dumps(r) for r in lines) + "\n",
                                            encoding="utf-8")
    (tmp_path / "despot").mkdir()
    for run, returns in enumerate([(1.0, 2.0), (3.0, 4.0)]):
        episodes = [{"planner": "despot", "episode": 2 * run + i, "discounted_return": x,
                     "steps": 10} for i, x in enumerate(returns)]
        (tmp_path / "despot" / f"rocksample-0.1s-{run}.jsonl").write_text(
            "\n".join(json.dumps(e) for e in episodes) + "\n", encoding="utf-8")
    rows = [r for r in results_table.CLASSIC_ROWS if r[1] == "kCT" and r[0] == "SimpleLightDark"]
    out = classic_with_rows(tmp_path / "classic.jsonl", rows)
    table = [line for line in out.split("\n\n")[0].splitlines() if line.startswith("| ")]
    assert len(table) == 1 + 3  # the header, then one row each
    assert "| 10 | return | 60.00 ± 1.00 |" in table[1] and "kct-lightdark`" in table[1]
    # 1, 2, 3, 4: mean 2.5, sd 1.291, s.e. 0.645.
    assert "DESPOT (`despot`) | 0.1 s of CPU | 4 | return | 2.50 ± 0.65 |" in table[2]
    assert "| 0.060 ± 0.006 |" in table[3] and "bench_classic.sh lqg`" in table[3]


def test_classic_keeps_kcts_trees_apart_and_reads_a_row_from_its_own_file(tmp_path):
    # A record without kct_tree is of the paper's tree; a later one with point children does not
    # replace it; the point-children row reads its own file beside classic.jsonl.
    vpw = {"problem": "vdptag", "planner": "kct", "cpu_ms": 1000, "threads": 2,
           "options": ["search.rollout_first=1", "search.num_particles=100000"],
           "stderr": 2.0, "mean_steps": 15.0, "success_rate": 1.0}
    lines = [dict(vpw, seed=1, episodes=100, mean_discounted_return=30.0),
             dict(vpw, seed=1, episodes=100, mean_discounted_return=99.0, kct_tree="points")]
    for distance, tree in ((0.06, None), (0.04, "points")):
        run = {"problem": "lqg", "planner": "kct", "options": [], "plans": 1000, "sims": 1000,
               "mean_distance": distance, "stderr": 0.005}
        if tree:
            run["kct_tree"] = tree
        lines.append(run)
    (tmp_path / "classic.jsonl").write_text("\n".join(json.dumps(r) for r in lines) + "\n",
                                            encoding="utf-8")
    side = tmp_path / results_table.KCT_POINTS_VDPTAG
    side.parent.mkdir()
    side.write_text("\n".join(json.dumps(dict(vpw, seed=s, episodes=25,
                                              mean_discounted_return=float(s)))
                              for s in results_table.KCT_POINTS_SEEDS) + "\n", encoding="utf-8")
    rows = [r for r in results_table.CLASSIC_ROWS
            if r[0].startswith("VDP Tag, the VPW paper's configuration") and r[1].startswith("kCT")
            and "pooled" not in r[0] or "point children" in r[1]]
    out = classic_with_rows(tmp_path / "classic.jsonl", rows)
    table = [line for line in out.split("\n\n")[0].splitlines() if line.startswith("| ")]
    assert len(table) == 1 + 2 + 2, table
    assert "| kCT, the paper's tree | 1 s of CPU | 100 | return | 30.00 ± 2.00 |" in table[1]
    seeds = results_table.KCT_POINTS_SEEDS
    mean = sum(seeds) / len(seeds)
    assert f"| kCT (point children: the defaults) | 1 s of CPU | {25 * len(seeds)} | return | " \
           f"{mean:.2f} ± " in table[2]
    assert "kCT, the paper's tree | 1,000 sims" in table[3] and "| 0.060 ± 0.005 |" in table[3]
    assert "kCT (point children: the defaults) | 1,000 sims" in table[4]
    assert "| 0.040 ± 0.005 |" in table[4]


def vdptag_run(**changes):
    """A run of npfkct-bench on VDP Tag (kCT, seed 7, 1 s of CPU), three episodes returning 1, 2,
    3 in 10 steps each, with `changes` applied."""
    run = {"problem": "vdptag", "planner": "kct", "seed": 7, "episodes": 3, "cpu_ms": 1000,
           "time_ms": 0, "sims": 0, "rollout": "tonextml", "max_steps": 100,
           "options": ["a=1"], "mean_discounted_return": 2.0,
           "episode_returns": [1.0, 2.0, 3.0], "episode_steps": [10, 10, 10]}
    run.update(changes)
    return run


def test_classic_paired_compares_runs_of_one_seed_episode_by_episode(tmp_path):
    # Two runs of one seed: the base (fewest options) returns 1, 2, 3 in 10, 10, 10 steps, the
    # other 2, 4, 3 in 9, 8, 10: differences 1, 2, 0 (mean 1, sd 1, 95% t interval 4.303 /
    # sqrt(3) = 2.48) and -1, -2, 0 steps. A run of another seed has no base and no row.
    base = vdptag_run()
    other = dict(base, options=["a=1", "d_lim=0.05"], mean_discounted_return=3.0,
                 episode_returns=[2.0, 4.0, 3.0], episode_steps=[9, 8, 10])
    alone = dict(base, seed=8)
    path = tmp_path / "runs.jsonl"
    path.write_text("\n".join(json.dumps(r) for r in (other, base, alone)) + "\n",
                    encoding="utf-8")
    out = results_table.capture(results_table.classic_paired, str(path))
    rows = [line for line in out.splitlines() if line.startswith("| vdptag")]
    assert rows == ["| vdptag | kct | 7 | 3 | a=1 | d_lim=0.05 | 2.00 | 3.00 | +1.00 ± 2.48 | "
                    "-1.0 ± 2.5 |"]


def test_classic_paired_pools_a_comparison_over_its_seeds(tmp_path):
    # The same arm against the same base on seeds 7 and 8: differences 1, 2, 0 and 3, 3, 3 pool
    # to six episodes, mean 2, sd 1.265, 95% t interval 2.571 x 1.265 / sqrt(6) = 1.33; steps
    # -1, -2, 0, 0, 0, 0. A comparison made on one seed only has no pooled row.
    base = vdptag_run()
    arm = dict(base, options=["a=1", "d_lim=0.05"], mean_discounted_return=3.0,
               episode_returns=[2.0, 4.0, 3.0], episode_steps=[9, 8, 10])
    base8 = dict(base, seed=8, episode_returns=[0.0, 0.0, 0.0])
    arm8 = dict(arm, seed=8, episode_returns=[3.0, 3.0, 3.0], episode_steps=[10, 10, 10])
    once = dict(arm, options=["a=1", "w2=0"])
    path = tmp_path / "runs.jsonl"
    path.write_text("\n".join(json.dumps(r) for r in (base, arm, base8, arm8, once)) + "\n",
                    encoding="utf-8")
    out = results_table.capture(results_table.classic_paired, str(path))
    pooled = out.split("pooled over their seeds")[1]
    rows = [line for line in pooled.splitlines() if line.startswith("| vdptag")]
    assert rows == ["| vdptag | kct | 7, 8 | 6 | a=1 | d_lim=0.05 | 1.00 | 3.00 | +2.00 ± 1.33 | "
                    "-0.5 ± 0.9 |"]


def test_classic_paired_against_a_base_planner(tmp_path):
    # VOMCPOW's run is the base; kCT's two runs are compared with it, episode by episode: the
    # first returns 1 less in every episode (interval 0), the second 1, 0, -2 more (mean -1/3).
    base = vdptag_run(planner="vomcpow", cpu_ms=100)
    kct = dict(base, planner="kct", mean_discounted_return=1.0,
               episode_returns=[0.0, 1.0, 2.0], episode_steps=[11, 11, 11])
    arm = dict(kct, options=["a=1", "w2=0"], episode_returns=[2.0, 2.0, 1.0])
    path = tmp_path / "runs.jsonl"
    path.write_text("\n".join(json.dumps(r) for r in (kct, arm, base)) + "\n", encoding="utf-8")
    out = results_table.capture(results_table.classic_paired, str(path), "vomcpow")
    rows = [line for line in out.splitlines() if line.startswith("| vdptag")]
    assert rows[0] == ("| vdptag | kct (base: vomcpow) | 7 | 3 | a=1 | – | 2.00 | 1.00 | "
                       "-1.00 ± 0.00 | +1.0 ± 0.0 |")
    assert rows[1].startswith("| vdptag | kct (base: vomcpow) | 7 | 3 | a=1 | w2=0 | 2.00 |")
    assert "-0.33 ± " in rows[1] and len(rows) == 2
    # Without a base planner each planner is its own group: kCT's arm against kCT's run.
    out = results_table.capture(results_table.classic_paired, str(path))
    rows = [line for line in out.splitlines() if line.startswith("| vdptag")]
    assert rows == ["| vdptag | kct | 7 | 3 | a=1 | w2=0 | 1.00 | 1.00 | +0.67 ± 3.79 | "
                    "+0.0 ± 0.0 |"]


def test_lightdark_leaf_pairs_the_leaves_and_the_budgets(tmp_path):
    # Seed 11: fo at 100 sims (returns 1, 2, 3), localize at 100 sims (2, 4, 3: +1 ± 2.48), fo at
    # 300 sims (1, 2, 5: one episode differs, +0.67 ± 2.87) and at 1 s (the same episodes: +0, 0
    # differ). Seed 2: localize at 1 s against the other file's fo run there (3, 3, 3 against
    # 1, 2, 3: +1 ± 2.48). A localize run without an fo run of its budget has no pair. An option
    # (k=2: 1, 1, 1) against the run without it: -1 ± 2.48, and no "more search" row.
    run = lambda **c: dict({"problem": "lightdark", "planner": "kct", "seed": 11, "episodes": 3,
                            "cpu_ms": 0, "time_ms": 0, "sims": 100, "rollout": "",
                            "mean_discounted_return": 2.0, "stderr": 0.5, "mean_steps": 9.0,
                            "success_rate": 1.0, "median_sims_per_step": 100,
                            "episode_returns": [1.0, 2.0, 3.0], "episode_steps": [9, 9, 9]}, **c)
    mine = [run(), run(rollout="localize", mean_discounted_return=3.0,
                       episode_returns=[2.0, 4.0, 3.0]),
            run(sims=300, mean_discounted_return=2.67, episode_returns=[1.0, 2.0, 5.0]),
            run(sims=0, cpu_ms=1000, mean_discounted_return=2.67, episode_returns=[1.0, 2.0, 5.0]),
            run(sims=0, cpu_ms=1000, seed=2, rollout="localize", mean_discounted_return=3.0,
                episode_returns=[3.0, 3.0, 3.0]),
            run(sims=900, rollout="localize"),
            run(options=["k=2"], mean_discounted_return=1.0, episode_returns=[1.0, 1.0, 1.0])]
    other = [run(sims=0, cpu_ms=1000, seed=2), dict(run(), problem="vdptag")]
    for path, runs in (("mine.jsonl", mine), ("other.jsonl", other)):
        (tmp_path / path).write_text("\n".join(json.dumps(r) for r in runs) + "\n",
                                     encoding="utf-8")
    out = results_table.capture(results_table.lightdark_leaf, str(tmp_path / "mine.jsonl"),
                                str(tmp_path / "other.jsonl"))
    assert len([line for line in out.splitlines() if line.startswith("| kct |")]) == 7
    pairs = [line for line in out.splitlines()
             if line.startswith(("| the detour", "| more", "| k="))]
    assert pairs == [
        "| the detour leaf | kct | 11 | 3 | fo, 100 sims | 2.00 | localize, 100 sims | 3.00 | "
        "+1.00 ± 2.48 | +0.00 ± 0.00 | 2 |",
        "| the detour leaf | kct | 2 | 3 | fo, 1000 ms CPU | 2.00 | localize, 1000 ms CPU | 3.00 | "
        "+1.00 ± 2.48 | +0.00 ± 0.00 | 2 |",
        "| more search | kct | 11 | 3 | fo, 100 sims | 2.00 | fo, 300 sims | 2.67 | "
        "+0.67 ± 2.87 | +0.00 ± 0.00 | 1 |",
        "| more search | kct | 11 | 3 | fo, 300 sims | 2.67 | fo, 1000 ms CPU | 2.67 | "
        "+0.00 ± 0.00 | +0.00 ± 0.00 | 0 |",
        "| k=2 | kct | 11 | 3 | fo, 100 sims | 2.00 | fo, 100 sims | 1.00 | -1.00 ± 2.48 | "
        "+0.00 ± 0.00 | 2 |"]


def test_despot_pools_runs_and_subtracts_the_authors_figure(tmp_path):
    # Theirs returns 1, 2, 3 then 4, 5, 6 (mean 3.5); ours 2 more in every episode (5.5). Standard
    # error of 1..6: 1.8708 / sqrt(6) = 0.7638; of the difference: sqrt(2) x that = 1.0801.
    paths = []
    for run, episodes in enumerate([(1, 2, 3), (4, 5, 6)]):
        path = tmp_path / f"run{run}.jsonl"
        lines = []
        for i in episodes:
            lines.append(json.dumps({"planner": "despot-original", "episode": i,
                                     "discounted_return": float(i), "steps": 10,
                                     "median_trials_per_step": 30, "commit": "abc"}))
            lines.append(json.dumps({"planner": "despot", "episode": i,
                                     "discounted_return": i + 2.0, "steps": 12.0,
                                     "median_trials_per_step": 60.0}))
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
        paths.append(str(path))
    out = results_table.capture(results_table.despot_table, *reversed(paths))
    theirs = [line for line in out.splitlines() if line.startswith("| DESPOT, the authors'")]
    ours = [line for line in out.splitlines() if line.startswith("| DESPOT, ours")]
    assert len(theirs) == 1 and "| 6 | 3.50 ± 0.76 | 10.0 | 30 | – |" in theirs[0]
    assert len(ours) == 1 and "| 6 | 5.50 ± 0.76 | 12.0 | 60 | +2.00 ± 1.08 |" in ours[0]
    runs = [line for line in out.splitlines() if line.startswith("- `")]
    assert [line.split("`")[1] for line in runs] == ["run0.jsonl", "run1.jsonl"]
    assert "commit abc" in out


def test_the_readme_headline_figures_are_those_of_docs_benchmarks():
    # The README's table of headline figures is typed by hand; every figure in it must still be
    # one that docs/benchmarks.md (generated from bench/results) shows.
    root = os.path.join(SCRIPTS, "..")
    with open(os.path.join(root, "README.md"), encoding="utf-8") as f:
        readme = f.read()
    with open(os.path.join(root, "docs", "benchmarks.md"), encoding="utf-8") as f:
        benchmarks = f.read()
    rows = readme.split("<!-- headline -->\n", 1)[1].split("\n\n", 1)[0].splitlines()[2:]
    assert len(rows) >= 4
    figure = re.compile(r"\d+(?:\.\d+)?%(?: ± \d+(?:\.\d+)?)?|\d+\.\d+ m?s\b|\d+\.\d+ ± \d+\.\d+")
    for row in rows:
        value = row.split("|")[2]
        found = figure.findall(value)
        assert found, row
        for x in found:
            assert x in benchmarks, f"README headline figure {x!r} is not in docs/benchmarks.md"
