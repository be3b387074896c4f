// Small hybrid-action models for planner tests.
#pragma once

#include <cmath>
#include <vector>

#include "npfkct/solver/model.h"
#include "npfkct/solver/spaces.h"

namespace npfkct::testing {

/// A continuous bandit wrapped as a POMDP: kind 0 probes a point x of [0, 1]^2 and earns
/// exp(-|x - peak|^2 / (2 0.1^2)) where the peak is (0.7, 0.3) or (0.2, 0.8) depending on the
/// hidden state (which a probe near a peak reveals: observation 1 + index of the peak within 0.25,
/// else 0); kind 1 stops (reward 0.2, terminal). Discount 0.5. The best first action is a probe at
/// the likelier peak.
class PeakSearch {
 public:
  using State = int;  // 0: peak at (0.7, 0.3); 1: peak at (0.2, 0.8)
  using Action = HybridAction;
  using Observation = int;

  explicit PeakSearch(double p_first = 0.8, ActionVec first_peak = MakeActionVec({0.7, 0.3}))
      : p_first_(p_first), first_peak_(first_peak) {
    box_ = BoxSpace(MakeActionVec({0.0, 0.0}), MakeActionVec({1.0, 1.0}));
  }

  ActionVec Peak(int s) const { return s == 0 ? first_peak_ : MakeActionVec({0.2, 0.8}); }

  State SampleInitialState(Rng& rng) const { return rng.Bernoulli(p_first_) ? 0 : 1; }
  StepResult<State, Observation> Step(const State& s, const Action& a, Rng& /*rng*/) const {
    if (a.kind == 1) return {s, 0, 0.2, true};
    const double d2 = (a.x - Peak(s)).squaredNorm();
    int o = 0;
    if ((a.x - Peak(0)).norm() < 0.25) o = 1 + (s == 0 ? 0 : 2);
    if ((a.x - Peak(1)).norm() < 0.25) o = 1 + (s == 1 ? 0 : 2);
    return {s, o, std::exp(-d2 / (2 * 0.01)), false};
  }
  double ObservationLikelihood(const Action& a, const State& sp, const Observation& o) const {
    Rng unused;
    return Step(sp, a, unused).observation == o ? 1.0 : 0.0;
  }
  double Discount() const { return 0.5; }
  void ActionKinds(const State&, std::vector<int>* out) const { out->assign({0, 1}); }
  const BoxSpace& KindSpace(int kind) const { return kind == 0 ? box_ : point_; }
  bool IsFeasible(const State&, const Action& a) const {
    // The corner x > 0.9 and y < 0.1 is 'occupied' (like a base pose inside furniture).
    return a.kind != 0 || !(a.x[0] > 0.9 && a.x[1] < 0.1);
  }
  double MinReward() const { return 0.0; }
  double MaxReward() const { return 1.0; }

 private:
  double p_first_;
  ActionVec first_peak_;
  BoxSpace box_;
  BoxSpace point_;
};

}  // namespace npfkct::testing
