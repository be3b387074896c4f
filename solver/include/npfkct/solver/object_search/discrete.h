// The object-search model on the paper's manual discrete action set, for POMCP and GPOMCP.
#pragma once

#include <memory>
#include <vector>

#include "npfkct/solver/object_search/model.h"

namespace npfkct::object_search {

/// ObjectSearchModel with integer actions: [0, M) move to the M manual configurations
/// (World::ManualConfigurations), then M + (kind - 1) for the declare/remove kinds.
class DiscreteObjectSearch {
 public:
  using State = object_search::State;
  using Action = int;
  using Observation = object_search::Observation;

  /// Wraps `model`, which must outlive this object.
  explicit DiscreteObjectSearch(const ObjectSearchModel& model) : model_(model) { Refresh(); }

  /// Re-reads the manual configurations after the model's World changed.
  void Refresh() { configs_ = model_.world().ManualConfigurations(); }

  /// The hybrid action of an integer action.
  HybridAction ToHybrid(int a) const {
    HybridAction h;
    if (a < static_cast<int>(configs_.size())) {
      h.kind = kMoveKind;
      h.x = ObjectSearchModel::VecOf(configs_[a]);
    } else {
      h.kind = a - static_cast<int>(configs_.size()) + 1;
    }
    return h;
  }
  /// The integer action of a discrete kind.
  int FromKind(int kind) const { return static_cast<int>(configs_.size()) + kind - 1; }
  int num_configs() const { return static_cast<int>(configs_.size()); }

  State SampleInitialState(Rng& rng) const { return model_.SampleInitialState(rng); }
  StepResult<State, Observation> Step(const State& s, const Action& a, Rng& rng) const {
    return model_.Step(s, ToHybrid(a), rng);
  }
  double Discount() const { return model_.Discount(); }
  bool IsTerminal(const State& s) const { return model_.IsTerminal(s); }
  int NumActions() const {
    return static_cast<int>(configs_.size()) + 3 * static_cast<int>(model_.world().objects.size());
  }
  void LegalActions(const State& s, std::vector<int>* out) const {
    out->clear();
    for (int m = 0; m < static_cast<int>(configs_.size()); ++m) out->push_back(m);
    thread_local std::vector<int> kinds;
    model_.ActionKinds(s, &kinds);
    for (int k : kinds) {
      if (k != kMoveKind) out->push_back(FromKind(k));
    }
  }
  Action RolloutAction(const State& s, Rng& rng) const {
    const HybridAction h = model_.RolloutAction(s, rng);
    if (h.kind != kMoveKind) return FromKind(h.kind);
    return static_cast<int>(rng.UniformInt(static_cast<int64_t>(configs_.size())));
  }
  double ObservationLikelihood(const Action& a, const State& sp, const Observation& o) const {
    return model_.ObservationLikelihood(ToHybrid(a), sp, o);
  }
  bool IsFeasible(const State& s, const Action& a) const {
    return model_.IsFeasible(s, ToHybrid(a));
  }
  double MinReward() const { return model_.MinReward(); }
  double MaxReward() const { return model_.MaxReward(); }

 private:
  const ObjectSearchModel& model_;
  std::vector<RobotConfig> configs_;
};

}  // namespace npfkct::object_search
