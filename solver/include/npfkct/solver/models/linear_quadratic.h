// A short-horizon linear-quadratic-Gaussian problem with an analytic optimal first action: the
// continuous-action test problem on which planners' first actions can be measured against the
// truth.
#pragma once

#include <array>

#include "npfkct/solver/belief.h"
#include "npfkct/solver/model.h"
#include "npfkct/solver/spaces.h"

namespace npfkct::models {

/// Two independent axes: x' = x + a + w with w ~ N(0, process_std^2); reward -(|x'|^2 + rho |a|^2)
/// per step; the episode ends after `horizon` steps; observations o = x' + v with
/// v ~ N(0, observation_std^2); x0 ~ N(mean0, initial_std^2) per axis; actions in
/// [-action_limit, action_limit]^2 (one continuous kind). With this certainty-equivalent LQG
/// structure the optimal first action is a0 = -q0 / (q0 + rho) * mean0, where
/// p_{T-1} = rho / (1 + rho), q_t = 1 + gamma p_{t+1} and p_t = q_t rho / (q_t + rho);
/// OptimalFirstAction() computes it. Params::VpwLqg() is the 2-D LQG of Lim, Tomlin & Sunberg
/// (2021, VOOTreeSearch.jl `scripts/LQG/action_compare.jl`), whose optimum lies far from the
/// action box's centre.
class LinearQuadratic {
 public:
  struct State {
    std::array<double, 2> x{};
    int t = 0;
    friend bool operator==(const State&, const State&) = default;
  };
  using Action = HybridAction;
  using Observation = std::array<double, 2>;

  /// What RolloutAction does.
  enum class Rollout {
    kUniform,  ///< A uniform action of the box.
    kLqr,      ///< The optimal linear feedback of the remaining steps on the state (clamped).
  };

  struct Params {
    int horizon = 3;
    double rho = 0.5;
    double gamma = 0.95;
    double process_std = 0.05;
    double observation_std = 0.1;
    double initial_std = 0.1;
    std::array<double, 2> mean0 = {0.8, -0.5};
    /// Actions lie in [-action_limit, action_limit] per axis.
    double action_limit = 1.0;
    Rollout rollout = Rollout::kUniform;
    /// MinReward(): a step's reward seldom falls below it.
    double min_reward = -10.0;
    /// The first step's reward also charges |x0|^2 of the sampled initial state: a cost no action
    /// changes, but a noise in every return (the published reward charges each step's state
    /// before the step).
    bool charge_initial_state = false;

    /// The VPW paper's LQG: x0 = (-10, 10), A = B = C = Q = R = I, noise standard deviations
    /// 0.1, two controlled steps, actions in [-10, 10]^2, the exact LQR rollout policy; the
    /// optimal first action is (6, -6). The returns are the published ones (charge_initial_state);
    /// the published state also counts time, which here is the horizon's end of the episode.
    static Params VpwLqg();
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
  /// A uniform action, or the LQR feedback (Params::rollout).
  Action RolloutAction(const State& s, Rng& rng) const;
  /// RolloutFirst's action: the rollout policy at the belief's weighted mean state.
  Action BeliefRolloutAction(const ParticleBelief<State>& belief, Rng& rng) const;
  double MinReward() const { return params_.min_reward; }
  double MaxReward() const { return 0.0; }

  /// The optimal first action from the initial belief.
  ActionVec OptimalFirstAction() const;
  /// The optimal feedback gain k (a = -k x) with `steps_left` controlled steps to go.
  double Gain(int steps_left) const;
  const Params& params() const { return params_; }

 private:
  Params params_;
  BoxSpace box_;
};

}  // namespace npfkct::models
