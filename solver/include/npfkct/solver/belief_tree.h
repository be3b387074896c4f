// The belief tree shared by the continuous-action planners (POMCPOW, VOMCPOW, ADVT-style and the
// k-center clustering tree): observation nodes with lists of action nodes, observation branching by
// exact matching or by progressive widening with weighted (s', r) node beliefs, and subtree reuse.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "npfkct/solver/model.h"
#include "npfkct/solver/node_array.h"
#include "npfkct/solver/planner.h"

namespace npfkct {

/// How observations branch below an action node.
struct ObservationWidening {
  /// False: one child per distinct observation (exact matching, for discrete observations).
  /// True: POMCPOW's widening; a new (s', o) is generated while |C(ha)| <= k N(ha)^alpha, else an
  /// existing child is chosen in proportion to how often it was generated, and the simulation
  /// continues from a (s', r) pair drawn from that child's weighted belief.
  bool enabled = true;
  double k = 10.0;
  double alpha = 0.5;
  /// Merge a generated observation into an existing equal child.
  bool check_repeat = true;

  /// Checks every option; the message names the offending one.
  Status Validate() const {
    if (!(k > 0.0) || !std::isfinite(k)) return InvalidArgumentError("k must be > 0");
    if (!(alpha >= 0.0 && alpha <= 1.0)) return InvalidArgumentError("alpha must be in [0, 1]");
    return OkStatus();
  }
};

/// No per-node payload.
struct NoData {};

/// Storage and observation branching of a belief tree over model M. `ActData` is the planner's
/// payload per action node (e.g. a Voronoi cell or a hypersphere). Nodes live in two NodeArrays
/// and refer to each other by index: the tree grows a block at a time, never by moving all its
/// nodes.
template <GenerativeModel M, class ActData = NoData>
class BeliefTree {
 public:
  using State = typename M::State;
  using Action = typename M::Action;
  using Observation = typename M::Observation;

  struct ObsNode {
    int64_t n = 0;             ///< Visits (action selections) at this node.
    std::vector<int> actions;  ///< Action node indices: the node's action list.
    // Weighted (s', r) belief, kept only with observation widening.
    std::vector<State> states;
    std::vector<double> rewards;
    std::vector<double> cumulative;
    std::vector<uint32_t> episodes;  ///< Episode that added each pair.
    double leaf_value = 0.0;         ///< Mean leaf estimate when the node was a leaf.
    int64_t leaf_count = 0;
  };
  struct ActNode {
    Action action{};
    int64_t n = 0;
    double q = 0.0;
    ObservationChildren<Observation> children;
    std::vector<int64_t> generated;  ///< Per child entry: M(hao), times it was generated.
    int64_t total_generated = 0;
    ActData data{};
  };

  /// Result of following an action node down to an observation child.
  struct Transition {
    int child = -1;         ///< Observation node reached (-1 when the step was terminal).
    int entry = -1;         ///< Index of that child in the action node's children table.
    bool new_node = false;  ///< The child was created by this transition.
    State state{};          ///< State to continue from at the child.
    double reward = 0.0;    ///< Reward paired with that state.
    bool terminal = false;  ///< The step ended the episode.
  };

  NodeArray<ObsNode> obs;
  NodeArray<ActNode> act;
  int root = -1;

  /// Drops every node.
  void Clear() {
    obs.clear();
    act.clear();
    root = -1;
  }
  /// Nodes in the tree.
  int64_t size() const { return static_cast<int64_t>(obs.size() + act.size()); }

  /// Appends an empty observation node and returns its index.
  int NewObsNode() {
    obs.emplace_back();
    return static_cast<int>(obs.size()) - 1;
  }
  /// Appends an action node to `node`'s action list and returns its index.
  int NewActNode(int node, Action a, ActData data = {}) {
    ActNode an;
    an.action = std::move(a);
    an.data = std::move(data);
    act.push_back(std::move(an));
    const int ai = static_cast<int>(act.size()) - 1;
    obs[node].actions.push_back(ai);
    return ai;
  }

