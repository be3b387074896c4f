// Pieces every planner shares: budgets and termination conditions (OMPL style), decisions and
// their statistics, rollouts, and the observation-children table of search trees.
#pragma once

#include <pthread.h>
#include <time.h>

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

#include "npfkct/common/rng.h"
#include "npfkct/common/status.h"
#include "npfkct/solver/belief.h"
#include "npfkct/solver/model.h"

namespace npfkct {

using Clock = std::chrono::steady_clock;

/// Milliseconds elapsed since `start`.
inline double MillisSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/// CPU time consumed so far by the calling thread, in milliseconds (CLOCK_THREAD_CPUTIME_ID).
inline double ThreadCpuMillis() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

/// How much search one planning call may spend; the search stops at the first limit reached. At
/// least one limit must be set. Limits count from the creation of the TerminationCondition that
/// carries them, so the teardown of the previous tree is included.
///
///   Budget b = Budget::Cpu(1000);         // 1 s of the planning thread's CPU time
///   b.max_simulations = 50000;            // ... or 50,000 simulations, whichever comes first
struct Budget {
  /// Wall-clock limit in milliseconds; 0 means no wall-clock limit.
  double time_ms = 0.0;
  /// Limit on simulations (episodes from the root); 0 means no limit.
  int64_t max_simulations = 0;
  /// Limit on the CPU time of the planning thread (CLOCK_THREAD_CPUTIME_ID) in milliseconds; 0
  /// means none. Unlike wall time it does not shrink when other work shares the core, so results
  /// measured under CPU budgets repeat on a loaded machine.
  double cpu_ms = 0.0;

  /// A budget of `ms` milliseconds of wall-clock time.
  static Budget Time(double ms) { return Budget{ms, 0, 0.0}; }
  /// A budget of `ms` milliseconds of the planning thread's CPU time.
  static Budget Cpu(double ms) { return Budget{0.0, 0, ms}; }
  /// A budget of `n` simulations and no time limit.
  static Budget Simulations(int64_t n) { return Budget{0.0, n, 0.0}; }

  /// Rejects negative or non-finite limits and a budget with no limit at all.
  Status Validate() const {
    if (!std::isfinite(time_ms) || time_ms < 0.0) {
      return InvalidArgumentError("budget.time_ms must be a finite number >= 0");
    }
    if (!std::isfinite(cpu_ms) || cpu_ms < 0.0) {
      return InvalidArgumentError("budget.cpu_ms must be a finite number >= 0");
    }
    if (max_simulations < 0) return InvalidArgumentError("budget.max_simulations must be >= 0");
    if (time_ms == 0.0 && cpu_ms == 0.0 && max_simulations == 0) {
      return InvalidArgumentError("budget: set time_ms, cpu_ms and/or max_simulations");
    }
    return OkStatus();
  }
};

/// Decides when a search stops: after the budget's wall time, CPU time or simulations, when
/// Terminate() was called (from any thread), when the optional extra condition holds (a
/// cancellation), or when the optional resource limit is reached (an early end). Like
/// OMPL's PlannerTerminationCondition it is owned by the caller and passed to Plan(), so a caller
/// that deletes a session, notices a disconnect or shuts down can stop a running search:
///
///   TerminationCondition stop(Budget::Cpu(500));   // created in the thread that will plan
///   std::thread watchdog([&] { if (client_gone()) stop.Terminate(); });
///   Decision d = planner.Plan(stop, rng);          // d.status is CANCELLED after Terminate()
///
/// Time counts from construction. A CPU budget reads the CPU clock of the thread that constructed
/// the condition, so construct it in the planning thread.
///
/// A resource limit ends a search early without cancelling it: the decision keeps an OK status
/// and its best action, with stats.budget_exhausted false:
///
///   TerminationCondition stop(Budget::Cpu(500), client_gone);
///   stop.StopAtLimit([] { return HeapBytes() > kMaxHeap; });
class TerminationCondition {
 public:
  /// Counts from now. `also_stop`, when given, is polled at most every `poll_ms` of wall time
  /// (e.g. "the client closed its connection") and cancels the search when it returns true.
  explicit TerminationCondition(const Budget& budget, std::function<bool()> also_stop = {},
                                double poll_ms = 5.0)
      : budget_(budget), also_stop_(std::move(also_stop)), poll_ms_(poll_ms) {
    start_ = Clock::now();
    pthread_getcpuclockid(pthread_self(), &cpu_clock_);
    cpu_start_ms_ = CpuNowMs();
    deadline_ = start_ + std::chrono::duration_cast<Clock::duration>(
                             std::chrono::duration<double, std::milli>(budget.time_ms));
  }
  TerminationCondition(const TerminationCondition&) = delete;
  TerminationCondition& operator=(const TerminationCondition&) = delete;

