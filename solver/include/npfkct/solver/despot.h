// DESPOT (Somani, Ye, Hsu & Lee, NIPS 2013; Ye, Somani, Hsu & Lee, "DESPOT: Online POMDP Planning
// with Regularization", JAIR 58, 2017): anytime heuristic search over a determinized sparse
// partially observable tree. K scenarios (a state sampled from the belief and a random-number
// stream per depth) fix every outcome, so the tree has one branch per action and per observation
// the scenarios produce. Each belief node keeps an upper bound (the model's per-state bound, or
// Rmax / (1 - gamma)) and a lower bound (a default policy's value); a trial follows the action of
// highest upper bound and the observation branch of highest weighted excess uncertainty, expands
// the leaf it reaches and backs the bounds up. The recommended action has the highest lower bound.
// A positive pruning constant lambda charges every policy node, the paper's regularization.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "npfkct/solver/belief.h"
#include "npfkct/solver/model.h"
#include "npfkct/solver/node_array.h"
#include "npfkct/solver/planner.h"
#include "npfkct/solver/planner_base.h"

namespace npfkct {

/// Options of DESPOT. The defaults are those of the authors' code (AdaCompNUS/despot, Config):
/// K = 500 scenarios, search depth 90, xi = 0.95, no regularization, default-policy simulations of
/// at most 90 steps.
struct DespotOptions {
  /// search.max_depth is DESPOT's search depth D; the belief settings serve Advance(). DESPOT
  /// builds a new tree every step, so reuse_tree is off (and must stay off).
  SearchOptions search = [] {
    SearchOptions s;
    s.max_depth = 90;
    s.reuse_tree = false;
    return s;
  }();
  /// Scenarios K sampled from the belief at every search.
  int num_scenarios = 500;
  /// A trial stops where the weighted gap falls below xi times the root's gap.
  double xi = 0.95;
  /// Regularization lambda: the value charged per policy node (0: plain DESPOT).
  double pruning_constant = 0.0;
  /// Steps of a default-policy rollout when the model has no DefaultMove (within the depth).
  int max_policy_sim_len = 90;

  /// Checks every option; the message names the offending one.
  Status Validate() const {
    if (Status s = search.Validate(); !s.ok()) return Prefixed("search", s);
    if (Status s = search.RequireOneThread(); !s.ok()) return s;
    if (search.reuse_tree) {
      return InvalidArgumentError("search.reuse_tree: DESPOT builds a new tree every step; use 0");
    }
    if (num_scenarios < 1 || num_scenarios > 100000) {
      return InvalidArgumentError("num_scenarios must be in [1, 100000]");
    }
    if (!(xi >= 0.0 && xi <= 1.0)) return InvalidArgumentError("xi must be in [0, 1]");
    if (!(pruning_constant >= 0.0 && std::isfinite(pruning_constant))) {
      return InvalidArgumentError("pruning_constant must be >= 0");
    }
    if (max_policy_sim_len < 0) return InvalidArgumentError("max_policy_sim_len must be >= 0");
    return OkStatus();
  }
};

/// DESPOT over a discrete-action generative model with hashable, comparable observations. Uses the
/// model's optional `double UpperBound(const State&) const` (the value of the state with its hidden
/// part known, e.g. an MDP value; else MaxReward() / (1 - gamma)) and, for the lower bound, the
/// first it has of `void DefaultPolicyActions(const std::vector<State>&, std::vector<int>*) const`
/// (a default policy of the node's scenarios taken together, as the authors' belief-level default
/// policies: one action per scenario from what all of them say and what that scenario observes;
/// run on all of them at once), `ValuedAction<int> DefaultMove(const State&) const`, or rollouts
/// of the model's rollout policy on each scenario's streams. The model must outlive the planner.
template <DiscreteActionModel M>
class Despot : public PlannerBase<Despot<M>, M, DespotOptions, int> {
  using Base = PlannerBase<Despot<M>, M, DespotOptions, int>;
  NPFKCT_PLANNER_INTERFACE(Base);

 public:
  using Base::Base;

