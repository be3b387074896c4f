#!/usr/bin/env python3
"""How far is SimpleLightDark's optimum? A reference for the tree searches of docs/benchmarks.md.

SimpleLightDark (solver/include/npfkct/solver/models/light_dark.h) has 121 positions, so its belief
is a vector that can be tracked exactly. This script solves the problem offline by point-based
value iteration (Perseus; Spaan & Vlassis 2005) with the observations binned: a policy that sees
only the bin of each observation is a policy of the continuous problem too, so its value is a lower
bound on the continuous problem's optimum. It prints, as one JSON line like npfkct-bench's:

- `lower_bound`: the value at the initial belief of the alpha-vectors found (each alpha-vector is
  the value of a conditional plan, so the bound holds up to float rounding),
- `mean_discounted_return` (± `stderr`, `ci95`): the policy's return over `--episodes` episodes
  with continuous observations drawn as the model draws them, then binned,
- `upper_bound_qmdp`: the QMDP value of the initial belief (full observability from the first
  step on), which no policy exceeds.

With `--score FILE` (lines of `npfkct-bench --problem lightdark --trace`) it adds each traced
decision's regret against the reference; with `--lookahead fo|plan` it plays a sparse-sampling
lookahead on the exact belief instead of solving (docs/experiments.md, "How far is
SimpleLightDark's optimum?").

The model is written again here (numpy, from the header's documented constants), not read from the
C++; tests/test_lightdark_optimum.py replays episodes that npfkct-bench plays against it and checks
the bounds' order. Binning: a bin of +-1e-3 around the light (where the noise is 1e-4, so a
reading there says "at the light"), bins of `--bin` (default 1.0) for readings in [-20, 40), four
times wider beyond, to +-120. Halving `--bin` refines these bins, which can only raise the binned
problem's optimum.

    python3 bench/lightdark_optimum.py                      # about 15 minutes on one core
    python3 bench/lightdark_optimum.py --episodes 200 --rounds 0 --max-iterations 5   # a smoke run
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

RADIUS = 60
STATES = 2 * RADIUS + 1  # positions -60..60 at index s + 60; declaring ends the episode
LIGHT = 10
GAMMA = 0.95
MOVES = (-10, -1, 1, 10)  # the moves; declaring is apart: +100 at 0, -100 elsewhere
MOVE_NAMES = ("-10", "-1", "+1", "+10")
DECLARE = -1
MOVE_COST = -1.0
# Moving forever is worth -1 / (1 - gamma): the first alpha-vector, a lower bound everywhere.
NEVER_DECLARE = MOVE_COST / (1.0 - GAMMA)
DECLARE_VALUE = np.where(np.arange(STATES) == RADIUS, 100.0, -100.0)
# NEXT[a][i]: the index of the position after move a from index i (clamped to the line).
NEXT = [np.clip(np.arange(STATES) + m, 0, STATES - 1) for m in MOVES]


def noise_std(s):
    """The observation noise at position s (light_dark.h: |s - 10| + 1e-4)."""
    return abs(s - LIGHT) + 1e-4


def bin_edges(width):
    """Observation bin edges, -inf and +inf at the ends: a bin of +-1e-3 at the light, `width`
    in [-20, 40), 4 * width out to +-120."""
    near = np.arange(-20.0, 40.0 + width / 2, width)
    far = np.concatenate([np.arange(-120.0, -20.0, 4 * width),
                          np.arange(40.0 + 4 * width, 120.0 + width, 4 * width)])
    edges = {round(float(x), 9) for x in np.concatenate([near, far]) if abs(x - LIGHT) > 1e-3}
    edges.update((LIGHT - 1e-3, LIGHT + 1e-3))
    return np.array([-math.inf] + sorted(edges) + [math.inf])


def observation_matrix(edges):
    """P(bin z | position index i): the Gaussian's mass on each bin, rows summing to 1."""
    cdf = np.empty((STATES, len(edges)))
    for i in range(STATES):
        s, sd = i - RADIUS, noise_std(i - RADIUS)
        for j, x in enumerate(edges):
            cdf[i, j] = 0.0 if x == -math.inf else 1.0 if x == math.inf else \
                0.5 * math.erfc(-(x - s) / (sd * math.sqrt(2.0)))
    probs = np.maximum(np.diff(cdf, axis=1), 0.0)
    return probs / probs.sum(axis=1, keepdims=True)


