// POMCPOW (Sunberg & Kochenderfer 2018) and VOMCPOW (Lim, Tomlin & Sunberg 2021): MCTS with
// action and observation progressive widening and weighted particle beliefs in the nodes; VOMCPOW
// draws new actions by Voronoi optimistic sampling around the best action so far.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "npfkct/solver/belief.h"
#include "npfkct/solver/belief_tree.h"
#include "npfkct/solver/hybrid.h"
#include "npfkct/solver/model.h"
#include "npfkct/solver/planner.h"
#include "npfkct/solver/planner_base.h"

namespace npfkct {

/// Options of POMCPOW and VOMCPOW.
struct PomcpowOptions {
  /// Depth, horizon, reuse, particles and belief update settings.
  SearchOptions search;
  /// UCB1 exploration constant; NaN means the model's reward range.
  double exploration_c = std::numeric_limits<double>::quiet_NaN();
  /// Widen actions: add a new action while |C(h)| <= k_action N(h)^alpha_action. When false, a
  /// discrete-action model expands all legal actions at once (hybrid models always widen).
  bool enable_action_pw = true;
  double k_action = 10.0;
  double alpha_action = 0.5;
  /// Observation widening (k_o, alpha_o) and repeated-observation merging.
  ObservationWidening observations;
  /// Draw new actions by Voronoi optimistic sampling (VOMCPOW) instead of uniformly.
  bool use_voo = false;
  /// Voronoi sampling settings (used when use_voo).
  VooOptions voo;
  /// Draws spent to find a new continuous action that passes the model's reasonability check
  /// (1: no check, as POMCPOW.jl; VOO proposals then only need to lie in the box).
  int feasibility_tries = 1;