  /// Builds a DESPOT from K scenarios of the current belief until `stop` (one trial is one
  /// simulation) or until the root's bounds meet, and recommends the action of highest lower
  /// bound (the default policy's action when nothing beats it).
  Decision<Action> Plan(const TerminationCondition& stop, Rng& rng) {
    Decision<Action> d;
    if (Status s = this->Begin(stop, &d); !s.ok()) return Base::Fail(std::move(d), std::move(s));
    const int k = options_.num_scenarios;
    scenario_seeds_.resize(k);
    std::vector<Particle> particles;
    particles.reserve(k);
    for (int i = 0; i < k; ++i) {
      scenario_seeds_[i] = rng();
      particles.push_back({belief_.Sample(rng), i});
    }
    weight_ = 1.0 / k;
    const int root = NewVNode(-1, 0, std::move(particles));
    InitBounds(root);
    max_depth_ = 0;
    int64_t trials = 0;
    while (!stop.ShouldStop(trials) && v_[root].upper - v_[root].lower > 1e-6) {
      Backup(Trial(root));
      ++trials;
    }
    d.stats.simulations = trials;
    Finish(root, &d);
    return FinishSearch(std::move(d), stop);
  }

  /// Nodes in the tree (belief + action nodes).
  int64_t TreeSize() const { return static_cast<int64_t>(v_.size() + q_.size()); }

 private:
  struct Particle {
    State state;
    int scenario = 0;
  };
  // A belief node: its scenarios (states at this depth), bounds on its weighted, discounted value
  // (from the root's time), the default move, and its action children (contiguous in q_).
  struct VNode {
    int parent_q = -1;
    int depth = 0;
    double weight = 0.0;
    double lower = 0.0;
    double upper = 0.0;
    double utility_upper = 0.0;  // the upper bound without regularization
    ValuedAction<Action> default_move;
    int first_q = -1;
    int num_q = 0;
    std::vector<Particle> particles;
  };
  struct QNode {
    Action action = 0;
    int parent_v = -1;
    double step_reward = 0.0;
    double lower = 0.0;
    double upper = 0.0;
    double utility_upper = 0.0;
    int64_t trials = 0;  // trials that chose this action
    ObservationChildren<Observation> children;
  };

  bool HasTree() const { return !v_.empty(); }
  void ClearTree() {
    v_ = NodeArray<VNode>();
    q_ = NodeArray<QNode>();
  }
  void KeepChild(const Action&, const Observation&) { ClearTree(); }

  double Discount(int depth) const { return std::pow(model_.Discount(), depth); }

  // Whether the model states a default policy of a node's scenarios taken together.
  static constexpr bool kHasJointDefaultPolicy =
      requires(const M& m, const std::vector<State>& states, std::vector<Action>* out) {
    m.DefaultPolicyActions(states, out);
  };

  // The generator of scenario `scenario` at `depth`: the same numbers whenever a scenario steps at
  // that depth, whichever branch it is in (DESPOT's random streams).
  Rng Stream(int scenario, int depth) const {
    return Rng(HashMix(scenario_seeds_[scenario] ^ (0x9e3779b97f4a7c15ULL * (depth + 1))));
  }

  int NewVNode(int parent_q, int depth, std::vector<Particle> particles) {
    VNode v;
    v.parent_q = parent_q;
    v.depth = depth;
    v.weight = weight_ * static_cast<double>(particles.size());
    v.particles = std::move(particles);
    v_.push_back(std::move(v));
    return static_cast<int>(v_.size()) - 1;
  }

  // The default policy's value of one scenario's state from `depth` (undiscounted to the root):
  // the model's DefaultMove, else a rollout on the scenario's streams.
  double DefaultValue(const Particle& p, int depth, Action* first) {
    if constexpr (requires { model_.DefaultMove(p.state); }) {
      const ValuedAction<Action> m = model_.DefaultMove(p.state);
      *first = m.action;
      return m.value;
    } else {
      const double gamma = model_.Discount();
      const int end = std::min(options_.search.max_depth, depth + options_.max_policy_sim_len);
      State s = p.state;
      double total = 0.0;
      double discount = 1.0;
      for (int t = depth; t < end && !IsTerminalState(model_, s); ++t) {
        Rng rng = Stream(p.scenario, t);
        const Action a = RolloutPolicyAction(model_, s, rng, &scratch_);
        if (t == depth) *first = a;
        auto step = model_.Step(s, a, rng);
        total += discount * step.reward;
        if (step.terminal) break;
        s = std::move(step.state);
        discount *= gamma;
      }
      return total;
    }
  }

