// What a planner of the solver is (the Planner concept) and the part every planner shares (the
// PlannerBase CRTP base): the model, the options, the root belief, and the calls around the search
// itself. A planner derives from PlannerBase and writes only its search:
//
//   template <DiscreteActionModel M>
//   class MyPlanner : public PlannerBase<MyPlanner<M>, M, MyOptions, int> {
//     using Base = PlannerBase<MyPlanner<M>, M, MyOptions, int>;
//     NPFKCT_PLANNER_INTERFACE(Base);  // State, Action, Plan(Budget), model_, options_, ...
//
//    public:
//     using Base::Base;  // MyPlanner(const M& model, MyOptions options)
//     Decision<int> Plan(const TerminationCondition& stop, Rng& rng) {
//       Decision<int> d;
//       if (Status s = this->Begin(stop, &d); !s.ok()) return Base::Fail(std::move(d), s);
//       ...  // search until stop.ShouldStop(simulations)
//       return FinishSearch(std::move(d), stop);
//     }
//
//    private:
//     bool HasTree() const;                          // whether there is a tree to drop
//     void ClearTree();                              // drop the tree, give its memory back
//     void KeepChild(int a, const Observation& o);   // keep the subtree under (a, o), or clear
//   };
//   static_assert(Planner<MyPlanner<models::Tiger>>);
#pragma once

#include <concepts>
#include <cstdint>
#include <utility>

#include "npfkct/common/rng.h"
#include "npfkct/common/status.h"
#include "npfkct/solver/belief.h"
#include "npfkct/solver/model.h"
#include "npfkct/solver/planner.h"

/// Brings PlannerBase's names into a planner derived from it (a dependent base's names are not
/// found by unqualified lookup), as Eigen's EIGEN_DENSE_PUBLIC_INTERFACE does for its CRTP
/// bases: the types and Plan(Budget) as public members, and the model, options, belief and
/// exploration constant for the search code. Leaves the access at private. A planner whose
/// constructor is PlannerBase's (model, options) adds `using Base::Base;`.
#define NPFKCT_PLANNER_INTERFACE(BaseType) \
 public:                                   \
  using typename BaseType::Action;         \
  using typename BaseType::Observation;    \
  using typename BaseType::State;          \
  using BaseType::Plan;                    \
                                           \
 private:                                  \
  friend BaseType;                         \
  using BaseType::belief_;                 \
  using BaseType::c_;                      \
  using BaseType::model_;                  \
  using BaseType::options_

namespace npfkct {

/// A planner of the solver: it keeps a root belief and a search tree over model states, plans
/// under a caller-owned termination condition (or a budget of its own), and moves its tree to the
/// subtree of a real step. POMCP, POMCPOW/VOMCPOW, the ADVT-style planner and kCT are Planners.
template <class P>
concept Planner = requires(P p, const P cp, Rng& rng, const TerminationCondition& stop,
                           const Budget& budget, ParticleBelief<typename P::State> belief,
                           const typename P::Action& a, const typename P::Observation& o) {
  typename P::State;
  typename P::Action;
  typename P::Observation;
  p.Reset(rng);
  p.SetBelief(std::move(belief));
  p.DropTree();
  { p.Plan(stop, rng) } -> std::same_as<Decision<typename P::Action>>;
  { p.Plan(budget, rng) } -> std::same_as<Decision<typename P::Action>>;
  { p.Advance(a, o, rng) } -> std::same_as<BeliefUpdateSummary>;
  p.AdvanceTo(a, o, std::move(belief));
  { cp.TreeSize() } -> std::convertible_to<int64_t>;
  { cp.belief() } -> std::same_as<const ParticleBelief<typename P::State>&>;
  cp.options();
};

/// The shared part of a planner over model `M` with options `Options` (which have a `search`
/// member of SearchOptions and Validate()), recommending actions of type `ActionT`. `Derived`
/// provides Plan(const TerminationCondition&, Rng&), HasTree(), ClearTree() and
/// KeepChild(action, observation); see the example at the top of this header.
template <class Derived, GenerativeModel M, class Options, class ActionT = typename M::Action>
class PlannerBase {
 public:
  using State = typename M::State;
  using Action = ActionT;
  using Observation = typename M::Observation;

