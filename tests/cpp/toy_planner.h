// A planner written the way a user adds one: this header and a registry entry (ToyEntry), nothing
// else. It looks from a uniformly random feasible configuration, and declares or removes an
// object as soon as the belief lets it (no search). tests/cpp/planner_registry_test.cc registers
// it and reaches it from the benchmark and from the server.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "npfkct/object_search/planner_registry.h"
#include "npfkct/solver/option_table.h"

namespace npfkct::toy {

using object_search::ObjectSearchModel;
using object_search::OptionList;
using object_search::State;

/// Its one option.
struct ToyOptions {
  int draws = 100;  ///< Draws of a random configuration before it gives up on a feasible one.
  Status Validate() const {
    return draws >= 1 ? OkStatus() : InvalidArgumentError("draws must be >= 1");
  }
};

/// The table of ToyOptions (SetOption and OptionValues for the registry).
inline const option_table::Table<ToyOptions>& ToyTable() {
  static const auto* table =
      new option_table::Table<ToyOptions>{{"draws", option_table::Int(&ToyOptions::draws)}};
  return *table;
}
inline Status SetOption(ToyOptions* o, std::string_view key, double value) {
  return option_table::Apply(ToyTable(), o, key, value);
}

/// The planner.
class ToyPlanner final : public object_search::SearchPlanner {
 public:
  ToyPlanner(const ObjectSearchModel& model, ToyOptions options)
      : model_(model), options_(options) {}

  const std::string& name() const override { return name_; }
  void SetBelief(ParticleBelief<State> belief) override { belief_ = std::move(belief); }
  using SearchPlanner::Plan;
  Decision<HybridAction> Plan(const TerminationCondition& stop, Rng& rng) override {
    Decision<HybridAction> d;
    if (belief_.empty()) {
      d.status = FailedPreconditionError("belief is empty");
      return d;
    }
    const State& s = belief_.Sample(rng);
    std::vector<int> kinds;
    model_.ActionKinds(s, &kinds);
    HybridAction a;
    for (int kind : kinds) {  // a legal declare or remove first
      if (kind != object_search::kMoveKind) {
        a.kind = kind;
        d.action = a;
        return FinishSearch(std::move(d), stop);
      }
    }
    a.kind = object_search::kMoveKind;
    for (int i = 0; i < options_.draws; ++i) {
      a.x = model_.KindSpace(a.kind).SampleUniform(rng);
      if (model_.IsFeasible(s, a)) break;
    }
    d.action = a;
    return FinishSearch(std::move(d), stop);
  }
  void AdvanceTo(const HybridAction&, const object_search::Observation&,
                 ParticleBelief<State> belief) override {
    belief_ = std::move(belief);
  }
  void DropTree() override {}
  int64_t TreeSize() const override { return 0; }
  bool ReusesTree() const override { return false; }
  OptionList OptionsUsed() const override { return option_table::Values(ToyTable(), options_); }

 private:
  std::string name_ = "toy";
  const ObjectSearchModel& model_;
  ToyOptions options_;
  ParticleBelief<State> belief_;
};

/// Its registry entry.
inline object_search::PlannerEntry ToyEntry() {
  return {"toy",
          "a random feasible view, or the first legal declare or remove (no search)",
          /*takes_sampler=*/false,
          /*needs_truth=*/false,
          [](const object_search::SearchParams&) {
            return option_table::Values(ToyTable(), ToyOptions{});
          },
          [](const object_search::PlannerArgs& args)
              -> StatusOr<std::unique_ptr<object_search::SearchPlanner>> {
            ToyOptions o;
            if (Status s = object_search::ApplyOptions(&o, args.options); !s.ok()) return s;
            return std::unique_ptr<object_search::SearchPlanner>(new ToyPlanner(*args.model, o));
          }};
}

}  // namespace npfkct::toy
