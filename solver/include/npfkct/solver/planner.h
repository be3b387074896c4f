// Pieces every planner shares: budgets and termination conditions (OMPL style), decisions and
// their statistics, rollouts, and the observation-children table of search trees.
#pragma once

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "npfkct/solver/belief.h"
#include "npfkct/solver/model.h"
#include "npfkct/solver/rng.h"
#include "npfkct/solver/status.h"

namespace npfkct {

using Clock = std::chrono::steady_clock;

/// Milliseconds elapsed since `start`.
inline double MillisSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/// How much search one planning call may spend. At least one limit must be set. Time is wall
/// clock from the moment Plan() is entered until it returns, tree teardown included.
struct Budget {
  /// Wall-clock limit in milliseconds; 0 means no time limit.
  double time_ms = 1000.0;
  /// Limit on simulations (episodes from the root); 0 means no limit.
  int64_t max_simulations = 0;

  /// A budget of `ms` milliseconds.
  static Budget Time(double ms) { return Budget{ms, 0}; }
  /// A budget of `n` simulations and no time limit.
  static Budget Simulations(int64_t n) { return Budget{0.0, n}; }

  /// Rejects negative or non-finite limits and a budget with no limit at all.
  Status Validate() const {
    if (!std::isfinite(time_ms) || time_ms < 0.0) {
      return InvalidArgumentError("budget.time_ms must be a finite number >= 0");
    }
    if (max_simulations < 0) return InvalidArgumentError("budget.max_simulations must be >= 0");
    if (time_ms == 0.0 && max_simulations == 0) {
      return InvalidArgumentError("budget: set time_ms and/or max_simulations");
    }
    return OkStatus();
  }
};

/// Decides when a search stops: after the budget's time or simulations, or when an external
/// cancel flag is raised (like OMPL's PlannerTerminationCondition).
class TerminationCondition {
 public:
  /// Counts time from `start`. `cancel` may be null.
  TerminationCondition(const Budget& budget, Clock::time_point start,
                       const std::atomic<bool>* cancel = nullptr)
      : max_sims_(budget.max_simulations), cancel_(cancel) {
    has_deadline_ = budget.time_ms > 0.0;
    deadline_ = start + std::chrono::duration_cast<Clock::duration>(
                            std::chrono::duration<double, std::milli>(budget.time_ms));
  }

  /// Whether the search must stop after `simulations` completed simulations.
  bool ShouldStop(int64_t simulations) const {
    if (max_sims_ > 0 && simulations >= max_sims_) return true;
    if (cancel_ != nullptr && cancel_->load(std::memory_order_relaxed)) return true;
    return has_deadline_ && Clock::now() >= deadline_;
  }

 private:
  int64_t max_sims_;
  const std::atomic<bool>* cancel_;
  bool has_deadline_ = false;
  Clock::time_point deadline_;
};

/// Statistics of one planning call.
struct SearchStats {
  int64_t simulations = 0;       ///< Episodes simulated from the root in this call.
  double elapsed_ms = 0.0;       ///< Wall time of the call, teardown included.
  double teardown_ms = 0.0;      ///< Time spent discarding the previous tree.
  int64_t tree_nodes = 0;        ///< Observation + action nodes in the tree after the call.
  int max_depth = 0;             ///< Deepest tree level reached.
  int root_actions = 0;          ///< Action branches at the root.
  int64_t root_visits = 0;       ///< Visits of the root (reused visits included).
  int64_t reused_visits = 0;     ///< Root visits inherited from the previous step's tree.
  int64_t refinements = 0;       ///< Action-space refinements (cell splits, sphere refinements).
  bool budget_exhausted = true;  ///< False when the search stopped for another reason.
};

/// Statistics of one root action, for logs and the API.
template <class Action>
struct RootActionStat {
  Action action;
  int64_t visits = 0;
  double value = 0.0;
};

/// What a planner recommends.
template <class Action>
struct Decision {
  Status status;                             ///< OK, or why no action could be chosen.
  Action action{};                           ///< The recommended action.
  double value = 0.0;                        ///< Estimated value of the action at the root.
  SearchStats stats;                         ///< How the search went.
  std::vector<RootActionStat<Action>> root;  ///< Per-action root statistics.
};

/// Options shared by all tree-search planners.
struct SearchOptions {
  /// Maximum depth of simulations (tree + rollout).
  int max_depth = 100;
  /// Simulations stop when discount^depth falls below this (POMCP's epsilon).
  double discount_horizon = 0.005;
  /// Keep the subtree under the executed (action, observation) after a real step.
  bool reuse_tree = true;
  /// Particles in the root belief.
  int num_particles = 1000;
  /// Belief update settings used by Advance().
  BeliefUpdateOptions belief;
  /// How a new leaf is valued: a rollout with the model's rollout policy, or the model's
  /// HeuristicValue(s) (e.g. the fully observable MDP value, as POMCPOW's FOValue).
  enum class LeafValue { kRollout, kHeuristic };
  LeafValue leaf_value = LeafValue::kRollout;

