#include "npfkct/solver/models/linear_quadratic.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace npfkct::models {

LinearQuadratic::LinearQuadratic() : LinearQuadratic(Params()) {}

LinearQuadratic::Params LinearQuadratic::Params::VpwLqg() {
  Params p;
  p.horizon = 2;
  p.rho = 1.0;
  p.gamma = 1.0;
  p.process_std = 0.1;
  p.observation_std = 0.1;
  p.initial_std = 0.1;
  p.mean0 = {-10.0, 10.0};
  p.action_limit = 10.0;
  p.rollout = Rollout::kLqr;
  p.min_reward = -1000.0;
  p.charge_initial_state = true;
  return p;
}

LinearQuadratic::LinearQuadratic(Params p)
    : params_(p),
      box_(MakeActionVec({-p.action_limit, -p.action_limit}),
           MakeActionVec({p.action_limit, p.action_limit})) {}

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
    const double u =
        a.x.size() == 2 ? std::clamp(a.x[i], -params_.action_limit, params_.action_limit) : 0.0;
    r.state.x[i] = s.x[i] + u + params_.process_std * rng.Normal();
    cost += r.state.x[i] * r.state.x[i] + params_.rho * u * u;
    r.observation[i] = r.state.x[i] + params_.observation_std * rng.Normal();
  }
  if (params_.charge_initial_state && s.t == 0) cost += s.x[0] * s.x[0] + s.x[1] * s.x[1];
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

LinearQuadratic::Action LinearQuadratic::RolloutAction(const State& s, Rng& rng) const {
  if (params_.rollout == Rollout::kUniform) return HybridAction{0, box_.SampleUniform(rng)};
  const double k = Gain(params_.horizon - s.t);
  const double limit = params_.action_limit;
  return HybridAction{0, MakeActionVec({std::clamp(-k * s.x[0], -limit, limit),
                                        std::clamp(-k * s.x[1], -limit, limit)})};
}

LinearQuadratic::Action LinearQuadratic::BeliefRolloutAction(const ParticleBelief<State>& belief,
                                                             Rng& rng) const {
  if (belief.empty() || !(belief.total_weight() > 0.0)) return RolloutAction(State{}, rng);
  const Eigen::Vector2d x =
      belief.Mean([](const State& s) { return Eigen::Vector2d(s.x[0], s.x[1]); });
  State mean = belief.particle(0);  // its time step
  mean.x = {x[0], x[1]};
  return RolloutAction(mean, rng);
}

double LinearQuadratic::Gain(int steps_left) const {
  // Backward Riccati recursion of the value's quadratic coefficient.
  double p = 0.0;  // beyond the horizon
  double gain = 0.0;
  for (int t = 0; t < steps_left; ++t) {
    const double q = 1.0 + params_.gamma * p;
    gain = q / (q + params_.rho);
    p = q * params_.rho / (q + params_.rho);
  }
  return gain;
}

ActionVec LinearQuadratic::OptimalFirstAction() const {
  const double gain = Gain(params_.horizon);
  return MakeActionVec({-gain * params_.mean0[0], -gain * params_.mean0[1]});
}

}  // namespace npfkct::models
