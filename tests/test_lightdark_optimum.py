"""bench/lightdark_optimum.py, the reference for SimpleLightDark's optimum: its model is the one
npfkct-bench plays (checked on traced episodes), its bounds are ordered and bind its own policy,
and its scoring of a traced planner adds up."""

import json
import math
import os
import subprocess
import sys

import pytest

from conftest import BUILD, ROOT

sys.path.insert(0, os.path.join(ROOT, "bench"))
import lightdark_optimum as ld  # noqa: E402

BENCH = os.path.join(BUILD, "bin", "npfkct-bench")


@pytest.fixture(scope="module")
def traces(tmp_path_factory):
    """Six episodes of kCT on SimpleLightDark, traced by npfkct-bench, and their file."""
    path = tmp_path_factory.mktemp("trace") / "kct.jsonl"
    with open(path, "w") as err:
        subprocess.run([BENCH, "--problem", "lightdark", "--planner", "kct", "--episodes", "6",
                        "--time-ms", "0", "--sims", "3000", "--seed", "5", "--trace"],
                       stdout=subprocess.DEVNULL, stderr=err, check=True, timeout=300)
    lines = [json.loads(line) for line in open(path)]
    assert sorted(t["episode"] for t in lines) == list(range(6))
    return path, lines


def test_the_scripts_model_is_the_one_the_bench_plays(traces):
    _, lines = traces
    for t in lines:
        ld.check_trace(t)  # initial state, moves, clamping, rewards, the declaration last
        for s, o in zip(t["states"][1:], t["observations"]):
            if s != 61:  # the terminal state after the declaration
                assert abs(o - s) < 6 * ld.noise_std(s), (s, o)
    broken = dict(lines[0], states=[lines[0]["states"][0]] + [s + 1 for s in lines[0]["states"][1:]])
    with pytest.raises(ValueError):
        ld.check_trace(broken)
    wrong = dict(lines[0], rewards=[-1.0] * len(lines[0]["actions"]))
    with pytest.raises(ValueError):
        ld.check_trace(wrong)


def test_the_fully_observable_values_and_the_bins():
    v = ld.fully_observable_values()
    assert v[ld.RADIUS] == 100.0  # declare at 0
    assert v[ld.RADIUS + 10] == pytest.approx(-1.0 + 0.95 * 100.0)  # one move of -10 first
    assert v[ld.RADIUS + 1] == pytest.approx(94.0)
    edges = ld.bin_edges(1.0)
    assert edges[0] == -math.inf and edges[-1] == math.inf and list(edges) == sorted(edges)
    inside = [e for e in edges if 9 < e < 11]
    assert inside == pytest.approx([9.999, 10.001])  # the light's own bin
    obs = ld.observation_matrix(edges)
    assert obs.sum(axis=1) == pytest.approx(1.0)
    light_bin = list(edges).index(inside[0])
    assert obs[ld.RADIUS + 10, light_bin] > 0.999 and obs[ld.RADIUS + 9, light_bin] < 0.001


def test_a_small_solve_bounds_its_own_policy_and_scores_a_trace(traces, capsys):
    path, lines = traces
    assert ld.main(["--walks", "20", "--rounds", "0", "--max-iterations", "30", "--episodes",
                    "400", "--score", str(path)]) == 0
    r = json.loads(capsys.readouterr().out)
    # A backup that failed would leave the first bound (-20, never declaring); the tree searches
    # make about 60.
    assert 55.0 < r["lower_bound"] < r["upper_bound_qmdp"] < 100.0
    # The alpha-vectors are values of plans the policy can follow: its return is not far below.
    assert r["mean_discounted_return"] + 4 * r["stderr"] > r["lower_bound"] - 1.0
    assert r["success_rate"] > 0.9
    s = r["scored"]
    assert s["traced_episodes"] == 6 and s["planner"] == "kct"
    assert sum(s["decisions_by_group"].values()) == sum(len(t["actions"]) for t in lines)
    assert s["decisions_by_group"]["first action"] == 6
    assert all(v >= 0.0 for v in s["regret_by_group"].values())
    assert sum(s["regret_by_group"].values()) == pytest.approx(s["mean_discounted_regret"],
                                                               abs=1e-3)
    returns = [sum(x * 0.95 ** i for i, x in enumerate(t["rewards"])) for t in lines]
    assert s["traced_mean_discounted_return"] == pytest.approx(sum(returns) / 6, abs=1e-3)


@pytest.mark.parametrize("args, named", [
    (["--bin", "0"], "--bin"), (["--bin", "11"], "--bin"), (["--episodes", "0"], "--episodes"),
    (["--worst", "-1"], "--worst"), (["--lookahead", "fo", "--depth", "5"], "--depth"),
    (["--lookahead", "plan", "--width", "101"], "--width"),
    (["--lookahead", "fo", "--score", "x.jsonl"], "--score")])
def test_bad_arguments_are_refused(capsys, args, named):
    with pytest.raises(SystemExit) as e:
        ld.main(args)
    assert e.value.code == 2 and named in capsys.readouterr().err