  double ParticleUpperBound(const State& s) const {
    if constexpr (requires {
                    { model_.UpperBound(s) } -> std::convertible_to<double>;
                  }) {
      return model_.UpperBound(s);
    } else {
      static_assert(
          requires { model_.MaxReward(); },
          "DESPOT needs the model's UpperBound(state) or MaxReward()");
      return model_.MaxReward() / (1.0 - model_.Discount());
    }
  }

  // The value of a model's default policy of the node's scenarios (DefaultPolicyActions), run
  // on all of them together on their streams; first_votes_ (empty when called) gets each live
  // scenario's first action.
  double JointDefaultValue(const VNode& v) {
    const double gamma = model_.Discount();
    const int end = std::min(options_.search.max_depth, v.depth + options_.max_policy_sim_len);
    joint_.clear();
    joint_scenarios_.clear();
    for (const Particle& p : v.particles) {
      if (IsTerminalState(model_, p.state)) continue;
      joint_.push_back(p.state);
      joint_scenarios_.push_back(p.scenario);
    }
    double total = 0.0;
    double discount = 1.0;
    for (int t = v.depth; t < end && !joint_.empty(); ++t) {
      model_.DefaultPolicyActions(joint_, &joint_actions_);
      joint_actions_.resize(joint_.size());  // one action per scenario, whatever the model gave
      if (t == v.depth) {
        first_votes_.assign(joint_actions_.begin(), joint_actions_.end());
      }
      size_t kept = 0;
      for (size_t i = 0; i < joint_.size(); ++i) {
        Rng rng = Stream(joint_scenarios_[i], t);
        auto step = model_.Step(joint_[i], joint_actions_[i], rng);
        total += discount * step.reward;
        if (step.terminal) continue;
        joint_[kept] = std::move(step.state);
        joint_scenarios_[kept] = joint_scenarios_[i];
        ++kept;
      }
      joint_.resize(kept);
      joint_scenarios_.resize(kept);
      discount *= gamma;
    }
    return total;
  }

  void InitBounds(int vi) {
    VNode& v = v_[vi];
    const double scale = Discount(v.depth) * weight_;
    double lower = 0.0;
    double upper = 0.0;
    first_votes_.clear();
    if constexpr (kHasJointDefaultPolicy) {
      lower = JointDefaultValue(v);
      for (const Particle& p : v.particles) upper += ParticleUpperBound(p.state);
    } else {
      for (const Particle& p : v.particles) {
        Action first = 0;
        lower += DefaultValue(p, v.depth, &first);
        upper += ParticleUpperBound(p.state);
        first_votes_.push_back(first);
      }
    }
    // A model's DefaultMove names one action for the belief; rollouts vote for their first.
    constexpr bool kHasDefaultMove = !kHasJointDefaultPolicy && requires {
      model_.DefaultMove(v.particles.front().state);
    };
    v.default_move = {kHasDefaultMove ? first_votes_.front() : MostCommon(&first_votes_),
                      scale * lower};
    v.lower = v.default_move.value;
    v.utility_upper = scale * upper;
    v.upper = v.utility_upper - options_.pruning_constant;
    // A node at the last level cannot be searched further: its value is the default policy's.
    if (v.upper < v.lower || v.depth >= options_.search.max_depth - 1) v.upper = v.lower;
  }

  static Action MostCommon(std::vector<Action>* actions) {
    std::sort(actions->begin(), actions->end());
    Action best = actions->empty() ? Action{} : actions->front();
    int best_count = 0;
    for (size_t i = 0; i < actions->size();) {
      size_t j = i;
      while (j < actions->size() && (*actions)[j] == (*actions)[i]) ++j;
      if (static_cast<int>(j - i) > best_count) {
        best_count = static_cast<int>(j - i);
        best = (*actions)[i];
      }
      i = j;
    }
    return best;
  }

  // Weighted excess uncertainty of a belief node against the root (node 0).
  double Weu(int vi) const {
    const VNode& v = v_[vi];
    return (v.upper - v.lower) -
           options_.xi * (v.weight / v_[0].weight) * (v_[0].upper - v_[0].lower);
  }