  /// Sets the belief to `search.num_particles` samples of the initial distribution; drops the
  /// tree.
  void Reset(Rng& rng) {
    belief_ = ParticleBelief<State>::FromInitial(model_, options_.search.num_particles, rng);
    self().ClearTree();
  }
  /// Replaces the belief; drops the tree.
  void SetBelief(ParticleBelief<State> belief) {
    belief_ = std::move(belief);
    self().ClearTree();
  }
  /// Drops the search tree and gives its memory back; the belief stays.
  void DropTree() { self().ClearTree(); }
  const ParticleBelief<State>& belief() const { return belief_; }
  const Options& options() const { return options_; }

  /// Plans within a budget of its own (a condition created here, which nobody can cancel).
  Decision<Action> Plan(const Budget& budget, Rng& rng) {
    TerminationCondition stop(budget);
    return self().Plan(stop, rng);
  }

  /// Updates the belief with the real step (a, o) and keeps the matching subtree when tree reuse
  /// is on.
  BeliefUpdateSummary Advance(const Action& a, const Observation& o, Rng& rng) {
    BeliefUpdateSummary summary = belief_.Update(model_, a, o, rng, BeliefOptions());
    self().KeepChild(a, o);
    return summary;
  }

  /// Keeps the subtree under (a, o) when tree reuse is on and installs `belief`: for models whose
  /// belief is maintained outside the planner (object search).
  void AdvanceTo(const Action& a, const Observation& o, ParticleBelief<State> belief) {
    belief_ = std::move(belief);
    self().KeepChild(a, o);
  }

 protected:
  /// Options with an exploration_c give c_ (NaN: the model's reward range). Public to the
  /// planners' inherited constructors (`using Base::Base;`).
 public:
  PlannerBase(const M& model, Options options) : model_(model), options_(std::move(options)) {
    if constexpr (requires { options_.exploration_c; }) {
      c_ = ExplorationConstant(options_.exploration_c);
    }
  }

 protected:
  /// The start of every Plan: CheckPlan, then the tree dropped when it is not reused.
  Status Begin(const TerminationCondition& stop, Decision<Action>* d) {
    if (Status s = CheckPlan(stop); !s.ok()) return s;
    ClearUnlessReused(d);
    return OkStatus();
  }

  /// Simulations from the root until `stop` says so: a state drawn from the belief each, passed to
  /// `simulate` unless it is terminal. Returns how many were run.
  template <class Simulate>
  int64_t SimulateUntil(const TerminationCondition& stop, Rng& rng, Simulate&& simulate) {
    int64_t sims = 0;
    while (!stop.ShouldStop(sims)) {
      const State& s = belief_.Sample(rng);
      if (!IsTerminalState(model_, s)) simulate(s);
      ++sims;
    }
    return sims;
  }

  /// Drops the tree before a search that does not reuse it, timed into d's teardown_ms.
  void ClearUnlessReused(Decision<Action>* d) {
    if (options_.search.reuse_tree || !self().HasTree()) return;
    const auto t0 = Clock::now();
    self().ClearTree();
    d->stats.teardown_ms = MillisSince(t0);
  }

  /// The checks before any search: the options, the budget, a belief to sample, and exact
  /// observation matching for a model without an observation likelihood.
  Status CheckPlan(const TerminationCondition& stop) const {
    if (Status s = options_.Validate(); !s.ok()) return s;
    if (Status s = stop.budget().Validate(); !s.ok()) return s;
    if (belief_.empty()) return FailedPreconditionError("belief is empty");
    if constexpr (requires { options_.observations.enabled; } && !HasObservationLikelihood<M>) {
      if (options_.observations.enabled) {
        return InvalidArgumentError(
            "observations.enabled needs the model's observation likelihood; use exact "
            "observation matching");
      }
    }
    return OkStatus();
  }

  /// A decision that failed with `s` (its budget not exhausted).
  static Decision<Action> Fail(Decision<Action> d, Status s) {
    d.status = std::move(s);
    d.stats.budget_exhausted = false;
    return d;
  }

  /// The belief update settings of Advance (its particles default to the root belief's).
  BeliefUpdateOptions BeliefOptions() const {
    BeliefUpdateOptions b = options_.search.belief;
    if (b.num_particles == 0) b.num_particles = options_.search.num_particles;
    return b;
  }

  /// The UCB exploration constant: `exploration_c`, or the model's reward range when it is NaN.
  double ExplorationConstant(double exploration_c) const {
    return std::isnan(exploration_c) ? RewardRange(model_, 1.0) : exploration_c;
  }

  const M& model_;
  Options options_;
  ParticleBelief<State> belief_;
  /// The UCB exploration constant (options' exploration_c resolved; 1 when it has none).
  double c_ = 1.0;

 private:
  Derived& self() { return static_cast<Derived&>(*this); }
};

}  // namespace npfkct
