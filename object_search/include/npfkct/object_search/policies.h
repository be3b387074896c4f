// Belief-level policies without a search tree, the references every search must beat: a greedy
// next-best view over the belief (what a practitioner would write instead of a POMDP) and the
// model's rollout policy executed as it is. Both are SearchPlanners of the registry ("nbv",
// "rollout"), so the bench and the server run them like any planner.
//
//   NextBestView nbv(model, NextBestViewOptions{});
//   nbv.SetBelief(belief);
//   Decision<HybridAction> d = nbv.Plan(Budget::Cpu(250), rng);
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "npfkct/object_search/model.h"
#include "npfkct/object_search/search_planner.h"
#include "npfkct/solver/option_table.h"

namespace npfkct::object_search {

/// Settings of the next-best view.
struct NextBestViewOptions {
  /// Configurations proposed each step (aimed at the target candidate, at other objects and
  /// uniform, as kCT's proposals); each scored on `particles` particles of the belief.
  int proposals = 1000;
  int particles = 32;
  /// Checks every field; the message names the offending one.
  Status Validate() const;
};

/// The table of NextBestViewOptions (SetOption and OptionValues).
const option_table::Table<NextBestViewOptions>& NextBestViewTable();
/// Sets NextBestViewOptions field `key` ("proposals", "particles") to `value`.
Status SetOption(NextBestViewOptions* o, std::string_view key, double value);

/// What the tree-less policies below share: the belief they hold, replaced by SetBelief and
/// AdvanceTo, and no tree to drop or reuse.
class TreelessPlanner : public SearchPlanner {
 public:
  const std::string& name() const override { return name_; }
  void SetBelief(ParticleBelief<State> belief) override { belief_ = std::move(belief); }
  using SearchPlanner::Plan;
  void AdvanceTo(const HybridAction&, const Observation&, ParticleBelief<State> belief) override {
    belief_ = std::move(belief);
  }
  void DropTree() override {}
  int64_t TreeSize() const override { return 0; }
  bool ReusesTree() const override { return false; }

 protected:
  TreelessPlanner(std::string name, const ObjectSearchModel& model)
      : name_(std::move(name)), model_(model) {}

  const std::string name_;
  const ObjectSearchModel& model_;
  ParticleBelief<State> belief_;
};

/// The greedy next-best view. Each step, in this order: remove a declared object (the target,
/// or an obstacle declared to be cleared); declare an object whose face grids confirm it as the
/// target; otherwise the better of
///  - the view that sees the most of the target: among the proposals, the one from which the
///    belief's particles most often show the guessed target (its grid-world mass), or, once an
///    object is the likeliest target, most of its face grids not yet confirmed; and
///  - clearing the movable object with the most of the target's mass inside it, worth that mass
///    discounted by the steps it takes (the views that confirm it as an obstacle, the
///    declaration, the removal, a look): declare it once it can be, else the view that confirms
///    most of its faces.
/// No search tree; the budget bounds how many proposals it scores.
class NextBestView final : public TreelessPlanner {
 public:
  /// `model` must outlive it.
  NextBestView(const ObjectSearchModel& model, NextBestViewOptions options);

  using TreelessPlanner::Plan;
  Decision<HybridAction> Plan(const TerminationCondition& stop, Rng& rng) override;
  OptionList OptionsUsed() const override;

 private:
  // The view among the proposals with the highest score(config), and that score.
  template <class Score>
  double BestView(const std::vector<RobotConfig>& views, const TerminationCondition& stop,
                  Score score, RobotConfig* best) const;

  NextBestViewOptions options_;
};

/// The model's rollout policy executed with no search: each step, the rollout action of a state
/// drawn from the belief (a legal declare or remove when the odds allow it, else a view aimed at
/// a placement of the target, else a random feasible configuration).
class RolloutPolicy final : public TreelessPlanner {
 public:
  /// `model` must outlive it.
  explicit RolloutPolicy(const ObjectSearchModel& model) : TreelessPlanner("rollout", model) {}

  using TreelessPlanner::Plan;
  Decision<HybridAction> Plan(const TerminationCondition& stop, Rng& rng) override;
  OptionList OptionsUsed() const override { return {}; }
};

}  // namespace npfkct::object_search
