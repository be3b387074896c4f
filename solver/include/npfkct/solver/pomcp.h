// POMCP (Silver & Veness 2010): UCT over histories for discrete-action POMDPs, with rollouts,
// optional preferred-action priors, a particle-filter root belief and tree reuse.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "npfkct/solver/belief.h"
#include "npfkct/solver/model.h"
#include "npfkct/solver/node_array.h"
#include "npfkct/solver/planner.h"
#include "npfkct/solver/planner_base.h"

namespace npfkct {

/// Options of POMCP.
struct PomcpOptions {
  /// Depth, horizon, reuse, particles and belief update settings.
  SearchOptions search;
  /// UCB1 exploration constant; NaN means the model's reward range (Rmax - Rmin), as in the paper.
  double exploration_c = std::numeric_limits<double>::quiet_NaN();
  /// Use the model's PreferredActions (if it has them) as priors in new nodes.
  bool use_preferred_actions = true;
  /// Prior visit count given to preferred actions.
  int prior_count = 10;
  /// Prior value given to preferred actions.
  double prior_value = 0.0;

  /// Checks every option; the message names the offending one.
  Status Validate() const {
    if (Status s = search.Validate(); !s.ok()) return Prefixed("search", s);
    if (Status s = search.RequireOneThread(); !s.ok()) return s;
    if (!std::isnan(exploration_c) && !(exploration_c >= 0.0 && std::isfinite(exploration_c))) {
      return InvalidArgumentError("exploration_c must be >= 0 (or NaN for the reward range)");
    }
    if (prior_count < 0) return InvalidArgumentError("prior_count must be >= 0");
    if (!std::isfinite(prior_value)) return InvalidArgumentError("prior_value must be finite");
    return OkStatus();
  }
};

/// POMCP over a discrete-action generative model. The model must outlive the planner.
template <DiscreteActionModel M>
class Pomcp : public PlannerBase<Pomcp<M>, M, PomcpOptions, int> {
  using Base = PlannerBase<Pomcp<M>, M, PomcpOptions, int>;
  NPFKCT_PLANNER_INTERFACE(Base);

 public:
  using Base::Base;

  /// Searches from the current belief within `budget` and recommends an action.
  Decision<Action> Plan(const TerminationCondition& stop, Rng& rng) {
    Decision<Action> d;
    if (Status s = this->Begin(stop, &d); !s.ok()) return Base::Fail(std::move(d), std::move(s));
    if (root_ >= 0 && obs_[root_].num_actions > 0 &&
        !RootMatchesLegalActions(belief_.Sample(rng))) {
      const auto t0 = Clock::now();
      ClearTree();
      d.stats.teardown_ms += MillisSince(t0);
    }
    if (root_ < 0) root_ = NewObsNode();
    max_depth_ = 0;
    d.stats.reused_visits = obs_[root_].n;
    if (obs_[root_].num_actions == 0) Expand(root_, belief_.Sample(rng));

    int64_t sims = 0;
    while (!stop.ShouldStop(sims)) {
      Simulate(belief_.Sample(rng), root_, 0, rng);
      ++sims;
    }
    d.stats.simulations = sims;
    return Finish(std::move(d), stop);
  }

  /// Nodes in the tree (observation + action nodes).
  int64_t TreeSize() const { return static_cast<int64_t>(obs_.size() + act_.size()); }
  /// Visit count of the root (0 when there is no tree).
  int64_t RootVisits() const { return root_ >= 0 ? obs_[root_].n : 0; }

 private:
  struct ObsNode {
    int64_t n = 0;
    int first_action = -1;
    int num_actions = 0;
  };
  struct ActNode {
    Action action = 0;
    int64_t n = 0;
    double q = 0.0;
    ObservationChildren<Observation> children;
  };

  bool HasTree() const { return root_ >= 0; }

  void KeepChild(Action a, const Observation& o) {
    int next = -1;
    if (options_.search.reuse_tree && root_ >= 0) {
      for (int i = 0; i < obs_[root_].num_actions; ++i) {
        const ActNode& an = act_[obs_[root_].first_action + i];
        if (an.action == a) next = an.children.Find(o, HashObservation(o));
      }
    }
    if (next < 0) {
      ClearTree();
    } else {
      KeepSubtree(next);
    }
  }

  // Whether the reused root's actions are the legal actions of the current belief (they may not
  // be after the model changed, e.g. when new objects were detected).
  bool RootMatchesLegalActions(const State& s) {
    LegalActionsOf(model_, s, &scratch_);
    const ObsNode& root = obs_[root_];
    if (root.num_actions != static_cast<int>(scratch_.size())) return false;
    for (int i = 0; i < root.num_actions; ++i) {
      if (act_[root.first_action + i].action != scratch_[i]) return false;
    }
    return true;
  }

  void ClearTree() {
    obs_.clear();
    act_.clear();
    root_ = -1;
  }