  /// Simulates `executed` (the action node's action, or a point drawn from it) from state `s`
  /// below action node `ai` and returns the observation child to continue in.
  Transition Descend(const M& model, int ai, const Action& executed, const State& s,
                     const ObservationWidening& widening, uint32_t episode, Rng& rng) {
    Transition t;
    if (!widening.enabled) {
      auto step = model.Step(s, executed, rng);
      t.reward = step.reward;
      t.terminal = step.terminal;
      if (!step.terminal) {
        const uint64_t h = HashObservation(step.observation);
        t.entry = act[ai].children.FindEntry(step.observation, h);
        if (t.entry < 0) {
          t.child = NewObsNode();
          t.new_node = true;
          act[ai].children.Add(std::move(step.observation), h, t.child);
          act[ai].generated.push_back(0);
          t.entry = act[ai].children.size() - 1;
        } else {
          t.child = act[ai].children.child(t.entry);
        }
        ++act[ai].generated[t.entry];
        ++act[ai].total_generated;
      }
      t.state = std::move(step.state);
      return t;
    }
    if constexpr (HasObservationLikelihood<M>) {
      ActNode& an = act[ai];
      const bool widen = static_cast<double>(an.children.size()) <=
                         widening.k * std::pow(static_cast<double>(an.n), widening.alpha);
      auto step = model.Step(s, executed, rng);
      if (widen) {
        const uint64_t h = HashObservation(step.observation);
        int entry = -1;
        if (widening.check_repeat) entry = an.children.FindEntry(step.observation, h);
        if (entry < 0) {
          const int child = NewObsNode();
          ActNode& an2 = act[ai];
          const double w = model.ObservationLikelihood(executed, step.state, step.observation);
          an2.children.Add(step.observation, h, child);
          an2.generated.push_back(0);
          entry = an2.children.size() - 1;
          PushWeighted(child, step.state, step.reward, w, episode);
          ++an2.generated[entry];
          ++an2.total_generated;
          t.child = child;
          t.entry = entry;
          t.new_node = true;
          t.state = std::move(step.state);
          t.reward = step.reward;
          t.terminal = step.terminal;
          return t;
        }
        ++act[ai].generated[entry];
        ++act[ai].total_generated;
      }
      // Continue in an existing child chosen in proportion to M(hao): add (s', r) to its weighted
      // belief and continue from a pair drawn from it.
      const ActNode& a2 = act[ai];
      int64_t u = rng.UniformInt(a2.total_generated);
      int entry = 0;
      while (u >= a2.generated[entry]) u -= a2.generated[entry++];
      t.child = a2.children.child(entry);
      t.entry = entry;
      const double w =
          model.ObservationLikelihood(executed, step.state, a2.children.observation(entry));
      PushWeighted(t.child, std::move(step.state), step.reward, w, episode);
      const int k = SampleWeighted(t.child, rng);
      t.state = obs[t.child].states[k];
      t.reward = obs[t.child].rewards[k];
      t.terminal = IsTerminalState(model, t.state);
      return t;
    } else {
      // Without Z(o | a, s') widening is impossible; the planners reject this configuration.
      (void)episode;
      return Descend(model, ai, executed, s, ObservationWidening{.enabled = false}, 0, rng);
    }
  }

  /// Records a leaf estimate at `node` (its value before any action is tried there).
  void AddLeafValue(int node, double v) {
    ObsNode& on = obs[node];
    ++on.leaf_count;
    on.leaf_value += (v - on.leaf_value) / static_cast<double>(on.leaf_count);
  }

  /// Makes observation node `new_root` the root and drops everything not below it.
  void KeepSubtree(int new_root) {
    NodeArray<ObsNode> new_obs;
    NodeArray<ActNode> new_act;
    std::vector<int> stack;
    new_obs.push_back(std::move(obs[new_root]));
    stack.push_back(0);
    while (!stack.empty()) {
      const int o = stack.back();
      stack.pop_back();
      for (int& ai : new_obs[o].actions) {
        new_act.push_back(std::move(act[ai]));
        ai = static_cast<int>(new_act.size()) - 1;
        ActNode& an = new_act.back();
        for (int k = 0; k < an.children.size(); ++k) {
          new_obs.push_back(std::move(obs[an.children.child(k)]));
          an.children.set_child(k, static_cast<int>(new_obs.size()) - 1);
          stack.push_back(static_cast<int>(new_obs.size()) - 1);
        }
      }
    }
    obs = std::move(new_obs);
    act = std::move(new_act);
    root = 0;
  }

  /// The action node of `node` whose action equals `a`, or -1.
  int FindAction(int node, const Action& a) const {
    for (int ai : obs[node].actions) {
      if (act[ai].action == a) return ai;
    }
    return -1;
  }

  /// Appends a weighted (s', r) pair to `node`'s belief.
  void PushWeighted(int node, State sp, double r, double w, uint32_t episode) {
    ObsNode& on = obs[node];
    if (!std::isfinite(w) || w < 0.0) w = 0.0;
    on.states.push_back(std::move(sp));
    on.rewards.push_back(r);
    on.episodes.push_back(episode);
    on.cumulative.push_back((on.cumulative.empty() ? 0.0 : on.cumulative.back()) + w);
  }

  /// Index of a pair of `node`'s belief drawn in proportion to its weight (uniform if all are 0).
  int SampleWeighted(int node, Rng& rng) const {
    const ObsNode& on = obs[node];
    const double total = on.cumulative.back();
    if (!(total > 0.0)) return static_cast<int>(rng.UniformInt(on.states.size()));
    const double u = rng.Uniform() * total;
    const auto it = std::upper_bound(on.cumulative.begin(), on.cumulative.end(), u);
    return std::min(static_cast<int>(it - on.cumulative.begin()),
                    static_cast<int>(on.states.size()) - 1);
  }
};

/// The root action of the highest Qhat among those tried, else the first (the root must have
/// actions).
template <class Tree>
int BestTriedRootAction(const Tree& tree) {
  int best = -1;
  for (int ai : tree.obs[tree.root].actions) {
    const auto& an = tree.act[ai];
    if (an.n > 0 && (best < 0 || an.q > tree.act[best].q)) best = ai;
  }
  return best < 0 ? tree.obs[tree.root].actions.front() : best;
}

/// Fills the statistics every planner reports from a tree's root.
template <class Tree, class Decision>
void FillRootStats(const Tree& tree, int best, int max_depth, Decision* d) {
  const auto& root = tree.obs[tree.root];
  for (int ai : root.actions) {
    const auto& an = tree.act[ai];
    d->root.push_back({an.action, an.n, an.q});
  }
  d->action = tree.act[best].action;
  d->value = tree.act[best].q;
  d->stats.tree_nodes = tree.size();
  d->stats.max_depth = max_depth;
  d->stats.root_actions = static_cast<int>(root.actions.size());
  d->stats.root_visits = root.n;
}

}  // namespace npfkct
