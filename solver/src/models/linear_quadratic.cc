#include "npfkct/solver/models/linear_quadratic.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace npfkct::models {

LinearQuadratic::LinearQuadratic() : LinearQuadratic(Params()) {}

LinearQuadratic::LinearQuadratic(Params p)
    : params_(p), box_(MakeActionVec({-1.0, -1.0}), MakeActionVec({1.0, 1.0})) {}

LinearQuadratic::State LinearQuadratic::SampleInitialState(Rng& rng) const {
  State s;
  for (int i = 0; i < 2; ++i) s.x[i] = params_.mean0[i] + params_.initial_std * rng.Normal();
  return s;
}

StepResult<LinearQuadratic::State, LinearQuadratic::Observation> LinearQuadratic::Step(
    const State& s, const Action& a, Rng& rng) const {
  StepResult<State, Observation> r;
  r.state = s;
  double cost = 0.0;
  for (int i = 0; i < 2; ++i) {
    const double u = a.x.size() == 2 ? std::clamp(a.x[i], -1.0, 1.0) : 0.0;
    r.state.x[i] = s.x[i] + u + params_.process_std * rng.Normal();
    cost += r.state.x[i] * r.state.x[i] + params_.rho * u * u;
    r.observation[i] = r.state.x[i] + params_.observation_std * rng.Normal();
  }
  r.state.t = s.t + 1;
  r.reward = -cost;
  r.terminal = r.state.t >= params_.horizon;
  return r;
}

double LinearQuadratic::ObservationLikelihood(const Action&, const State& sp,
                                              const Observation& o) const {
  const double sd = params_.observation_std;
  double p = 1.0;
  for (int i = 0; i < 2; ++i) {
    const double z = (o[i] - sp.x[i]) / sd;
    p *= std::exp(-0.5 * z * z) / (sd * std::sqrt(2.0 * std::numbers::pi));
  }
  return p;
}

LinearQuadratic::Action LinearQuadratic::RolloutAction(const State&, Rng& rng) const {
  return HybridAction{0, box_.SampleUniform(rng)};
}

ActionVec LinearQuadratic::OptimalFirstAction() const {
  // Backward Riccati recursion of the value's quadratic coefficient.
  double p = 0.0;  // beyond the horizon
  double gain = 0.0;
  for (int t = params_.horizon - 1; t >= 0; --t) {
    const double q = 1.0 + params_.gamma * p;
    gain = q / (q + params_.rho);
    p = q * params_.rho / (q + params_.rho);
  }
  return MakeActionVec({-gain * params_.mean0[0], -gain * params_.mean0[1]});
}

}  // namespace npfkct::models
