// SimpleLightDark, the 'Light Dark' problem of the POMCPOW paper (Sunberg & Kochenderfer 2018).
#pragma once

#include <cmath>
#include <vector>

#include "npfkct/solver/model.h"

namespace npfkct::models {

/// SimpleLightDark: the agent lives on the integers -60..60 and must declare (action 0) when it is
/// at 0 (+100; -100 elsewhere; either way the episode ends). Moves of -10, -1, +1, +10 cost 1 and
/// are clamped to the line. Observations are continuous: o ~ N(s', |s' - 10| + 1e-4), precise only
/// near the light at +10. Initial state uniform on -30..30; discount 0.95.
class SimpleLightDark {
 public:
  /// Position; kTerminal once the agent has declared.
  using State = int;
  /// Index into kMoves: 0: -10, 1: -1, 2: declare (0), 3: +1, 4: +10.
  using Action = int;
  using Observation = double;

  static constexpr int kRadius = 60;
  static constexpr int kTerminal = kRadius + 1;
  static constexpr int kLight = 10;
  static constexpr int kDeclare = 2;
  static constexpr int kMoves[5] = {-10, -1, 0, 1, 10};

  /// What HeuristicValue (the planners' leaf value) gives.
  enum class Leaf {
    /// The fully observable MDP's V*(s), as the published experiments value leaves.
    kFullyObservable,
    /// The value of first going to the light by the fewest moves, then to 0 and declaring: the
    /// detour that the observations make necessary (only at the light is one exact).
    /// Hand-written knowledge of this problem, for the experiment of docs/experiments.md
    /// ("What caps kCT on SimpleLightDark?"), not what the published figures used.
    kLocalize,
  };

  /// The continuous problem, or with `observation_bin` > 0 the authors' discretised one
  /// (DSimpleLightDark of ContinuousPOMDPTreeSearchExperiments.jl): the observation is the bin
  /// index floor(o / observation_bin), its likelihood the Gaussian's mass on the bin.
  explicit SimpleLightDark(double observation_bin = 0.0, Leaf leaf = Leaf::kFullyObservable);

  State SampleInitialState(Rng& rng) const;
  StepResult<State, Observation> Step(const State& s, const Action& a, Rng& rng) const;
  double Discount() const { return 0.95; }
  bool IsTerminal(const State& s) const { return s == kTerminal; }
  int NumActions() const { return 5; }
  double ObservationLikelihood(const Action& a, const State& sp, const Observation& o) const;
  /// The leaf value of s: the fully observable MDP value V*(s), computed once by value iteration
  /// (POMCPOW's FOValue), or with Leaf::kLocalize the value of the detour by the light.
  double HeuristicValue(const State& s) const;
  /// A particle consistent with observation o: round(N(o, |o - 10| + 1e-4)), clamped.
  bool Reinvigorate(const State& near, const Action& a, const Observation& o, Rng& rng,
                    State* out) const;
  double MinReward() const { return -100.0; }
  double MaxReward() const { return 100.0; }

  /// Observation noise standard deviation at position s.
  static double NoiseStd(double s) { return std::abs(s - kLight) + 1e-4; }
  /// The observation bin width (0: continuous observations).
  double observation_bin() const { return observation_bin_; }

 private:
  double observation_bin_ = 0.0;
  std::vector<double> leaf_value_;  // HeuristicValue, index s + kRadius
};

}  // namespace npfkct::models