  // One trial: from the root, expand leaves and descend by the action of highest upper bound and
  // the observation of highest excess uncertainty, while that is positive and within the depth.
  int Trial(int root) {
    int cur = root;
    while (true) {
      max_depth_ = std::max(max_depth_, v_[cur].depth);
      ExploitBlockers(cur);
      if (v_[cur].upper - v_[cur].lower <= 0.0) break;
      if (v_[cur].num_q == 0) Expand(cur);
      if (v_[cur].num_q == 0) break;
      int qstar = v_[cur].first_q;
      for (int i = 1; i < v_[cur].num_q; ++i) {
        const int qi = v_[cur].first_q + i;
        if (q_[qi].upper > q_[qstar].upper) qstar = qi;
      }
      ++q_[qstar].trials;
      int next = -1;
      double best = -std::numeric_limits<double>::infinity();
      const QNode& q = q_[qstar];
      for (int c = 0; c < q.children.size(); ++c) {
        const int child = q.children.child(c);
        const double weu = Weu(child);
        if (weu >= best) {
          best = weu;
          next = child;
        }
      }
      if (next < 0) break;
      cur = next;
      if (v_[cur].depth >= options_.search.max_depth || Weu(cur) <= 0.0) break;
    }
    return cur;
  }

  // Adds a belief node's action children: every legal action steps every scenario on its stream,
  // and the scenarios are partitioned by observation into new belief nodes.
  void Expand(int vi) {
    LegalActionsOf(model_, v_[vi].particles.front().state, &actions_);
    v_[vi].first_q = static_cast<int>(q_.size());
    v_[vi].num_q = static_cast<int>(actions_.size());
    for (Action a : actions_) {
      QNode q;
      q.action = a;
      q.parent_v = vi;
      q_.push_back(std::move(q));
    }
    for (int i = 0; i < v_[vi].num_q; ++i) ExpandAction(vi, v_[vi].first_q + i);
  }

  void ExpandAction(int vi, int qi) {
    const int depth = v_[vi].depth;
    const Action a = q_[qi].action;
    // Step every scenario into one reused buffer, then copy each observation's scenarios into a
    // vector of its exact size.
    ObservationChildren<Observation> groups;
    std::vector<Observation> observations;
    stepped_.clear();
    group_of_.clear();
    double reward = 0.0;
    for (const Particle& p : v_[vi].particles) {
      Rng rng = Stream(p.scenario, depth);
      auto step = model_.Step(p.state, a, rng);
      reward += step.reward;
      if (step.terminal) continue;
      const uint64_t h = HashObservation(step.observation);
      int g = groups.Find(step.observation, h);
      if (g < 0) {
        g = static_cast<int>(observations.size());
        groups.Add(step.observation, h, g);
        observations.push_back(std::move(step.observation));
      }
      stepped_.push_back({std::move(step.state), p.scenario});
      group_of_.push_back(g);
    }
    std::vector<std::vector<Particle>> partitions(observations.size());
    std::vector<int> counts(observations.size(), 0);
    for (int g : group_of_) ++counts[g];
    for (size_t g = 0; g < partitions.size(); ++g) partitions[g].reserve(counts[g]);
    for (size_t i = 0; i < stepped_.size(); ++i) {
      partitions[group_of_[i]].push_back(std::move(stepped_[i]));
    }
    const double step_reward = Discount(depth) * weight_ * reward - options_.pruning_constant;
    double lower = step_reward;
    double upper = step_reward;
    for (size_t g = 0; g < partitions.size(); ++g) {
      const int child = NewVNode(qi, depth + 1, std::move(partitions[g]));
      InitBounds(child);
      lower += v_[child].lower;
      upper += v_[child].upper;
      const Observation& o = observations[g];
      q_[qi].children.Add(o, HashObservation(o), child);
    }
    QNode& q = q_[qi];
    q.step_reward = step_reward;
    q.lower = lower;
    q.upper = upper;
    q.utility_upper = upper + options_.pruning_constant;
  }

  // Bounds of a belief node from its children (they only tighten).
  void UpdateV(int vi) {
    VNode& v = v_[vi];
    if (v.num_q == 0) return;
    double lower = v.default_move.value;
    double upper = v.default_move.value;
    double utility_upper = -std::numeric_limits<double>::infinity();
    for (int i = v.first_q; i < v.first_q + v.num_q; ++i) {
      lower = std::max(lower, q_[i].lower);
      upper = std::max(upper, q_[i].upper);
      utility_upper = std::max(utility_upper, q_[i].utility_upper);
    }
    v.lower = std::max(v.lower, lower);
    v.upper = std::min(v.upper, upper);
    v.utility_upper = std::min(v.utility_upper, utility_upper);
  }