def fully_observable_values():
    """V*(s) of the fully observable problem by value iteration (light_dark.cc's leaf value)."""
    v = np.zeros(STATES)
    for _ in range(2000):
        nxt = np.maximum(DECLARE_VALUE, np.max([MOVE_COST + GAMMA * v[n] for n in NEXT], axis=0))
        if np.max(np.abs(nxt - v)) < 1e-12:
            return nxt
        v = nxt
    return v


def initial_belief():
    b = np.zeros(STATES)
    b[RADIUS - 30:RADIUS + 31] = 1.0 / 61.0
    return b


def after_move(b, a):
    """The belief after move a, before its observation."""
    out = np.zeros(STATES)
    np.add.at(out, NEXT[a], b)
    return out


class Solver:
    """Perseus over a fixed set of beliefs; alpha-vectors are rows of `alphas`."""

    def __init__(self, obs):
        self.obs = obs
        self.alphas = np.vstack([np.full(STATES, NEVER_DECLARE), DECLARE_VALUE])

    def value(self, b):
        return float(np.max(self.alphas @ b))

    def _move_scores(self, b, a):
        """For move a from b, per (alpha, bin): the value of following that alpha after that bin,
        weighted by the bin's probability (the predicted belief's support only)."""
        p = after_move(b, a)
        k = np.nonzero(p > 1e-14)[0]
        return (self.alphas[:, k] * p[k]) @ self.obs[k]

    def q_values(self, b):
        """Q(b, a) for a in (declare, -10, -1, +1, +10) under the current alpha-vectors."""
        q = [float(DECLARE_VALUE @ b)]
        for a in range(len(MOVES)):
            q.append(MOVE_COST + GAMMA * float(self._move_scores(b, a).max(axis=0).sum()))
        return q

    def action(self, b):
        """The greedy action at b: DECLARE or a move index."""
        q = self.q_values(b)
        best = int(np.argmax(q))
        return DECLARE if best == 0 else best - 1

    def backup(self, b):
        """The best alpha-vector at b after one Bellman backup of the current set."""
        best, best_alpha = float(DECLARE_VALUE @ b), DECLARE_VALUE
        for a in range(len(MOVES)):
            chosen = self._move_scores(b, a).argmax(axis=0)  # an alpha per bin
            after = MOVE_COST + GAMMA * np.einsum("sz,zs->s", self.obs, self.alphas[chosen])
            alpha = after[NEXT[a]]
            if alpha @ b > best:
                best, best_alpha = float(alpha @ b), alpha
        return best_alpha

    def iterate(self, beliefs, rng):
        """One Perseus stage: back up beliefs in random order until every belief's value is at
        least what it was. Beliefs still at the first bound are each backed up themselves (the
        flat start would otherwise end the stage at once). Returns the largest gain."""
        before = (beliefs @ self.alphas.T).max(axis=1)
        best = np.full(len(beliefs), -math.inf)
        done = np.zeros(len(beliefs), bool)
        new = []
        flat = before <= NEVER_DECLARE + 1e-9
        todo = np.arange(len(beliefs))
        while len(todo):
            i = int(todo[rng.integers(len(todo))])
            alpha = self.backup(beliefs[i])
            if alpha @ beliefs[i] < before[i]:
                alpha = self.alphas[int(np.argmax(self.alphas @ beliefs[i]))]
            new.append(alpha)
            best = np.maximum(best, beliefs @ alpha)
            done[i] = True
            covered = np.where(flat, best > before + 1e-9, best >= before - 1e-9)
            todo = np.nonzero(~covered & ~done)[0]
        for j in np.nonzero(best < before - 1e-9)[0]:  # keep what a belief had
            new.append(self.alphas[int(np.argmax(self.alphas @ beliefs[j]))])
        new = np.array(new)
        new = new[np.unique((beliefs @ new.T).argmax(axis=1))]  # the vectors best somewhere
        self.alphas = np.vstack([new, DECLARE_VALUE])
        return float(((beliefs @ self.alphas.T).max(axis=1) - before).max())


def bin_of(edges, o):
    """The index of the bin holding observation o."""
    return int(np.searchsorted(edges, o, side="right") - 1)


def update(b, a, z, obs):
    p = after_move(b, a) * obs[:, z]
    total = p.sum()
    return p / total if total > 0 else None


def collect(obs, episodes, depth, rng, solver=None, explore=1.0):
    """Beliefs met on `episodes` episodes of the binned problem: random moves, or the solver's
    greedy action except with probability `explore`."""
    found = [initial_belief()]
    for _ in range(episodes):
        s = int(rng.integers(61)) + RADIUS - 30
        b = initial_belief()
        for _ in range(depth):
            if solver is None or rng.random() < explore:
                a = int(rng.integers(len(MOVES)))
            else:
                a = solver.action(b)
                if a == DECLARE:
                    break
            s = int(NEXT[a][s])
            b = update(b, a, int(rng.choice(obs.shape[1], p=obs[s])), obs)
            found.append(b)
    return np.unique(np.round(np.array(found), 12), axis=0)


