#!/usr/bin/env bash
# Reproduces every figure of docs/benchmarks.md, "Classic problems with published results".
# Results are appended as JSON lines to bench/results/classic.jsonl (one object per run, see
# npfkct-bench --help).
# Usage: bench/bench_classic.sh [section ...]
#   sections: tiger rocksample tag throughput lightdark lightdark-discretised vdptag kct lqg (kct:
#   kCT beside POMCPOW and VOMCPOW on VDP Tag and SimpleLightDark at the published 1 s budgets,
#   as CPU time of the planning thread; lightdark-discretised: the authors' discretised POMCP,
#   half an hour; kct-vdptag and kct-lightdark: either half of it; lqg: the VPW paper's first-action
#   benchmark on its 2-D LQG, a few minutes; vdptag-published: VDP Tag at the VPW paper's own
#   configuration, EPISODES per planner, default 100, PLANNERS, default "vomcpow kct pomcpow";
#   kct-lightdark takes EPISODES, default 200, and PLANNERS, default "kct pomcpow", likewise;
#   tag: Tag at DESPOT's protocol, EPISODES, default 60, PLANNERS, default "despot pomcp";
#   lightdark-leaf: what caps kCT on SimpleLightDark, its own file; lightdark-optimum: a
#   reference for SimpleLightDark's optimum, kCT's decisions scored against it, and shallow
#   lookaheads by leaf value, about an hour)
# Takes about three and a half hours on a 2-core machine with every section (tag: 25 minutes).
# env: THREADS (episodes at once; default: the number of cores), SEED (the kct and tag sections'
# seed, default 1; a second seed gives new episodes to pool with the first).
set -euo pipefail
NPFKCT_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$NPFKCT_ROOT/scripts/deps.sh"
npfkct_prepare npfkct-bench
BENCH="$BUILD_DIR/bin/npfkct-bench"
OUT="${OUT:-$NPFKCT_ROOT/bench/results/classic.jsonl}"
mkdir -p "$(dirname "$OUT")"
THREADS="${THREADS:-$(nproc)}"
SEED="${SEED:-1}"
run() { "$BENCH" "$@" | tee -a "$OUT"; }
sections=("$@")
[ ${#sections[@]} -eq 0 ] && sections=(tiger rocksample tag throughput lightdark lightdark-discretised vdptag kct lqg)

for section in "${sections[@]}"; do
  case "$section" in
    tiger)
      # POMCP, 5000 simulations per step, 100 steps; optimal value 19.37 (19.25 over 100 steps).
      run --problem tiger --planner pomcp --episodes 1000 --time-ms 0 --sims 5000 --threads "$THREADS"
      run --problem tiger --planner pomcp --episodes 200 --time-ms 0 --sims 5000 --threads "$THREADS" --rollout random
      ;;
    rocksample)
      # POMCP with preferred actions, 1 s per step (Silver & Veness: 20.71 +- 0.21).
      run --problem rocksample --planner pomcp --episodes 100 --time-ms 1000 --threads "$THREADS"
      ;;
    throughput)
      # Simulations per second of POMCP on RockSample(7,8), one thread, 1 s per step.
      run --problem rocksample --planner pomcp --episodes 8 --time-ms 1000 --threads 1
      ;;
    lightdark)
      # POMCPOW paper: POMCPOW 56.1 +- 0.6, POMCP (continuous observations) -7.1 +- 1.0 at 1 s.
      run --problem lightdark --planner pomcpow --episodes 200 --time-ms 1000 --threads "$THREADS"
      run --problem lightdark --planner pomcpow --episodes 300 --time-ms 0 --sims 10000 --threads "$THREADS"
      run --problem lightdark --planner pomcp --episodes 200 --time-ms 100 --threads "$THREADS"
      ;;
    lightdark-discretised)
      # The authors' discretised POMCP (icaps_2018/ld_discretization.jl, d_pomcp): 60.99 +- 0.41
      # at 1 s with observation bins of 10^-1.5, the best of the seven widths they tried.
      run --problem lightdark --planner d-pomcp --episodes 200 --cpu-ms 1000 --time-ms 0 --threads "$THREADS"
      ;;
    vdptag)
      # POMCPOW paper: POMCPOW 29.3 +- 0.8 at 1 s (random rollouts). VPW paper at 1 s with
      # ToNextML rollouts: VOMCPOW 33.2 +- 0.9, POMCPOW 28.3 +- 1.0.
      for planner in pomcpow vomcpow advt kct; do
        run --problem vdptag --planner "$planner" --episodes 300 --time-ms 100 --threads "$THREADS"
      done
      for planner in pomcpow vomcpow; do
        run --problem vdptag --planner "$planner" --episodes 100 --time-ms 1000 --threads "$THREADS" --rollout tonextml
      done
      ;;
    kct|kct-vdptag|kct-lightdark)
      # kCT with the project's defaults beside POMCPOW and VOMCPOW (the VPW paper's settings) at
      # 1 s, ToNextML rollouts for all; SimpleLightDark's actions are discrete, so there kCT's
      # list holds them as points and VOMCPOW is POMCPOW.
      [ "$section" = kct-lightdark ] || for planner in kct vomcpow pomcpow; do
        run --problem vdptag --planner "$planner" --episodes 100 --cpu-ms 1000 --threads "$THREADS" \
          --rollout tonextml --seed "$SEED"
      done
      [ "$section" = kct-vdptag ] || for planner in ${PLANNERS:-kct pomcpow}; do
        run --problem lightdark --planner "$planner" --episodes "${EPISODES:-200}" --cpu-ms 1000 \
          --threads "$THREADS" --seed "$SEED"
      done
      ;;
    vdptag-published)
      # The VPW paper's configuration (VOOTreeSearch.jl scripts/VDPTag2/compare.jl): ToNextML
      # rollouts, the root's first action towards the belief's mean target's next position
      # (RootToNextMLFirst = search.rollout_first), 100,000 particles; its constants are
      # npfkct-bench's. kCT beside it with the same rollout, first action and particles (and
      # VOMCPOW's observation widening).
      for planner in ${PLANNERS:-vomcpow kct pomcpow}; do
        run --problem vdptag --planner "$planner" --episodes "${EPISODES:-100}" --cpu-ms 1000 \
          --threads "$THREADS" --rollout tonextml --seed "$SEED" \
          --opt search.rollout_first=1 --opt search.num_particles=100000
      done
      ;;
    tag)
      # Tag as DESPOT's papers run it: 1 s per step, 90 steps at most. Somani et al. (2013),
      # Table 1: POMCP -7.14 +- 0.28, AR-DESPOT -6.26 +- 0.28.
      for planner in ${PLANNERS:-despot pomcp}; do
        run --problem tag --planner "$planner" --episodes "${EPISODES:-60}" --cpu-ms 1000 \
          --threads "$THREADS" --seed "$SEED"
      done
      ;;
    lightdark-leaf)
      # What caps SimpleLightDark (docs/experiments.md): kCT on seed 11, 200 episodes, with the
      # published leaf value (the fully observable MDP, "fo") and with the labelled detour by the
      # light ("localize") at 30,000, 90,000 and 270,000 simulations, then with "fo" at 1 s of
      # CPU; kCT with "localize" at 1 s on seed 2 (its "fo" run there is kct-lightdark's, in
      # classic.jsonl). Its own file, bench/results/lightdark-leaf.jsonl; about 80 minutes.
      leaf_run() {
        "$BENCH" --problem lightdark --planner kct --episodes 200 --time-ms 0 \
          --threads "$THREADS" "$@" | tee -a "$NPFKCT_ROOT/bench/results/lightdark-leaf.jsonl"
      }
      for sims in 30000 90000 270000; do
        for leaf in fo localize; do leaf_run --sims "$sims" --seed 11 --rollout "$leaf"; done
      done
      leaf_run --cpu-ms 1000 --seed 11 --rollout fo
      leaf_run --cpu-ms 1000 --seed 2 --rollout localize
      # The observation widening (5 N^(1/15), POMCPOW's published setting) four times wider and
      # two and a half times narrower, at 270,000 simulations.
      for k in 20 2; do
        leaf_run --sims 270000 --seed 11 --rollout fo --opt observations.k="$k"
      done
      ;;
    lightdark-optimum)
      # How far SimpleLightDark's optimum is (docs/experiments.md): bench/lightdark_optimum.py
      # solves the problem offline with binned observations (point-based value iteration on the
      # exact belief; a lower bound on the optimum) and plays its policy for 5,000 episodes; kCT's
      # 200 episodes of seed 11 at 270,000 simulations (the same episodes, action for action, as
      # at 1 s of CPU; lightdark-leaf) are traced and each decision scored against it. One line
      # in classic.jsonl; the trace is kept beside it in bench/results/lightdark-kct-trace.jsonl.
      trace="$NPFKCT_ROOT/bench/results/lightdark-kct-trace.jsonl"
      "$BENCH" --problem lightdark --planner kct --episodes 200 --time-ms 0 --sims 270000 \
        --seed 11 --threads "$THREADS" --trace 2> "$trace" > /dev/null
      python3 "$NPFKCT_ROOT/bench/lightdark_optimum.py" --walks 30 --rounds 4 \
        --round-episodes 100 --episodes 5000 --score "$trace" | tee -a "$OUT"
      # Which leaf value a shallow search needs: sparse sampling on the exact belief, the trees'
      # leaf (fo) against the value of a plan the agent can follow (plan), depths 1-3.
      for depth in 1 2; do
        for leaf in fo plan; do
          python3 "$NPFKCT_ROOT/bench/lightdark_optimum.py" --lookahead "$leaf" --depth "$depth" \
            --width 8 --episodes 500 | tee -a "$OUT"
        done
      done
      for leaf in fo plan; do
        python3 "$NPFKCT_ROOT/bench/lightdark_optimum.py" --lookahead "$leaf" --depth 3 \
          --width 4 --episodes 300 | tee -a "$OUT"
      done
      # Depth 2 with depth 3's width: what the narrower sampling alone costs each leaf.
      for leaf in fo plan; do
        python3 "$NPFKCT_ROOT/bench/lightdark_optimum.py" --lookahead "$leaf" --depth 2 \
          --width 4 --episodes 500 | tee -a "$OUT"
      done
      ;;
    lqg)
      # The VPW paper's LQG (VOOTreeSearch.jl scripts/LQG/action_compare.jl): 1,000 plans of 1,000
      # simulations from the initial belief, the first action's distance to the LQR optimum
      # (6, -6). Published with RolloutFirst and the exact LQR rollout: VOMCPOW 0.246, POMCPOW
      # 0.277. kCT with its defaults, then with RolloutFirst as the others have it.
      for planner in vomcpow pomcpow kct; do
        run --problem lqg --planner "$planner" --episodes 1000 --sims 1000 --threads "$THREADS"
      done
      run --problem lqg --planner kct --episodes 1000 --sims 1000 --threads "$THREADS" \
        --opt search.rollout_first=1
      ;;
    *) echo "unknown section $section" >&2; exit 2 ;;
  esac
done
