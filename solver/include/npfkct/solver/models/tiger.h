// The Tiger problem (Kaelbling, Littman & Cassandra 1998).
#pragma once

#include <vector>

#include "npfkct/solver/model.h"

namespace npfkct::models {

/// Tiger: a tiger hides behind the left or right door. Listening costs 1 and reports the tiger's
/// side correctly with probability 0.85; opening the tiger's door costs 100, the other door pays
/// 10, and either opening resets the problem (the tiger is placed again uniformly at random).
/// Never terminal; discount 0.95.
class Tiger {
 public:
  /// 0: tiger behind the left door, 1: behind the right door.
  using State = int;
  /// 0: listen, 1: open left, 2: open right.
  using Action = int;
  /// 0: hear the tiger on the left, 1: on the right.
  using Observation = int;

  static constexpr int kListen = 0;
  static constexpr int kOpenLeft = 1;
  static constexpr int kOpenRight = 2;

  /// Rollout policy used by the planners' leaf estimates.
  enum class Rollout {
    kRandom,  ///< Uniformly random actions: opens a door two times in three.
    kListen,  ///< Always listen (a history-independent default policy, value -1 / (1 - gamma)).
  };

  /// Listening accuracy, discount and rollout policy; defaults are the classic problem.
  explicit Tiger(double listen_accuracy = 0.85, double discount = 0.95,
                 Rollout rollout = Rollout::kRandom)
      : accuracy_(listen_accuracy), discount_(discount), rollout_(rollout) {}

  State SampleInitialState(Rng& rng) const { return static_cast<int>(rng.UniformInt(2)); }
  StepResult<State, Observation> Step(const State& s, const Action& a, Rng& rng) const;
  double Discount() const { return discount_; }
  int NumActions() const { return 3; }
  double ObservationLikelihood(const Action& a, const State& sp, const Observation& o) const;
  Action RolloutAction(const State& s, Rng& rng) const;
  double MinReward() const { return -100.0; }
  double MaxReward() const { return 10.0; }

 private:
  double accuracy_;
  double discount_;
  Rollout rollout_;
};

}  // namespace npfkct::models