  void UpdateQ(int qi) {
    QNode& q = q_[qi];
    double lower = q.step_reward;
    double upper = q.step_reward;
    double utility_upper = q.step_reward + options_.pruning_constant;
    for (int c = 0; c < q.children.size(); ++c) {
      const VNode& v = v_[q.children.child(c)];
      lower += v.lower;
      upper += v.upper;
      utility_upper += v.utility_upper;
    }
    q.lower = std::max(q.lower, lower);
    q.upper = std::min(q.upper, upper);
    q.utility_upper = std::min(q.utility_upper, utility_upper);
  }

  void Backup(int vi) {
    while (true) {
      UpdateV(vi);
      const int qi = v_[vi].parent_q;
      if (qi < 0) return;
      UpdateQ(qi);
      vi = q_[qi].parent_v;
    }
  }

  // The belief node's parent belief node, or -1 at the root.
  int ParentV(int vi) const {
    const int qi = v_[vi].parent_q;
    return qi < 0 ? -1 : q_[qi].parent_v;
  }

  // The nearest ancestor (or the node itself) whose default policy is worth at least its
  // unregularized upper bound less lambda per policy node between them: below it, no policy can
  // beat the default policy by more than the regularization charges. -1 when there is none.
  int FindBlocker(int vi) const {
    int count = 1;
    for (int cur = vi; cur >= 0; cur = ParentV(cur), ++count) {
      const VNode& v = v_[cur];
      if (v.utility_upper - count * options_.pruning_constant <= v.default_move.value) return cur;
    }
    return -1;
  }

  // Regularization: closes the gap of blocked nodes (the node itself, or its observation siblings
  // when an ancestor blocks it) at the default policy's value, up the path while blockers remain.
  void ExploitBlockers(int vi) {
    if (options_.pruning_constant <= 0.0) return;
    for (int cur = vi; cur >= 0;) {
      const int blocker = FindBlocker(cur);
      if (blocker < 0) return;
      auto close = [this](int node) {
        VNode& v = v_[node];
        v.lower = v.upper = v.utility_upper = v.default_move.value;
      };
      const int qi = v_[cur].parent_q;
      if (qi < 0 || blocker == cur) {
        close(cur);
      } else {
        const QNode& q = q_[qi];
        for (int c = 0; c < q.children.size(); ++c) close(q.children.child(c));
      }
      Backup(cur);
      cur = ParentV(cur);
    }
  }

  // DESPOT's recommendation: the action of highest lower bound, or the default move when its
  // value is higher.
  void Finish(int root, Decision<Action>* d) {
    const VNode& r = v_[root];
    Action best = r.default_move.action;
    double best_value = r.default_move.value;
    double q_best = -std::numeric_limits<double>::infinity();
    Action q_action = best;
    for (int i = r.first_q; i < r.first_q + r.num_q; ++i) {
      const QNode& q = q_[i];
      d->root.push_back({q.action, q.trials, q.lower / r.weight});
      if (q.lower > q_best) {
        q_best = q.lower;
        q_action = q.action;
      }
    }
    if (r.num_q > 0 && q_best >= best_value) {
      best = q_action;
      best_value = q_best;
    }
    d->action = best;
    d->value = best_value / r.weight;
    d->stats.tree_nodes = TreeSize();
    d->stats.max_depth = max_depth_;
    d->stats.root_actions = r.num_q;
    d->stats.root_visits = d->stats.simulations;
  }

  NodeArray<VNode> v_;
  NodeArray<QNode> q_;
  std::vector<uint64_t> scenario_seeds_;
  double weight_ = 1.0;
  int max_depth_ = 0;
  std::vector<int> actions_;
  std::vector<int> scratch_;
  std::vector<Action> first_votes_;
  std::vector<Particle> stepped_;
  std::vector<int> group_of_;
  std::vector<State> joint_;
  std::vector<int> joint_scenarios_;
  std::vector<Action> joint_actions_;
};

}  // namespace npfkct
