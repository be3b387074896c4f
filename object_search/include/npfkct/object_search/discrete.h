// The object-search model on a manual discrete action set, for the POMCP-family baselines.
//
// Two sets, both built from World::ManualPoses() (4 base poses in the paper: the middle of each
// table side, facing its centre), 3 lift heights and 9 head orientations (3 pans x 3 tilts):
//
//   kPrimitive  the paper's set (footnote 9): base, lift and head are *separate* primitive
//               actions. A base action moves to one of the poses and keeps the lift and head; a
//               lift action changes only the lift; a head action changes only pan and tilt. A new
//               view can therefore take up to three steps. 4 + 3 + 9 = 16 move actions.
//   kJoint      one action per joint configuration (4 x 3 x 9 = 108): every view is one step.
//               Stronger than the paper's baseline; benchmarked as `pomcp-joint`.
//
// Integer actions [0, M) are the M moves, then M + (kind - 1) for the declare/remove kinds.
// Rollouts run in the underlying hybrid model (rollout_model()), so every planner shares one
// rollout policy.
#pragma once

#include <vector>

#include "npfkct/object_search/model.h"

namespace npfkct::object_search {

/// Which manual action set a discrete baseline plans over.
enum class DiscreteActionSet {
  kPrimitive,  ///< Separate base / lift / head actions (the paper's POMCP and GPOMCP).
  kJoint,      ///< Joint base x lift x head configurations (pomcp-joint).
};

/// ObjectSearchModel with integer actions over a manual discrete set.
class DiscreteObjectSearch {
 public:
  using State = object_search::State;
  using Action = int;
  using Observation = object_search::Observation;

  /// Wraps `model`, which must outlive this object.
  explicit DiscreteObjectSearch(const ObjectSearchModel& model,
                                DiscreteActionSet set = DiscreteActionSet::kJoint);

  /// Re-reads the manual poses after the model's World changed.
  void Refresh();

  DiscreteActionSet action_set() const { return set_; }
  /// Number of move actions (16 primitive or 108 joint with 4 poses and a lift, pan and tilt;
  /// fewer for a robot without some of them).
  int num_moves() const { return num_moves_; }
  /// The manual base poses (x, y, yaw).
  const std::vector<RobotConfig>& poses() const { return poses_; }

  /// The configuration move action `a` leads to from configuration `from` (primitive actions
  /// keep the parts they do not set; joint actions ignore `from`).
  RobotConfig MoveTarget(int a, const RobotConfig& from) const;
  /// The hybrid action of integer action `a` taken at robot configuration `from`.
  HybridAction ToHybrid(int a, const RobotConfig& from) const;
  /// The integer action of a discrete kind.
  int FromKind(int kind) const { return num_moves_ + kind - 1; }

  State SampleInitialState(Rng& rng) const { return model_.SampleInitialState(rng); }
  StepResult<State, Observation> Step(const State& s, const Action& a, Rng& rng) const {
    return model_.Step(s, ToHybrid(a, s.robot), rng);
  }
  double Discount() const { return model_.Discount(); }
  bool IsTerminal(const State& s) const { return model_.IsTerminal(s); }
  int NumActions() const {
    return num_moves_ + 3 * static_cast<int>(model_.world().objects.size());
  }
  /// Every move, then the discrete kinds legal at s.
  void LegalActions(const State& s, std::vector<int>* out) const;
  double ObservationLikelihood(const Action& a, const State& sp, const Observation& o) const {
    return model_.ObservationLikelihood(ToHybrid(a, sp.robot), sp, o);
  }
  bool IsFeasible(const State& s, const Action& a) const {
    return model_.IsFeasible(s, ToHybrid(a, s.robot));
  }
  double MinReward() const { return model_.MinReward(); }
  double MaxReward() const { return model_.MaxReward(); }
  /// Rollouts use the hybrid model's rollout policy (the same for every planner).
  const ObjectSearchModel& rollout_model() const { return model_; }

 private:
  const ObjectSearchModel& model_;
  DiscreteActionSet set_;
  std::vector<RobotConfig> poses_;
  std::vector<double> lifts_;                     // the world's manual lifts
  std::vector<std::pair<double, double>> heads_;  // and head orientations
  int num_moves_ = 0;
};

}  // namespace npfkct::object_search
