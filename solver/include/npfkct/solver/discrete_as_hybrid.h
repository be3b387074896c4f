// A discrete-action model seen as a hybrid one, so that the continuous-action planners (kCT,
// POMCPOW, ...) run on it: discrete action i becomes kind i without a continuous part.
#pragma once

#include <vector>

#include "npfkct/solver/model.h"
#include "npfkct/solver/spaces.h"

namespace npfkct {

/// Wraps discrete-action model M (which must outlive the wrapper). Kind i is action i; the kinds'
/// boxes are points, so kCT's list holds the actions themselves and its spheres never refine.
template <DiscreteActionModel M>
class DiscreteAsHybrid {
 public:
  using State = typename M::State;
  using Action = HybridAction;
  using Observation = typename M::Observation;

  explicit DiscreteAsHybrid(const M& model) : model_(model) {}

  State SampleInitialState(Rng& rng) const { return model_.SampleInitialState(rng); }
  StepResult<State, Observation> Step(const State& s, const Action& a, Rng& rng) const {
    return model_.Step(s, a.kind, rng);
  }
  double Discount() const { return model_.Discount(); }
  bool IsTerminal(const State& s) const { return IsTerminalState(model_, s); }
  void ActionKinds(const State& s, std::vector<int>* out) const { LegalActionsOf(model_, s, out); }
  const BoxSpace& KindSpace(int /*kind*/) const { return point_; }
  double ObservationLikelihood(const Action& a, const State& sp,
                               const Observation& o) const requires HasObservationLikelihood<M> {
    return model_.ObservationLikelihood(a.kind, sp, o);
  }
  double HeuristicValue(const State& s) const requires requires(const M& m, const State& x) {
    m.HeuristicValue(x);
  }
  { return model_.HeuristicValue(s); }
  bool Reinvigorate(const State& near, const Action& a, const Observation& o, Rng& rng,
                    State* out) const requires
      requires(const M& m, const State& x, const Observation& ob, Rng& r, State* p) {
    m.Reinvigorate(x, 0, ob, r, p);
  }
  { return model_.Reinvigorate(near, a.kind, o, rng, out); }
  double MinReward() const requires requires(const M& m) { m.MinReward(); }
  { return model_.MinReward(); }
  double MaxReward() const requires requires(const M& m) { m.MaxReward(); }
  { return model_.MaxReward(); }

 private:
  const M& model_;
  BoxSpace point_;
};

}  // namespace npfkct
