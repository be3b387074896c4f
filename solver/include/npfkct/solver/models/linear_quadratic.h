// A short-horizon linear-quadratic-Gaussian problem with an analytic optimal first action: the
// continuous-action test problem on which planners' first actions can be measured against the
// truth.
#pragma once

#include <array>

#include "npfkct/solver/model.h"
#include "npfkct/solver/spaces.h"

namespace npfkct::models {

/// Two independent axes: x' = x + a + w with w ~ N(0, process_std^2); reward -(|x'|^2 + rho |a|^2)
/// per step; the episode ends after `horizon` steps; observations o = x' + v with
/// v ~ N(0, observation_std^2); x0 ~ N(mean0, initial_std^2) per axis; actions in [-1, 1]^2
/// (one continuous kind). With this certainty-equivalent LQG structure the optimal first action is
/// a0 = -q0 / (q0 + rho) * mean0, where p_{T-1} = rho / (1 + rho), q_t = 1 + gamma p_{t+1} and
/// p_t = q_t rho / (q_t + rho); OptimalFirstAction() computes it.
class LinearQuadratic {
 public:
  struct State {
    std::array<double, 2> x{};
    int t = 0;
    friend bool operator==(const State&, const State&) = default;
  };
  using Action = HybridAction;
  using Observation = std::array<double, 2>;

  struct Params {
    int horizon = 3;
    double rho = 0.5;
    double gamma = 0.95;
    double process_std = 0.05;
    double observation_std = 0.1;
    double initial_std = 0.1;
    std::array<double, 2> mean0 = {0.8, -0.5};
  };

  LinearQuadratic();
  explicit LinearQuadratic(Params p);

  State SampleInitialState(Rng& rng) const;
  StepResult<State, Observation> Step(const State& s, const Action& a, Rng& rng) const;
  double Discount() const { return params_.gamma; }
  bool IsTerminal(const State& s) const { return s.t >= params_.horizon; }
  void ActionKinds(const State&, std::vector<int>* out) const { out->assign({0}); }
  const BoxSpace& KindSpace(int /*kind*/) const { return box_; }
  double ObservationLikelihood(const Action& a, const State& sp, const Observation& o) const;
  /// Uniform actions.
  Action RolloutAction(const State& s, Rng& rng) const;
  double MinReward() const { return -10.0; }
  double MaxReward() const { return 0.0; }

  /// The optimal first action from the initial belief.
  ActionVec OptimalFirstAction() const;
  const Params& params() const { return params_; }

 private:
  Params params_;
  BoxSpace box_;
};

}  // namespace npfkct::models