  /// Also ends the search, like its budget, once `reached` returns true (polled with the extra
  /// condition; e.g. "the process's memory is past its bound"). Call before planning.
  void StopAtLimit(std::function<bool()> reached) { limit_ = std::move(reached); }

  /// Asks the search to stop at its next check. Safe to call from any thread.
  void Terminate() const { terminated_.store(true, std::memory_order_relaxed); }
  /// Whether Terminate() was called or the extra condition fired (a cancellation, not a budget).
  bool cancelled() const { return terminated_.load(std::memory_order_relaxed); }
  /// Whether the resource limit of StopAtLimit() ended the search.
  bool limit_reached() const { return limit_hit_.load(std::memory_order_relaxed); }
  const Budget& budget() const { return budget_; }

  /// Whether the search was cancelled or reached its resource limit, polling the extra condition
  /// and the limit when `poll_ms` has passed since the last poll; the budget is not read. For a
  /// search split over threads, each under a condition of its own: any thread may call it.
  bool Interrupted() const { return Interrupted(ElapsedMs()); }

  /// Whether the search must stop after `simulations` completed simulations.
  bool ShouldStop(int64_t simulations) const {
    if (budget_.max_simulations > 0 && simulations >= budget_.max_simulations) return true;
    const auto now = Clock::now();
    if (budget_.time_ms > 0.0 && now >= deadline_) return true;
    const double wall_ms = std::chrono::duration<double, std::milli>(now - start_).count();
    if (Interrupted(wall_ms)) return true;
    if (budget_.cpu_ms > 0.0) {
      // Reading a thread's CPU clock is a system call; read it at most every 0.1 ms of wall time
      // (the CPU time used in between cannot exceed the wall time that passed).
      const double seen = cpu_seen_ms_.load(std::memory_order_relaxed);
      const double at = cpu_seen_at_ms_.load(std::memory_order_relaxed);
      if (seen + (wall_ms - at) < budget_.cpu_ms && wall_ms - at < 0.1) return false;
      const double used = CpuNowMs() - cpu_start_ms_;
      cpu_seen_ms_.store(used, std::memory_order_relaxed);
      cpu_seen_at_ms_.store(wall_ms, std::memory_order_relaxed);
      if (used >= budget_.cpu_ms) return true;
    }
    return false;
  }

  /// Wall-clock milliseconds since construction.
  double ElapsedMs() const { return MillisSince(start_); }
  /// CPU milliseconds of the constructing thread since construction.
  double CpuMs() const { return CpuNowMs() - cpu_start_ms_; }

 private:
  // One thread at a time runs the callbacks: the one that moves the next poll time on.
  bool Interrupted(double wall_ms) const {
    if (cancelled() || limit_reached()) return true;
    if (!also_stop_ && !limit_) return false;
    double next = next_poll_ms_.load(std::memory_order_relaxed);
    if (wall_ms < next || !next_poll_ms_.compare_exchange_strong(next, wall_ms + poll_ms_,
                                                                 std::memory_order_relaxed)) {
      return false;
    }
    if (also_stop_ && also_stop_()) {
      Terminate();
      return true;
    }
    if (limit_ && limit_()) {
      limit_hit_.store(true, std::memory_order_relaxed);
      return true;
    }
    return false;
  }

  double CpuNowMs() const {
    timespec ts{};
    clock_gettime(cpu_clock_, &ts);
    return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
  }