def evaluate(act, obs, edges, episodes, rng):
    """Episodes of the policy `act` (belief -> action) with the model's continuous observations,
    binned for the policy."""
    returns, steps, successes = [], [], 0
    for _ in range(episodes):
        i = int(rng.integers(61)) + RADIUS - 30  # the position's index
        b = initial_belief()
        ret, discount = 0.0, 1.0
        for t in range(100):
            a = act(b)
            if a == DECLARE:
                ret += discount * DECLARE_VALUE[i]
                successes += i == RADIUS
                break
            i = int(NEXT[a][i])
            ret += discount * MOVE_COST
            discount *= GAMMA
            o = rng.normal(i - RADIUS, noise_std(i - RADIUS))
            b = update(b, a, bin_of(edges, o), obs)
        returns.append(ret)
        steps.append(t + 1)
    returns = np.array(returns)
    se = float(returns.std(ddof=1) / math.sqrt(episodes))
    return float(returns.mean()), se, successes / episodes, float(np.mean(steps))


def plan_values():
    """V[g, i]: the return from position index i of the fully observable plan of position g (its
    greedy moves to 0, then the declaration), followed without looking."""
    fo = fully_observable_values()
    values = np.empty((STATES, STATES))
    for g in range(STATES):
        s, end, moves = g, np.arange(STATES), 0
        while s != RADIUS:
            a = max(range(len(MOVES)), key=lambda m: fo[NEXT[m][s]])
            s, end, moves = NEXT[a][s], NEXT[a][end], moves + 1
        values[g] = (MOVE_COST * (1.0 - GAMMA ** moves) / (1.0 - GAMMA) +
                     GAMMA ** moves * DECLARE_VALUE[end])
    return values


class Lookahead:
    """Sparse sampling (Kearns, Mansour & Ng 2002) on the exact belief: `depth` levels, `width`
    sampled observations per move, the leaves valued by `leaf`: "fo", the fully observable value
    averaged over the belief (what the tree searches' leaves estimate), or "plan", the best
    return of one position's fully observable plan followed blind from the belief (the value of
    a plan the agent can execute, so it counts what the belief does not know)."""

    def __init__(self, obs, leaf, depth, width, rng):
        self.obs, self.depth, self.width, self.rng = obs, depth, width, rng
        if leaf == "fo":
            fo = fully_observable_values()
            self.leaf = lambda b: float(b @ fo)
        else:
            plans = plan_values()
            self.leaf = lambda b: float(np.max(plans @ b))

    def _q(self, b, depth):
        q = [float(DECLARE_VALUE @ b)]
        for a in range(len(MOVES)):
            p = after_move(b, a)
            total = 0.0
            for _ in range(self.width):
                s = self.rng.choice(STATES, p=p)
                nb = update(b, a, int(self.rng.choice(self.obs.shape[1], p=self.obs[s])), self.obs)
                total += self.leaf(nb) if depth == 1 else max(self._q(nb, depth - 1))
            q.append(MOVE_COST + GAMMA * total / self.width)
        return q

    def action(self, b):
        best = int(np.argmax(self._q(b, self.depth)))
        return DECLARE if best == 0 else best - 1


# npfkct-bench's action indices on SimpleLightDark (light_dark.h's kMoves: -10, -1, declare, +1,
# +10) as this script's: a move index or DECLARE.
BENCH_ACTIONS = {0: 0, 1: 1, 2: DECLARE, 3: 2, 4: 3}
SPREAD_GROUPS = ((8.0, "spread >= 8"), (3.0, "spread 3-8"), (1.0, "spread 1-3"), (0.0, "spread < 1"))


def check_trace(trace):
    """Raises ValueError unless `trace` (a line of npfkct-bench --trace) is an episode of this
    script's model: states on the line, moves as MOVES, -1 a move, +-100 a declaration."""
    states, actions = trace["states"], trace["actions"]
    if not (-30 <= states[0] <= 30) or len(states) != len(actions) + 1:
        raise ValueError(f"episode {trace['episode']}: initial state {states[0]} or lengths")
    for t, (a, r) in enumerate(zip(actions, trace["rewards"])):
        a = BENCH_ACTIONS[int(a)]
        s = int(states[t])
        if a == DECLARE:
            if r != (100.0 if s == 0 else -100.0) or t != len(actions) - 1:
                raise ValueError(f"episode {trace['episode']} step {t}: declaration at {s}")
        elif r != MOVE_COST or int(NEXT[a][s + RADIUS]) - RADIUS != int(states[t + 1]):
            raise ValueError(f"episode {trace['episode']} step {t}: move {MOVES[a]} from {s}")


