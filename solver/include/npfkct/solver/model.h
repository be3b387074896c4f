// The generative POMDP model concept that every planner is a template over.
//
// A model is a plain class with three member types and a few const member functions, in the
// spirit of DESPOT's DSPOMDP and POMDPs.jl's generative interface:
//
//   struct MyModel {
//     using State = ...; using Action = ...; using Observation = ...;
//     State SampleInitialState(Rng& rng) const;                       // b0
//     StepResult<State, Observation> Step(const State& s, const Action& a, Rng& rng) const;
//     double Discount() const;
//   };
//
// Optional members, detected at compile time, refine what planners can do:
//   bool IsTerminal(const State&) const;
//       default: never terminal
//   double ObservationLikelihood(const Action&, const State& sp, const Observation&) const;
//       Z(o | a, s'), needed by POMCPOW-style planners
//   Action RolloutAction(const State&, Rng&) const;
//       the rollout policy; default: a uniformly random legal action
//   double MinReward() const; double MaxReward() const;
//       the UCB scale (c = max - min)
//   bool Reinvigorate(const State& near, const Action&, const Observation&, Rng&,
//                     State* out) const;
//       a particle near `near` that is consistent with (a, o)
//   double HeuristicValue(const State&) const;
//       a leaf value instead of a rollout
//   void Condition(const State& s, const Action&, const Observation&, State* sp) const;
//       rewrites the history kept in s' for the real observation
//   double UpperBound(const State&) const; ValuedAction<Action> DefaultMove(const State&) const;
//       DESPOT's bounds: the state's value with its hidden part known, and a default policy's
//       first action and value
//
// Discrete-action models (Action = int) add
//   int NumActions() const;
//   void LegalActions(const State&, std::vector<int>*) const;         // default: all actions
//   void PreferredActions(const State&, std::vector<int>*) const;     // optional prior knowledge
//
// Hybrid/continuous-action models (Action = HybridAction) add
//   void ActionKinds(const State&, std::vector<int>*) const;          // legal kinds at a state
//   const BoxSpace& KindSpace(int kind) const;                        // dim 0: purely discrete
//   bool IsFeasible(const State&, const Action&) const;               // optional reasonability
#pragma once

#include <array>
#include <bit>
#include <concepts>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "npfkct/common/rng.h"
#include "npfkct/solver/spaces.h"

namespace npfkct {

/// What one call of the generative model returns: (s', o, r) and whether s' is terminal.
template <class State, class Observation>
struct StepResult {
  State state;
  Observation observation;
  double reward = 0.0;
  bool terminal = false;
};

/// An action and a value. A model's optional `ValuedAction<Action> DefaultMove(const State&)`
/// gives the first action of its default (blind) policy from a state and that policy's value from
/// the state, a lower bound on its optimal value (DESPOT's default move). The action must be the
/// same for every state of a belief (it may depend on what they share, such as a known robot
/// position), since a belief node executes one action for all its states. RockSample's is "go
/// east and exit".
template <class Action>
struct ValuedAction {
  Action action{};
  double value = 0.0;
};

/// The core generative POMDP model concept.
template <class M>
concept GenerativeModel = requires(const M& m, Rng& rng, const typename M::State& s,
                                   const typename M::Action& a) {
  typename M::State;
  typename M::Action;
  typename M::Observation;
  { m.SampleInitialState(rng) } -> std::convertible_to<typename M::State>;
  { m.Step(s, a, rng) } -> std::same_as<StepResult<typename M::State, typename M::Observation>>;
  { m.Discount() } -> std::convertible_to<double>;
};

/// A generative model whose actions are the integers [0, NumActions()).
template <class M>
concept DiscreteActionModel = GenerativeModel<M> && std::same_as<typename M::Action, int> &&
    requires(const M& m) {
  { m.NumActions() } -> std::convertible_to<int>;
};

/// A generative model whose actions are hybrid: a kind and a point of that kind's box.
template <class M>
concept HybridActionModel = GenerativeModel<M> && std::same_as<typename M::Action, HybridAction> &&
    requires(const M& m, const typename M::State& s, std::vector<int>* kinds, int kind) {
  {m.ActionKinds(s, kinds)};
  { m.KindSpace(kind) } -> std::convertible_to<const BoxSpace&>;
};

/// A model that can evaluate Z(o | a, s').
template <class M>
concept HasObservationLikelihood = requires(const M& m, const typename M::Action& a,
                                            const typename M::State& s,
                                            const typename M::Observation& o) {
  { m.ObservationLikelihood(a, s, o) } -> std::convertible_to<double>;
};

/// Whether the state is terminal (false when the model does not say).
template <GenerativeModel M>
bool IsTerminalState(const M& m, const typename M::State& s) {
  if constexpr (requires { m.IsTerminal(s); }) {
    return m.IsTerminal(s);
  } else {
    return false;
  }
}

/// The legal actions of a discrete-action model at a state.
template <DiscreteActionModel M>
void LegalActionsOf(const M& m, const typename M::State& s, std::vector<int>* out) {
  out->clear();
  if constexpr (requires { m.LegalActions(s, out); }) {
    m.LegalActions(s, out);
  } else {
    const int n = m.NumActions();
    for (int a = 0; a < n; ++a) out->push_back(a);
  }
}

/// The model's reward range Rmax - Rmin, or `fallback` when the model does not state it.
template <GenerativeModel M>
double RewardRange(const M& m, double fallback) {
  if constexpr (requires {
                  { m.MaxReward() } -> std::convertible_to<double>;
                  { m.MinReward() } -> std::convertible_to<double>;
                }) {
    return m.MaxReward() - m.MinReward();
  } else {
    return fallback;
  }
}

/// Whether a hybrid action passes the model's reasonability check (true when it has none).
template <GenerativeModel M>
bool IsFeasibleAction(const M& m, const typename M::State& s, const typename M::Action& a) {
  if constexpr (requires {
                  { m.IsFeasible(s, a) } -> std::convertible_to<bool>;
                }) {
    return m.IsFeasible(s, a);
  } else {
    return true;
  }
}

// ---- Observation hashing, used to find observation children in search trees. ----

/// Mixes a 64-bit value (the splitmix64 finaliser).
inline uint64_t HashMix(uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// Hash of an observation: arithmetic values, std::array/std::vector of them, or any type with a
/// `uint64_t Hash() const` member.
template <class O>
uint64_t HashObservation(const O& o) {
  if constexpr (requires {
                  { o.Hash() } -> std::convertible_to<uint64_t>;
                }) {
    return o.Hash();
  } else if constexpr (std::is_integral_v<O>) {
    return HashMix(static_cast<uint64_t>(o));
  } else if constexpr (std::is_floating_point_v<O>) {
    const double d = (o == 0.0) ? 0.0 : static_cast<double>(o);  // +0 and -0 compare equal
    return HashMix(std::bit_cast<uint64_t>(d));
  } else {
    uint64_t h = 0x84222325cbf29ce4ULL;
    for (const auto& v : o) h = HashMix(h ^ HashObservation(v));
    return h;
  }
}

}  // namespace npfkct