  /// Checks every option; the message names the offending one.
  Status Validate() const {
    if (Status s = search.Validate(); !s.ok()) return Prefixed("search", s);
    if (Status s = search.RequireOneThread(); !s.ok()) return s;
    if (!std::isnan(exploration_c) && !(exploration_c >= 0.0 && std::isfinite(exploration_c))) {
      return InvalidArgumentError("exploration_c must be >= 0 (or NaN for the reward range)");
    }
    if (!(k_action > 0.0) || !std::isfinite(k_action)) {
      return InvalidArgumentError("k_action must be > 0");
    }
    if (!(alpha_action >= 0.0 && alpha_action <= 1.0)) {
      return InvalidArgumentError("alpha_action must be in [0, 1]");
    }
    if (Status s = observations.Validate(); !s.ok()) return Prefixed("observations", s);
    if (feasibility_tries < 1) return InvalidArgumentError("feasibility_tries must be >= 1");
    if (use_voo) return Prefixed("voo", voo.Validate());
    return OkStatus();
  }
};

/// POMCPOW over a generative model with an observation likelihood. Discrete-action models
/// (Action = int) and hybrid-action models are both supported. The model must outlive the planner.
template <GenerativeModel M>
requires HasObservationLikelihood<M> &&(DiscreteActionModel<M> || HybridActionModel<M>)class Pomcpow
    : public PlannerBase<Pomcpow<M>, M, PomcpowOptions> {
  using Base = PlannerBase<Pomcpow<M>, M, PomcpowOptions>;
  NPFKCT_PLANNER_INTERFACE(Base);

 public:
  using Base::Base;

  /// Searches from the current belief within `budget` and recommends an action.
  Decision<Action> Plan(const TerminationCondition& stop, Rng& rng) {
    Decision<Action> d;
    if (Status s = this->Begin(stop, &d); !s.ok()) return Base::Fail(std::move(d), std::move(s));
    if (tree_.root < 0) tree_.root = tree_.NewObsNode();
    max_depth_ = 0;
    d.stats.reused_visits = tree_.obs[tree_.root].n;

    d.stats.simulations =
        this->SimulateUntil(stop, rng, [&](const State& s) { Simulate(s, tree_.root, 0, rng); });
    if (tree_.obs[tree_.root].actions.empty()) AddActions(tree_.root, belief_.Sample(rng), rng);
    if (tree_.obs[tree_.root].actions.empty()) {
      return Base::Fail(std::move(d), FailedPreconditionError("no legal action at the root"));
    }
    FillRootStats(tree_, BestTriedRootAction(tree_), max_depth_, &d);
    return FinishSearch(std::move(d), stop);
  }

  int64_t TreeSize() const { return tree_.size(); }
  int64_t RootVisits() const { return tree_.root >= 0 ? tree_.obs[tree_.root].n : 0; }

 private:
  using Tree = BeliefTree<M>;

  void ClearTree() { tree_.Clear(); }

  bool HasTree() const { return tree_.root >= 0; }

  void KeepChild(const Action& a, const Observation& o) {
    int next = -1;
    if (options_.search.reuse_tree && tree_.root >= 0) {
      const int ai = tree_.FindAction(tree_.root, a);
      if (ai >= 0) next = tree_.act[ai].children.Find(o, HashObservation(o));
    }
    if (next < 0) {
      tree_.Clear();
    } else {
      tree_.KeepSubtree(next);
    }
  }

  // Adds all legal actions (discrete, no PW) or one new action (PW). Uses state `s` for legality.
  void AddActions(int node, const State& s, Rng& rng) {
    auto& actions = tree_.obs[node].actions;
    if constexpr (DiscreteActionModel<M>) {
      LegalActionsOf(model_, s, &scratch_);
      if (!options_.enable_action_pw) {
        if (actions.empty()) {
          for (int a : scratch_) tree_.NewActNode(node, a);
        }
        return;
      }
      std::vector<int> untried;
      for (int a : scratch_) {
        if (tree_.FindAction(node, a) < 0) untried.push_back(a);
      }
      if (!untried.empty()) tree_.NewActNode(node, untried[rng.UniformInt(untried.size())]);
    } else {
      // RolloutFirst (VOOTreeSearch): the root's first action is the rollout policy's.
      if constexpr (requires { model_.RolloutAction(s, rng); }) {
        if (options_.search.rollout_first && node == tree_.root && actions.empty()) {
          tree_.NewActNode(node, RolloutFirstAction(model_, belief_, s, rng));
          return;
        }
      }
      existing_.clear();
      for (int ai : actions) existing_.push_back(&tree_.act[ai].action);
      if (options_.use_voo && existing_.size() > 1 &&
          !rng.Bernoulli(options_.voo.uniform_probability)) {
        int best = -1;
        for (int ai : actions) {
          const auto& an = tree_.act[ai];
          if (an.n > 0 && (best < 0 || an.q > tree_.act[best].q)) best = ai;
        }
        if (best >= 0 && model_.KindSpace(tree_.act[best].action.kind).dim() > 0) {
          HybridAction a = SampleVoronoiAround(model_, s, tree_.act[best].action, existing_,
                                               options_.voo, rng, options_.feasibility_tries > 1);
          tree_.NewActNode(node, std::move(a));
          return;
        }
      }
      HybridAction a;
      if (SampleUniformNewAction(model_, s, existing_, rng, &scratch_, &a,
                                 options_.feasibility_tries)) {
        tree_.NewActNode(node, std::move(a));
      }
    }
  }

  int SelectAction(int node) const {
    const auto& on = tree_.obs[node];
    const double log_n = std::log(static_cast<double>(std::max<int64_t>(on.n, 1)));
    int best = on.actions.front();
    double best_score = -std::numeric_limits<double>::infinity();
    for (int ai : on.actions) {
      const double score = Ucb1(tree_.act[ai].q, tree_.act[ai].n, log_n, c_);
      if (score > best_score) {
        best_score = score;
        best = ai;
      }
    }
    return best;
  }

  double Simulate(const State& s, int node, int depth, Rng& rng) {
    if (IsTerminalState(model_, s) || depth >= options_.search.max_depth ||
        std::pow(model_.Discount(), depth) < options_.search.discount_horizon) {
      return 0.0;
    }
    max_depth_ = std::max(max_depth_, depth);
    const bool widen_actions = HybridActionModel<M> || options_.enable_action_pw;
    const auto& on = tree_.obs[node];
    if (on.actions.empty() ||
        (widen_actions &&
         static_cast<double>(on.actions.size()) <=
             options_.k_action * std::pow(static_cast<double>(on.n), options_.alpha_action))) {
      AddActions(node, s, rng);
    }
    if (tree_.obs[node].actions.empty()) return 0.0;
    const int ai = SelectAction(node);
    const Action a = tree_.act[ai].action;
    auto t = tree_.Descend(model_, ai, a, s, options_.observations, 0, rng);
    double total = t.reward;
    if (!t.terminal) {
      const double gamma = model_.Discount();
      if (t.new_node) {
        total += gamma * LeafEstimate(model_, t.state, depth + 1, options_.search, rng, &scratch_);
      } else {
        total += gamma * Simulate(t.state, t.child, depth + 1, rng);
      }
    }
    ++tree_.obs[node].n;
    auto& an = tree_.act[ai];
    ++an.n;
    an.q += (total - an.q) / static_cast<double>(an.n);
    return total;
  }

  Tree tree_;
  int max_depth_ = 0;
  std::vector<int> scratch_;
  std::vector<const Action*> existing_;
};

/// Options of VOMCPOW: POMCPOW with Voronoi optimistic sampling of new actions.
inline PomcpowOptions VomcpowOptions() {
  PomcpowOptions o;
  o.use_voo = true;
  return o;
}

}  // namespace npfkct