def score(solver, edges, traces, worst=0):
    """Each traced decision's regret against the solved Q-values: Q(b, best) - Q(b, taken) on the
    exact belief b of the binned observations, discounted to the episode's start and summed by
    the belief's spread (standard deviation of the position) at the decision. Both Q-values are
    lower bounds from the same alpha-vectors, so the regrets are estimates. The `worst` largest
    regrets are listed on stderr with the belief's mean and spread."""
    listed = []
    groups = {"first action": 0.0, **{name: 0.0 for _, name in SPREAD_GROUPS}}
    decisions = {name: 0 for name in groups}
    agree = total_decisions = 0
    returns = []
    positions = np.arange(STATES) - RADIUS
    for trace in traces:
        check_trace(trace)
        b, discount = initial_belief(), 1.0
        for t, (a, o) in enumerate(zip(trace["actions"], trace["observations"])):
            a = BENCH_ACTIONS[int(a)]
            q = solver.q_values(b)
            best = int(np.argmax(q))
            regret = discount * (q[best] - q[a + 1])
            mean = float(b @ positions)
            spread = math.sqrt(float(b @ (positions - mean) ** 2))
            name = "first action" if t == 0 else next(n for lo, n in SPREAD_GROUPS if spread >= lo)
            groups[name] += regret
            decisions[name] += 1
            listed.append((regret, trace["episode"], t, mean, spread, a, best - 1))
            agree += best == a + 1
            total_decisions += 1
            if a == DECLARE:
                break
            discount *= GAMMA
            b = update(b, a, bin_of(edges, o), solver.obs)
            if b is None:
                raise ValueError(f"episode {trace['episode']}: observation {o} impossible")
        returns.append(sum(r * GAMMA ** t for t, r in enumerate(trace["rewards"])))
    names = {**dict(enumerate(MOVE_NAMES)), DECLARE: "declare"}
    for regret, episode, t, mean, spread, a, best in sorted(listed, reverse=True)[:worst]:
        print(f"regret {regret:5.2f}: episode {episode} step {t}, belief mean {mean:6.1f} spread "
              f"{spread:5.1f}: took {names[a]}, the reference {names[best]}", file=sys.stderr)
    n = len(traces)
    return {
        "traced_episodes": n, "traced_mean_discounted_return": round(float(np.mean(returns)), 4),
        "mean_discounted_regret": round(sum(groups.values()) / n, 4),
        "regret_by_group": {k: round(v / n, 4) for k, v in groups.items()},
        "decisions_by_group": decisions,
        "share_of_decisions_as_reference": round(agree / total_decisions, 4),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", type=float, default=1.0, help="bin width in [-20, 40) (default 1.0)")
    ap.add_argument("--walks", type=int, default=30, help="random-walk episodes for the first "
                    "beliefs (default 30)")
    ap.add_argument("--rounds", type=int, default=4, help="rounds of beliefs met by the policy "
                    "found so far (default 4)")
    ap.add_argument("--round-episodes", type=int, default=100, help="episodes a round "
                    "(default 100)")
    ap.add_argument("--tolerance", type=float, default=0.05, help="a stage's largest gain that "
                    "ends a round (default 0.05)")
    ap.add_argument("--max-iterations", type=int, default=60, help="stages per round at most")
    ap.add_argument("--episodes", type=int, default=5000, help="evaluation episodes "
                    "(default 5000)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--save", help="write the alpha-vectors and beliefs to this .npz file")
    ap.add_argument("--load", help="read the alpha-vectors of an earlier --save instead of solving")
    ap.add_argument("--score", help="a file of npfkct-bench --problem lightdark --trace lines: "
                    "add each decision's regret against the reference to the record")
    ap.add_argument("--worst", type=int, default=0, help="with --score: list this many of the "
                    "largest regrets on stderr")
    ap.add_argument("--lookahead", choices=("fo", "plan"), help="instead of solving, play a "
                    "sparse-sampling lookahead on the exact belief with this leaf value")
    ap.add_argument("--depth", type=int, default=2, help="--lookahead's depth (default 2)")
    ap.add_argument("--width", type=int, default=10, help="--lookahead's sampled observations per "
                    "move (default 10)")
    args = ap.parse_args(argv)
    if not (0.05 <= args.bin <= 10.0) or min(args.walks, args.round_episodes, args.episodes) < 1 \
            or args.rounds < 0 or args.max_iterations < 1 or not args.tolerance > 0 \
            or args.worst < 0:
        ap.error("--bin in [0.05, 10], --walks/--round-episodes/--episodes >= 1, --rounds >= 0, "
                 "--worst >= 0")
    if args.lookahead and (args.load or args.save or args.score or not 1 <= args.depth <= 4 or
                           not 1 <= args.width <= 100):
        ap.error("--lookahead takes --depth 1-4 and --width 1-100, not --load, --save or --score")
    start = time.process_time()
    rng = np.random.default_rng(args.seed)
    edges = bin_edges(args.bin)
    obs = observation_matrix(edges)
    if args.lookahead:
        policy = Lookahead(obs, args.lookahead, args.depth, args.width, rng)
        mean, se, success, steps = evaluate(policy.action, obs, edges, args.episodes,
                                            np.random.default_rng([args.seed, 1]))
        print(json.dumps({
            "problem": "lightdark", "planner": f"lookahead-{args.lookahead}",
            "episodes": args.episodes, "seed": args.seed, "bin": args.bin, "depth": args.depth,
            "width": args.width, "cpu_seconds": round(time.process_time() - start, 1),
            "mean_discounted_return": round(mean, 4), "stderr": round(se, 4),
            "ci95": round(1.96 * se, 4), "success_rate": round(success, 4),
            "mean_steps": round(steps, 3)}))
        return 0
    solver = Solver(obs)
    if args.load:
        saved = np.load(args.load)
        if float(saved["bin"]) != args.bin:
            ap.error(f"--load {args.load} was solved with --bin {float(saved['bin'])}")
        solver.alphas, beliefs = saved["alphas"], saved["beliefs"]
        solve_s = float(saved["solve_cpu_seconds"])
    else:
        beliefs = collect(obs, args.walks, 20, rng)
    for rnd in range(0 if args.load else args.rounds + 1):
        if rnd > 0:
            met = collect(obs, args.round_episodes, 30, rng, solver, explore=0.1)
            beliefs = np.unique(np.vstack([beliefs, met]), axis=0)
        for it in range(args.max_iterations):
            gain = solver.iterate(beliefs, rng)
            print(f"round {rnd} stage {it}: {len(beliefs)} beliefs, {len(solver.alphas)} "
                  f"alpha-vectors, V(b0) >= {solver.value(initial_belief()):.3f}, gain {gain:.3f}",
                  file=sys.stderr, flush=True)
            if gain < args.tolerance:
                break
    if not args.load:
        solve_s = time.process_time() - start
    if args.save:
        np.savez_compressed(args.save, alphas=solver.alphas, beliefs=beliefs, bin=args.bin,
                            solve_cpu_seconds=solve_s)
    # The evaluation's episodes depend on the seed only, not on how the policy was found.
    mean, se, success, steps = evaluate(solver.action, obs, edges, args.episodes,
                                        np.random.default_rng([args.seed, 1]))
    b0 = initial_belief()
    fo = fully_observable_values()
    qmdp = max(max(MOVE_COST + GAMMA * float(b0 @ fo[n]) for n in NEXT), float(b0 @ DECLARE_VALUE))
    record = {
        "problem": "lightdark", "planner": "perseus-binned", "episodes": args.episodes,
        "seed": args.seed, "bin": args.bin, "bins": int(obs.shape[1]),
        "beliefs": int(len(beliefs)), "alpha_vectors": int(len(solver.alphas)),
        "solve_cpu_seconds": round(solve_s, 1),
        "first_action": ["declare", *MOVE_NAMES][solver.action(b0) + 1],
        "lower_bound": round(solver.value(b0), 4), "upper_bound_qmdp": round(qmdp, 4),
        "mean_discounted_return": round(mean, 4), "stderr": round(se, 4),
        "ci95": round(1.96 * se, 4), "success_rate": round(success, 4),
        "mean_steps": round(steps, 3),
    }
    if args.score:
        with open(args.score) as f:
            traces = [json.loads(line) for line in f if line.startswith('{"trace": "lightdark/')]
        if not traces:
            ap.error(f"--score {args.score}: no lightdark trace lines")
        record["scored"] = dict(file=os.path.basename(args.score),
                                planner=traces[0]["trace"].split("/", 1)[1],
                                **score(solver, edges, traces, args.worst))
    print(json.dumps(record))
    return 0


if __name__ == "__main__":
    sys.exit(main())
