#include "npfkct/solver/models/tiger.h"

namespace npfkct::models {

StepResult<Tiger::State, Tiger::Observation> Tiger::Step(const State& s, const Action& a,
                                                         Rng& rng) const {
  StepResult<State, Observation> r;
  if (a == kListen) {
    r.state = s;
    r.reward = -1.0;
    r.observation = rng.Bernoulli(accuracy_) ? s : 1 - s;
    return r;
  }
  const int opened = (a == kOpenLeft) ? 0 : 1;
  r.reward = (opened == s) ? -100.0 : 10.0;
  r.state = static_cast<int>(rng.UniformInt(2));
  r.observation = static_cast<int>(rng.UniformInt(2));
  return r;
}

Tiger::Action Tiger::RolloutAction(const State&, Rng& rng) const {
  if (rollout_ == Rollout::kListen) return kListen;
  return static_cast<int>(rng.UniformInt(3));
}

double Tiger::ObservationLikelihood(const Action& a, const State& sp, const Observation& o) const {
  if (a == kListen) return o == sp ? accuracy_ : 1.0 - accuracy_;
  return 0.5;
}

}  // namespace npfkct::models