  /// Checks the shared fields.
  Status Validate() const {
    if (max_depth < 1) return InvalidArgumentError("max_depth must be >= 1");
    if (!(discount_horizon > 0.0 && discount_horizon < 1.0)) {
      return InvalidArgumentError("discount_horizon must be in (0, 1)");
    }
    if (num_particles < 1) return InvalidArgumentError("num_particles must be >= 1");
    if (Status s = belief.Validate(); !s.ok()) return Status(s.code(), "belief." + s.message());
    return OkStatus();
  }
};

/// Prefixes a non-OK status message with `field.` so that it names the option's full path.
inline Status Prefixed(const std::string& field, Status s) {
  if (s.ok()) return s;
  return Status(s.code(), field + "." + s.message());
}

/// The UCB1 score Q + c sqrt(log N / n); +infinity for an untried action (n == 0).
inline double Ucb1(double q, int64_t n, double log_parent, double c) {
  if (n <= 0) return std::numeric_limits<double>::infinity();
  return q + c * std::sqrt(log_parent / static_cast<double>(n));
}

/// A uniformly random action of a model: a legal discrete action, or a legal kind with a uniform
/// point of its box for hybrid models.
template <GenerativeModel M>
typename M::Action UniformRandomAction(const M& model, const typename M::State& s, Rng& rng,
                                       std::vector<int>* scratch) {
  if constexpr (DiscreteActionModel<M>) {
    LegalActionsOf(model, s, scratch);
    return (*scratch)[rng.UniformInt(static_cast<int64_t>(scratch->size()))];
  } else {
    static_assert(HybridActionModel<M>, "the model's actions must be discrete or hybrid");
    model.ActionKinds(s, scratch);
    HybridAction a;
    a.kind = (*scratch)[rng.UniformInt(static_cast<int64_t>(scratch->size()))];
    a.x = model.KindSpace(a.kind).SampleUniform(rng);
    return a;
  }
}

/// The discounted return of a rollout from `s` at `depth` with the model's rollout policy
/// (uniform random when it has none), until a terminal state, max_depth or the discount horizon.
template <GenerativeModel M>
double Rollout(const M& model, typename M::State s, int depth, const SearchOptions& options,
               Rng& rng, std::vector<int>* scratch) {
  const double gamma = model.Discount();
  double total = 0.0;
  double discount = 1.0;
  double horizon_discount = std::pow(gamma, depth);
  while (depth < options.max_depth && horizon_discount >= options.discount_horizon) {
    if (IsTerminalState(model, s)) break;
    typename M::Action a;
    if constexpr (requires {
                    { model.RolloutAction(s, rng) } -> std::same_as<typename M::Action>;
                  }) {
      a = model.RolloutAction(s, rng);
    } else {
      a = UniformRandomAction(model, s, rng, scratch);
    }
    auto step = model.Step(s, a, rng);
    total += discount * step.reward;
    if (step.terminal) break;
    s = std::move(step.state);
    discount *= gamma;
    horizon_discount *= gamma;
    ++depth;
  }
  return total;
}

/// The value of a new leaf at `depth`: the model's HeuristicValue when asked for (and present),
/// else a rollout.
template <GenerativeModel M>
double LeafEstimate(const M& model, const typename M::State& s, int depth,
                    const SearchOptions& options, Rng& rng, std::vector<int>* scratch) {
  if constexpr (requires {
                  { model.HeuristicValue(s) } -> std::convertible_to<double>;
                }) {
    if (options.leaf_value == SearchOptions::LeafValue::kHeuristic) {
      return IsTerminalState(model, s) ? 0.0 : model.HeuristicValue(s);
    }
  }
  return Rollout(model, s, depth, options, rng, scratch);
}

/// Maps observations to child indices for one action node. Small tables are scanned linearly;
/// larger ones (continuous observations) switch to a hash index.
template <class Observation>
class ObservationChildren {
 public:
  /// The child index of `o`, or -1.
  int Find(const Observation& o, uint64_t hash) const {
    const int e = FindEntry(o, hash);
    return e < 0 ? -1 : entries_[e].child;
  }

  /// The entry index of `o`, or -1.
  int FindEntry(const Observation& o, uint64_t hash) const {
    if (index_.empty()) {
      for (int i = 0; i < static_cast<int>(entries_.size()); ++i) {
        if (entries_[i].hash == hash && entries_[i].observation == o) return i;
      }
      return -1;
    }
    auto [lo, hi] = index_.equal_range(hash);
    for (auto it = lo; it != hi; ++it) {
      if (entries_[it->second].observation == o) return it->second;
    }
    return -1;
  }

  /// Adds `o -> child`; `o` must not be present.
  void Add(Observation o, uint64_t hash, int child) {
    entries_.push_back(Entry{std::move(o), hash, child});
    if (!index_.empty()) {
      index_.emplace(hash, static_cast<int>(entries_.size()) - 1);
    } else if (entries_.size() > kLinearLimit) {
      for (int i = 0; i < static_cast<int>(entries_.size()); ++i) {
        index_.emplace(entries_[i].hash, i);
      }
    }
  }

  int size() const { return static_cast<int>(entries_.size()); }
  bool empty() const { return entries_.empty(); }
  const Observation& observation(int i) const { return entries_[i].observation; }
  uint64_t hash(int i) const { return entries_[i].hash; }
  int child(int i) const { return entries_[i].child; }
  void set_child(int i, int child) { entries_[i].child = child; }

 private:
  static constexpr size_t kLinearLimit = 16;
  struct Entry {
    Observation observation;
    uint64_t hash;
    int child;
  };
  std::vector<Entry> entries_;
  std::unordered_multimap<uint64_t, int> index_;
};

}  // namespace npfkct