  int NewObsNode() {
    obs_.emplace_back();
    return static_cast<int>(obs_.size()) - 1;
  }

  void Expand(int node, const State& s) {
    LegalActionsOf(model_, s, &scratch_);
    preferred_.clear();
    if constexpr (requires { model_.PreferredActions(s, &preferred_); }) {
      if (options_.use_preferred_actions) model_.PreferredActions(s, &preferred_);
    }
    obs_[node].first_action = static_cast<int>(act_.size());
    obs_[node].num_actions = static_cast<int>(scratch_.size());
    for (int a : scratch_) {
      ActNode an;
      an.action = a;
      if (std::find(preferred_.begin(), preferred_.end(), a) != preferred_.end()) {
        an.n = options_.prior_count;
        an.q = options_.prior_value;
        obs_[node].n += options_.prior_count;
      }
      act_.push_back(std::move(an));
    }
  }

  int SelectAction(int node) const {
    const ObsNode& on = obs_[node];
    const double log_n = std::log(static_cast<double>(std::max<int64_t>(on.n, 1)));
    int best = on.first_action;
    double best_score = -std::numeric_limits<double>::infinity();
    for (int i = on.first_action; i < on.first_action + on.num_actions; ++i) {
      const double score = Ucb1(act_[i].q, act_[i].n, log_n, c_);
      if (score > best_score) {
        best_score = score;
        best = i;
      }
    }
    return best;
  }

  double Simulate(const State& s, int node, int depth, Rng& rng) {
    if (depth >= options_.search.max_depth ||
        std::pow(model_.Discount(), depth) < options_.search.discount_horizon) {
      return 0.0;
    }
    max_depth_ = std::max(max_depth_, depth);
    if (obs_[node].num_actions == 0) {
      Expand(node, s);
      ++obs_[node].n;
      return LeafEstimate(model_, s, depth, options_.search, rng, &scratch_);
    }
    const int ai = SelectAction(node);
    auto step = model_.Step(s, act_[ai].action, rng);
    double total = step.reward;
    if (!step.terminal) {
      const uint64_t h = HashObservation(step.observation);
      int child = act_[ai].children.Find(step.observation, h);
      if (child < 0) {
        child = NewObsNode();
        act_[ai].children.Add(std::move(step.observation), h, child);
      }
      total += model_.Discount() * Simulate(step.state, child, depth + 1, rng);
    }
    ++obs_[node].n;
    ActNode& an = act_[ai];
    ++an.n;
    an.q += (total - an.q) / static_cast<double>(an.n);
    return total;
  }

  Decision<Action> Finish(Decision<Action> d, const TerminationCondition& stop) {
    const ObsNode& root = obs_[root_];
    int best = -1;
    for (int i = root.first_action; i < root.first_action + root.num_actions; ++i) {
      const ActNode& an = act_[i];
      d.root.push_back({an.action, an.n, an.q});
      if (an.n == 0) continue;
      if (best < 0 || an.q > act_[best].q || (an.q == act_[best].q && an.n > act_[best].n)) {
        best = i;
      }
    }
    if (best < 0) best = root.first_action;
    d.action = act_[best].action;
    d.value = act_[best].q;
    d.stats.tree_nodes = TreeSize();
    d.stats.max_depth = max_depth_;
    d.stats.root_actions = root.num_actions;
    d.stats.root_visits = root.n;
    return FinishSearch(std::move(d), stop);
  }

  // Copies the subtree under observation node `new_root` into fresh arrays and makes it the root.
  void KeepSubtree(int new_root) {
    NodeArray<ObsNode> obs;
    NodeArray<ActNode> act;
    std::vector<std::pair<int, int>> stack;  // (old obs index, new obs index)
    obs.push_back(obs_[new_root]);
    stack.emplace_back(new_root, 0);
    while (!stack.empty()) {
      auto [old_o, new_o] = stack.back();
      stack.pop_back();
      const ObsNode& src = obs_[old_o];
      obs[new_o].first_action = static_cast<int>(act.size());
      for (int i = 0; i < src.num_actions; ++i)
        act.push_back(std::move(act_[src.first_action + i]));
      for (int i = 0; i < src.num_actions; ++i) {
        ActNode& an = act[obs[new_o].first_action + i];
        for (int k = 0; k < an.children.size(); ++k) {
          const int old_child = an.children.child(k);
          obs.push_back(obs_[old_child]);
          const int new_child = static_cast<int>(obs.size()) - 1;
          an.children.set_child(k, new_child);
          stack.emplace_back(old_child, new_child);
        }
      }
    }
    obs_ = std::move(obs);
    act_ = std::move(act);
    root_ = 0;
  }

  NodeArray<ObsNode> obs_;
  NodeArray<ActNode> act_;
  int root_ = -1;
  int max_depth_ = 0;
  std::vector<int> scratch_;
  std::vector<int> preferred_;
};

}  // namespace npfkct