  Budget budget_;
  std::function<bool()> also_stop_;
  std::function<bool()> limit_;
  double poll_ms_;
  Clock::time_point start_;
  Clock::time_point deadline_;
  clockid_t cpu_clock_ = CLOCK_THREAD_CPUTIME_ID;
  double cpu_start_ms_ = 0.0;
  mutable std::atomic<bool> terminated_{false};
  mutable std::atomic<bool> limit_hit_{false};
  mutable std::atomic<double> next_poll_ms_{0.0};
  mutable std::atomic<double> cpu_seen_ms_{0.0};
  mutable std::atomic<double> cpu_seen_at_ms_{-1.0};
};

/// Statistics of one planning call.
struct SearchStats {
  int64_t simulations = 0;       ///< Episodes simulated from the root in this call.
  double elapsed_ms = 0.0;       ///< Wall time of the call, teardown included.
  double cpu_ms = 0.0;           ///< CPU time of the call's threads (the caller's and workers').
  double teardown_ms = 0.0;      ///< Time spent discarding the previous tree.
  int64_t tree_nodes = 0;        ///< Observation + action nodes in the tree after the call.
  int max_depth = 0;             ///< Deepest tree level reached.
  int root_actions = 0;          ///< Action branches at the root.
  int64_t root_visits = 0;       ///< Visits of the root (reused visits included).
  int64_t reused_visits = 0;     ///< Root visits inherited from the previous step's tree.
  int64_t refinements = 0;       ///< Action-space refinements (cell splits, sphere refinements).
  bool budget_exhausted = true;  ///< False when the search stopped for another reason.
};

/// Fills the time statistics of a finished search from its termination condition and reports a
/// cancellation (Terminate() or the extra condition) as CANCELLED and a search ended by its
/// resource limit as not having exhausted its budget. The decision's action is kept, so a caller
/// may still use the best action found so far.
template <class Decision>
Decision FinishSearch(Decision d, const TerminationCondition& stop) {
  d.stats.elapsed_ms = stop.ElapsedMs();
  d.stats.cpu_ms = stop.CpuMs();
  if (stop.cancelled() && d.status.ok()) {
    d.status = CancelledError("planning was cancelled");
    d.stats.budget_exhausted = false;
  } else if (stop.limit_reached()) {
    d.stats.budget_exhausted = false;
  }
  return d;
}

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
  /// Search threads per planning call. kCT runs that many independent trees over the same belief
  /// and root candidates (root parallelism) and merges their root statistics; the other planners
  /// plan on one thread and reject more.
  int threads = 1;
  /// Try the model's rollout action first at the root (VOOTreeSearch's RolloutFirst): continuous
  /// planners add it to the root's actions before any sampled one. Needs RolloutAction; a model's
  /// BeliefRolloutAction, when it has one, gives it for the whole belief (RolloutFirstAction).
  bool rollout_first = false;

  /// Checks the shared fields.
  Status Validate() const {
    if (max_depth < 1) return InvalidArgumentError("max_depth must be >= 1");
    if (!(discount_horizon > 0.0 && discount_horizon < 1.0)) {
      return InvalidArgumentError("discount_horizon must be in (0, 1)");
    }
    if (num_particles < 1) return InvalidArgumentError("num_particles must be >= 1");
    if (threads < 1 || threads > 64) return InvalidArgumentError("threads must be in [1, 64]");
    if (Status s = belief.Validate(); !s.ok()) return Status(s.code(), "belief." + s.message());
    return OkStatus();
  }
  /// INVALID_ARGUMENT naming search.threads unless it is 1: for the planners that search on one
  /// thread (only kCT plans on several).
  Status RequireOneThread() const {
    if (threads == 1) return OkStatus();
    return InvalidArgumentError(
        "search.threads: only kCT plans on several threads; this planner needs 1");
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

/// The rollout policy's action at `s`: the model's RolloutAction, or a uniformly random legal
/// action when it has none.
template <GenerativeModel M>
typename M::Action RolloutPolicyAction(const M& model, const typename M::State& s, Rng& rng,
                                       std::vector<int>* scratch) {
  if constexpr (requires {
                  { model.RolloutAction(s, rng) } -> std::same_as<typename M::Action>;
                }) {
    return model.RolloutAction(s, rng);
  } else {
    return UniformRandomAction(model, s, rng, scratch);
  }
}

/// The discounted return of a rollout from `s` at `depth` with the model's rollout policy
/// (uniform random when it has none), until a terminal state, max_depth or the discount horizon.
template <GenerativeModel M>
double Rollout(const M& model, typename M::State s, int depth, const SearchOptions& options,
               Rng& rng, std::vector<int>* scratch) {
  // A model over a restricted action set (e.g. a manual discrete set) may delegate its rollouts
  // to the full model it wraps, so that every planner shares one rollout policy.
  if constexpr (requires { model.rollout_model(); }) {
    return Rollout(model.rollout_model(), std::move(s), depth, options, rng, scratch);
  } else {
    const double gamma = model.Discount();
    double total = 0.0;
    double discount = 1.0;
    double horizon_discount = std::pow(gamma, depth);
    while (depth < options.max_depth && horizon_discount >= options.discount_horizon) {
      if (IsTerminalState(model, s)) break;
      const typename M::Action a = RolloutPolicyAction(model, s, rng, scratch);
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
